"""The rendering space comes from the OCIO config (its scene_linear role) or
``--rendering-space NAME``, not a fixed ACEScg.

Analytic check: a camera inside a closed box whose walls are an exact Lambertian
of albedo rho that also emits Le. Every wall sees only walls, so the radiance is
L = Le + rho L, i.e. Le / (1 - rho) per channel *of the rendering space*. That is
not invariant under a change of primaries (it is a sum of powers of rho), so a
Rec.709-linear render must match Le / (1 - rho) computed in Rec.709, and the
default ACEScg render the same formula computed in ACEScg, and the two differ.
"""
from __future__ import annotations

import json

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt.cli import main
from cmlt.color import get_config, load_config, set_config
from cmlt.io.exr import read_exr
from cmlt.usd.color import load_texture
from support.stages import closed_box_shot

RHO = (0.8, 0.3, 0.1)           # authored, untagged: linear Rec.709
LE = 0.2
W, H = 48, 32
REC709 = "Linear Rec.709 (sRGB)"


pytestmark = pytest.mark.usefixtures("builtin_color_config")


@pytest.fixture
def box(tmp_path):
    p = tmp_path / "box.usda"
    p.write_text(closed_box_shot(RHO, f"color3f inputs:emissiveColor = ({LE}, {LE}, {LE})\n"
                                      "int inputs:useSpecularWorkflow = 1\n"
                                      "color3f inputs:specularColor = (0, 0, 0)"))
    return str(p)


def _render(box, out, *flags):
    code = main(["render", box, "--spp", "16", "--res", f"{W}x{H}", "--max-depth", "200",
                 "--integrator", "pt", "--aov", "variance", "--out", str(out), "--quiet",
                 *flags])
    assert code == 0
    img, meta = read_exr(str(out))
    n = W * H
    mean = img[..., :3].reshape(-1, 3).mean(0)
    se = np.sqrt(img[..., 3:6].reshape(-1, 3).sum(0)) / n       # pixels are independent
    return mean, se, meta


@pytest.mark.statistical
def test01_rec709_rendering_space_matches_the_furnace_in_rec709(box, tmp_path, capsys):
    mean, se, meta = _render(box, tmp_path / "r709.exr", "--rendering-space", "lin_rec709")
    want = LE / (1.0 - np.asarray(RHO))
    assert (se < 0.01 * want).all(), se                 # a 1 % error would show
    assert (np.abs(mean - want) < 4.5 * se + 1e-5).all(), (mean, want, se)
    # the space is recorded: EXR header, its colour space (the output default) and sidecar
    assert meta["cmlt:renderingSpace"] == REC709
    assert meta["oiio:ColorSpace"] == "lin_rec709_scene"
    side = json.loads((tmp_path / "r709.exr.json").read_text())
    assert side["settings"]["rendering_space"] == REC709


@pytest.mark.statistical
def test02_default_space_is_the_configs_scene_linear_acescg(box, tmp_path):
    cfg = get_config()
    assert cfg.rendering_space == "ACEScg"              # the built-in config's scene_linear
    mean, se, meta = _render(box, tmp_path / "ap1.exr", "--output-colorspace", "lin_rec709")
    rho = np.asarray(cfg.to_rendering_space(RHO, "lin_rec709"))
    le = np.asarray(cfg.to_rendering_space((LE, LE, LE), "lin_rec709"))
    want = np.asarray(cfg.from_rendering_space((le / (1 - rho)).astype(np.float32),
                                               "lin_rec709"))
    assert (np.abs(mean - want) < 4.5 * se + 1e-5).all(), (mean, want, se)
    rec709 = LE / (1.0 - np.asarray(RHO))
    assert (np.abs(mean - rec709) > 10 * se).any()     # the choice of space is visible
    assert meta["cmlt:renderingSpace"] == "ACEScg"


def test03_unknown_rendering_space_is_a_usage_error_listing_choices(box, tmp_path, capsys):
    code = main(["render", box, "--spp", "1", "--res", "8x8", "--out", str(tmp_path / "x.exr"),
                 "--rendering-space", "no such space"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("cmlt: error: --rendering-space 'no such space'")
    assert "choose one of" in err[0] and REC709 in err[0] and "ACEScg" in err[0]
    assert not (tmp_path / "x.exr").exists()


def test04_textures_and_colours_convert_into_the_chosen_space(tmp_path):
    set_config(load_config(rendering_space="lin_rec709"))
    cfg = get_config()
    assert cfg.rendering_space == REC709
    np.testing.assert_allclose(cfg.to_rendering_space(RHO, "lin_rec709"), RHO, rtol=1e-6)
    np.testing.assert_allclose(cfg.luminance_weights, (0.2126, 0.7152, 0.0722), atol=1e-4)
    # an 8-bit sRGB texture decodes to linear Rec.709 values, not AP1 ones
    path = str(tmp_path / "t.png")
    texels = np.array([[[255, 128, 0]]], np.uint8)
    out = oiio.ImageOutput.create(path)
    assert out.open(path, oiio.ImageSpec(1, 1, 3, oiio.UINT8))
    assert out.write_image(texels)
    out.close()
    got = load_texture(path, "sRGB")[0, 0]
    srgb = texels[0, 0] / 255.0
    lin = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(got, lin, atol=2e-3)
