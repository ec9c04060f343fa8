"""A known colour through the whole pipeline (issue 6, "Proof").

Authored colours and texels arrive in the rendering space (ACEScg) with the
values OpenColorIO itself computes (a processor built here with
PyOpenColorIO, independently of cmlt.color); the EXR header names the colour
space; reading a written frame back with OpenImageIO gives exactly the image
that was rendered (float, zip).
"""
from __future__ import annotations

import os
import re

import numpy as np
import OpenImageIO as oiio
import PyOpenColorIO as ocio
import pytest
from pxr import Sdf, Usd, UsdShade

import cmlt.shot.frame_job as seqmod
from cmlt.io.atomic import TEMP_MARKER
from cmlt.color import GAMUT_CHROMATICITIES, get_config, load_config, set_config
from cmlt.shot import RenderOptions, render_sequence
from cmlt.usd import load_frame, open_stage
from cmlt.usd.color import load_texture, to_rendering_space


@pytest.fixture(scope="module")
def raw():
    """The built-in config, straight from PyOpenColorIO."""
    return ocio.Config.CreateFromFile("ocio://studio-config-latest")


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def ocio_convert(raw, src, rgb, dst="ACEScg"):
    cpu = raw.getProcessor(src, dst).getDefaultCPUProcessor()
    return np.array(cpu.applyRGB([float(c) for c in rgb]), dtype=np.float64)


def _stage_with_materials(path):
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(1)

    def material(mpath, rgb, colorspace=None, api_space=None):
        mat = UsdShade.Material.Define(stage, mpath)
        if api_space:
            Usd.ColorSpaceAPI.Apply(mat.GetPrim()).CreateColorSpaceNameAttr(api_space)
        sh = UsdShade.Shader.Define(stage, mpath + "/S")
        sh.CreateIdAttr("UsdPreviewSurface")
        inp = sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
        inp.Set(tuple(rgb))
        if colorspace:
            inp.GetAttr().SetColorSpace(colorspace)
        mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        return mat
    return stage, material


def test01_diffuse_colours_arrive_in_acescg_as_ocio_computes(tmp_path, raw):
    from cmlt.usd.materials import read_material

    stage, material = _stage_with_materials(tmp_path / "m.usda")
    rgb = (0.8, 0.2, 0.1)
    cases = {
        "/untagged": (material("/untagged", rgb), "Linear Rec.709 (sRGB)"),
        "/tagged": (material("/tagged", rgb, colorspace="lin_rec709_scene"),
                    "Linear Rec.709 (sRGB)"),
        "/srgb": (material("/srgb", rgb, colorspace="srgb_rec709_scene"),
                  "sRGB Encoded Rec.709 (sRGB)"),
        "/ap0": (material("/ap0", rgb, api_space="lin_ap0_scene"), "ACES2065-1"),
        "/acescg": (material("/acescg", rgb, colorspace="lin_ap1_scene"), "ACEScg"),
    }
    for name, (mat, src) in cases.items():
        m = read_material(mat, Usd.TimeCode.Default(), [])
        want = ocio_convert(raw, src, rgb)
        np.testing.assert_allclose(m.diffuse, want, rtol=1e-6, atol=1e-7, err_msg=name)
    # linear Rec.709 red is not ACEScg red: the conversion really happens
    assert read_material(cases["/untagged"][0], 0, []).diffuse[0] < 0.7
    np.testing.assert_allclose(read_material(cases["/acescg"][0], 0, []).diffuse, rgb, rtol=1e-6)


def test02_unknown_authored_colour_space_names_the_prim(tmp_path):
    from cmlt.color import ColorError
    from cmlt.usd.materials import read_material

    stage, material = _stage_with_materials(tmp_path / "m.usda")
    mat = material("/bad", (0.5, 0.5, 0.5), colorspace="not_a_space")
    with pytest.raises(ColorError, match=r"not_a_space.*/bad/S"):
        read_material(mat, 0, [])


@pytest.mark.parametrize("token,bits", [("sRGB", "uint8"), ("auto", "uint8"),
                                        ("raw", "uint8"), ("auto", "half")])
