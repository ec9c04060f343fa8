"""UsdRender.Product / RenderVar prims choose a frame's EXR channels and path.

A quad of a known diffuse colour at a known distance D, seen by a camera whose
RenderSettings name one product with two usable vars (the albedo as layer
``diffuse``, the depth as a half channel ``depth``) and one whose sourceName
cmlt does not render. The EXR must have exactly the beauty plus those two
layers, the albedo layer must hold the diffuse colour converted to the
rendering space, the depth layer D, and the unknown var a warning naming it.
"""
from __future__ import annotations

import json

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt.cli import main
from cmlt.color import to_rendering_space
from support.stages import exr_channels, facing_quad_shot

D = 5.0
DIFFUSE = (0.8, 0.3, 0.1)        # untagged: linear Rec.709
W, H = 48, 32


#: RenderVar prim name -> (sourceName, dataType, aov name or None)
VARS = {"color": ("color", "color3f", None), "diffuse": ("albedo", "color3f", None),
        "depth": ("depth", "half", "Z"), "position": ("P", "point3f", None),
        "shortNormal": ("normal", "float", None)}
_VARS = "\n".join(
    f'''                def RenderVar "{name}"
                {{
                    uniform string sourceName = "{src}"
                    uniform token dataType = "{dtype}"'''
    + (f'''\n                    uniform string driver:parameters:aov:name = "{aov}"''' if aov else "")
    + "\n                }"
    for name, (src, dtype, aov) in VARS.items())


def _shot(product_name: str = "prod/beauty.####.exr", extra_var: str = "") -> str:
    name = f'uniform token productName = "{product_name}"' if product_name else ""
    return facing_quad_shot(D, DIFFUSE, f'''\
        def Scope "Render"
        {{
            def RenderSettings "Settings"
            {{
                rel camera = </Cam>
                uniform int2 resolution = ({W}, {H})
                rel products = </Render/Product>
            }}
            def RenderProduct "Product"
            {{
                {name}
                rel orderedVars = [</Render/Vars/color>, </Render/Vars/diffuse>,
                                   </Render/Vars/depth>, </Render/Vars/position>{extra_var}]
            }}
            def Scope "Vars"
            {{
{_VARS}
            }}
        }}
        ''')


pytestmark = pytest.mark.usefixtures("builtin_color_config")


def _centre():
    """Pixels well inside the quad (the quad covers the middle of the frame), two pixels
    in from its edges: the default gaussian filter reaches 1.5 pixels."""
    m = np.zeros((H, W), bool)
    m[H // 2 - 4:H // 2 + 4, W // 2 - 6:W // 2 + 6] = True
    return m


def test01_product_vars_drive_channels_values_and_path(tmp_path, monkeypatch, capsys):
    shot = tmp_path / "shot.usda"
    shot.write_text(_shot())
    monkeypatch.chdir(tmp_path)
    code = main(["render", str(shot), "--frames", "1", "--spp", "2", "--log-json"])
    out = capsys.readouterr()
    assert code == 0, out.err
    exr = tmp_path / "prod" / "beauty.0001.exr"          # productName, no --out
    assert exr.is_file()
    spec, ch = exr_channels(exr)
    # (OpenEXR stores channels sorted by name: compare the sets)
    assert set(spec.channelnames) == {"R", "G", "B", "diffuse.R", "diffuse.G", "diffuse.B", "Z"}
    fmts = dict(zip(spec.channelnames, spec.channelformats or [spec.format] * spec.nchannels))
    assert fmts["Z"] == oiio.HALF and fmts["diffuse.R"] == oiio.FLOAT      # dataType half
    inside = _centre()
    want = np.array(to_rendering_space(DIFFUSE, "lin_rec709"), dtype=np.float32)
    assert not np.allclose(want, DIFFUSE, atol=1e-2)    # the rendering space is not Rec.709
    albedo = np.stack([ch["diffuse.R"], ch["diffuse.G"], ch["diffuse.B"]], -1)[inside]
    np.testing.assert_allclose(albedo, np.broadcast_to(want, albedo.shape), rtol=1e-6)
    np.testing.assert_allclose(ch["Z"][inside], D, rtol=1e-3)             # half precision
    # the beauty is lit (not replaced by an AOV)
    assert ch["R"][inside].mean() > 0 and not np.allclose(ch["R"][inside], albedo[:, 0])
    events = [json.loads(line) for line in out.out.splitlines() if line.strip()]
    warns = [e["message"] for e in events if e.get("event") == "warning"]
    assert any("/Render/Vars/position" in w and "'P'" in w and "skipped" in w for w in warns), warns
    side = json.loads((tmp_path / "prod" / "beauty.0001.exr.json").read_text())
    prod = side["settings"]["render_product"]
    assert prod["product"] == "/Render/Product"
    assert [layer["var"] for layer in prod["layers"]] == ["/Render/Vars/diffuse",
                                                          "/Render/Vars/depth"]


def test02_out_flag_wins_over_product_name_and_aov_flag_over_vars(tmp_path, monkeypatch, capsys):
    shot = tmp_path / "shot.usda"
    shot.write_text(_shot())
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "flag.exr"
    assert main(["render", str(shot), "--frames", "1", "--spp", "1", "--out", str(out),
                 "--aov", "normal", "--quiet"]) == 0, capsys.readouterr().err
    assert out.is_file() and not (tmp_path / "prod").exists()
    spec, _ = exr_channels(out)
    assert set(spec.channelnames) == {"R", "G", "B", "N.X", "N.Y", "N.Z"}


def test03_data_type_that_does_not_fit_is_a_warning_naming_the_var(tmp_path, monkeypatch,
                                                                   capsys):
    shot = tmp_path / "shot.usda"
    shot.write_text(_shot("", extra_var=", </Render/Vars/shortNormal>"))
    out = tmp_path / "x.exr"
    assert main(["render", str(shot), "--frames", "1", "--spp", "1", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "/Render/Vars/shortNormal" in err and "'float'" in err
    spec, _ = exr_channels(out)
    assert set(spec.channelnames) == {"R", "G", "B", "diffuse.R", "diffuse.G", "diffuse.B", "Z"}


def test04_product_name_without_frame_token_for_two_frames_names_the_product(tmp_path, capsys):
    shot = tmp_path / "shot.usda"
    shot.write_text(_shot(str(tmp_path / "one.exr")))
    code = main(["render", str(shot), "--frames", "1-2", "--spp", "1"])
    err = capsys.readouterr().err
    assert code == 2 and "/Render/Product: productName" in err, err