def test03_texture_authored_in_srgb_arrives_in_acescg(tmp_path, raw, token, bits):
    """A UsdUVTexture read by the loader: texels converted once, at load."""
    texels = np.array([[[0, 0, 0], [255, 128, 64]], [[10, 200, 30], [255, 255, 255]]],
                      dtype=np.uint8)
    ext = "png" if bits == "uint8" else "exr"
    tex_path = tmp_path / f"tex.{ext}"
    values = texels.astype(np.float32) / 255.0
    buf = oiio.ImageBuf(oiio.ImageSpec(2, 2, 3, oiio.UINT8 if bits == "uint8" else oiio.HALF))
    buf.set_pixels(oiio.ROI(0, 2, 0, 2, 0, 1, 0, 3), texels if bits == "uint8" else values)
    assert buf.write(str(tex_path)), buf.geterror()
    if bits == "half":
        values = values.astype(np.float16).astype(np.float32)

    stage, material = _stage_with_materials(tmp_path / "m.usda")
    mat = material("/tex", (0.2, 0.4, 0.6))
    sh = UsdShade.Shader(stage.GetPrimAtPath("/tex/S"))
    t = UsdShade.Shader.Define(stage, "/tex/T")
    t.CreateIdAttr("UsdUVTexture")
    t.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./tex.{ext}"))
    t.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(token)
    t.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    sh.GetInput("diffuseColor").ConnectToSource(t.ConnectableAPI(), "rgb")
    stage.GetRootLayer().Save()

    from cmlt.usd.materials import read_material
    m = read_material(UsdShade.Material(stage.GetPrimAtPath("/tex")), 0, [])
    rec = m.inputs["diffuseColor"]
    assert rec["sourceColorSpace"] == token
    got = load_texture(rec["texture"], rec["sourceColorSpace"])
    assert got.shape == (2, 2, 3) and got.dtype == np.float32
    src = {"sRGB": "sRGB Encoded Rec.709 (sRGB)", "raw": None}.get(
        token, "sRGB Encoded Rec.709 (sRGB)" if bits == "uint8" else "Linear Rec.709 (sRGB)")
    want = values if src is None else np.array(
        [ocio_convert(raw, src, px) for px in values.reshape(-1, 3)]).reshape(2, 2, 3)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
    if token == "sRGB":
        # sRGB 128/255 decodes to ~0.216 before the gamut change
        assert 0.1 < got[0, 1, 1] < 0.3


def test04_light_colour_and_display_colour_are_converted(tmp_path, raw):
    stage = Usd.Stage.CreateInMemory()
    from pxr import UsdGeom, UsdLux
    light = UsdLux.RectLight.Define(stage, "/L")
    light.CreateColorAttr((1.0, 0.5, 0.25))
    light.CreateIntensityAttr(2.0)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cube = UsdGeom.Mesh.Define(stage, "/M")
    cube.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    cube.CreateFaceVertexCountsAttr([3])
    cube.CreateFaceVertexIndicesAttr([0, 1, 2])
    cube.CreateDisplayColorAttr([(0.3, 0.6, 0.9)])
    fs = load_frame(stage, 0)
    rect = [l for l in fs.lights if l.name == "/L"][0]
    want_l = ocio_convert(raw, "Linear Rec.709 (sRGB)", (1.0, 0.5, 0.25))
    np.testing.assert_allclose(np.asarray(rect.radiance) / np.max(rect.radiance),
                               want_l / np.max(want_l), rtol=1e-5)
    mid = fs.meshes[0].material_ids[0]
    np.testing.assert_allclose(fs.materials[mid].diffuse,
                               ocio_convert(raw, "Linear Rec.709 (sRGB)", (0.3, 0.6, 0.9)),
                               rtol=1e-6)


def test05_to_rendering_space_never_returns_nan():
    out = to_rendering_space((float("nan"), float("inf"), 0.5))
    assert all(np.isfinite(out))


def _spy_writes(monkeypatch):
    written = {}
    real = seqmod.write_exr

    def spy(path, image, **kw):
        # the frame loop writes to a temporary name (cmlt.io.atomic) renamed afterwards:
        # key by the final name
        head, tail = os.path.split(path)
        m = re.match(r"^\.(.+)" + re.escape(TEMP_MARKER) + r".*?(\.[^.]*)$", tail)
        final = os.path.join(head, m.group(1) + m.group(2)) if m else path
        written[final] = np.array(image, dtype=np.float32, copy=True)
        return real(path, image, **kw)
    monkeypatch.setattr(seqmod, "write_exr", spy)
    return written


@pytest.mark.parametrize("output", [None, "lin_rec709"])
def test06_exr_header_and_exact_read_back(tiny_shot, tmp_path, monkeypatch, output):
    written = _spy_writes(monkeypatch)
    out = str(tmp_path / "o" / "f.####.exr")
    res = render_sequence(tiny_shot, "1:2", out,
                          RenderOptions(spp=2, threads=1, output_colorspace=output),
                          progress=False, quiet=True)
    assert len(res.written) == 2
    for path in res.written:
        inp = oiio.ImageInput.open(path)
        spec = inp.spec()
        pix = np.asarray(inp.read_image(oiio.FLOAT), dtype=np.float32)
        inp.close()
        assert spec.format == oiio.FLOAT and spec.get_string_attribute("compression") == "zip"
        np.testing.assert_array_equal(pix.reshape(spec.height, spec.width, -1),
                                      written[path])                       # exact
        cs = spec.get_string_attribute("oiio:ColorSpace")
        gamut = "ap1" if output is None else "rec709"
        assert cs == ("lin_ap1_scene" if output is None else "lin_rec709_scene")
        chroma = spec.getattribute("chromaticities")
        np.testing.assert_allclose(chroma, GAMUT_CHROMATICITIES[gamut], atol=1e-6)
        assert get_config().colorspace_of_header(spec) == get_config().resolve(
            output or "lin_ap1_scene")
