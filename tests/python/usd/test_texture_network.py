"""UsdUVTexture networks beyond the plain case (issue 6): luminance textures
colour-converted, wrap ``useMetadata`` (the file's metadata, else black, as the
UsdPreviewSurface spec says), ``st`` through UsdTransform2d, and the
UsdPrimvarReader_float2 fallback where a mesh lacks the primvar."""
from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

import cmlt._core as core
from cmlt.color import ACESCG_LUMINANCE, get_config, load_config, set_config
from cmlt.scene import Camera, FrameScene, Instance, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge
from cmlt.shot.material_table import resolve_wrap_modes
from cmlt.usd import load_frame
from cmlt.usd.color import load_texture, texture_wrap_metadata
from cmlt.usd.materials import read_material


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _write(path, pixels, fmt=oiio.UINT8, attrs=None):
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    for k, v in (attrs or {}).items():
        spec.attribute(k, v)
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec), out.geterror()
    assert out.write_image(np.ascontiguousarray(pixels))
    out.close()
    return path


def _srgb_to_acescg(v):
    cfg = get_config()
    return np.asarray(cfg.to_rendering_space(np.asarray(v, np.float32), "sRGB"), np.float64)


# ---------------------------------------------------------------- luminance textures

def test01_one_channel_srgb_texture_is_linearised(tmp_path):
    lum = np.array([[[0], [64]], [[128], [255]]], np.uint8)
    path = _write(str(tmp_path / "l.png"), lum)
    got = load_texture(path, "sRGB")
    assert got.shape == (2, 2, 1)
    grey = np.repeat(lum.astype(np.float32) / 255.0, 3, axis=2)
    want = _srgb_to_acescg(grey) @ np.asarray(ACESCG_LUMINANCE)
    np.testing.assert_allclose(got[..., 0], want, rtol=1e-5, atol=1e-6)
    # the sRGB curve is undone: 128/255 -> ~0.216, not 0.502
    assert 0.2 < got[1, 0, 0] < 0.23
    # grey stays grey: the one channel is each of ACEScg R, G, B of that grey
    np.testing.assert_allclose(_srgb_to_acescg(grey)[1, 0], got[1, 0, 0], rtol=2e-3)
    # auto: sRGB only for 8-bit 3/4-channel files (spec), so a 1-channel map is as read
    np.testing.assert_allclose(load_texture(path, "auto")[..., 0], lum[..., 0] / 255.0,
                               rtol=1e-6)
    np.testing.assert_allclose(load_texture(path, "raw")[..., 0], lum[..., 0] / 255.0,
                               rtol=1e-6)


def test02_two_channel_texture_keeps_its_alpha(tmp_path):
    la = np.array([[[128, 10], [255, 200]]], np.uint8)
    path = _write(str(tmp_path / "la.png"), la)
    got = load_texture(path, "sRGB")
    assert got.shape == (1, 2, 2)
    np.testing.assert_allclose(got[..., 1], la[..., 1] / 255.0, rtol=1e-6)   # alpha untouched
    # (OIIO hands PNG luminance over alpha-associated; convert what it read)
    raw = load_texture(path, "raw")
    want = _srgb_to_acescg(np.repeat(raw[..., :1], 3, axis=2)) @ np.asarray(ACESCG_LUMINANCE)
    np.testing.assert_allclose(got[..., 0], want, rtol=1e-5, atol=1e-7)
    assert not np.allclose(got[..., 0], raw[..., 0], rtol=1e-3)       # really converted


# ---------------------------------------------------------------- wrap modes

def test03_wrap_metadata_of_the_file(tmp_path):
    img = np.zeros((2, 2, 3), np.float32)
    tagged = _write(str(tmp_path / "w.exr"), img, oiio.FLOAT, {"wrapmodes": "periodic,clamp"})
    assert texture_wrap_metadata(tagged) == ("repeat", "clamp")
    named = _write(str(tmp_path / "n.exr"), img, oiio.FLOAT, {"wrapS": "mirror",
                                                              "wrapT": "black"})
    assert texture_wrap_metadata(named) == ("mirror", "black")
    plain = _write(str(tmp_path / "p.png"), np.zeros((2, 2, 3), np.uint8))
    assert texture_wrap_metadata(plain) == (None, None)
    assert texture_wrap_metadata(str(tmp_path / "missing.png")) == (None, None)
    # useMetadata: the file's, else black (spec); authored modes win
    assert resolve_wrap_modes(tagged, "useMetadata", "useMetadata") == ("repeat", "clamp")
    assert resolve_wrap_modes(plain, "useMetadata", "useMetadata") == ("black", "black")
    assert resolve_wrap_modes(plain, None, "mirror") == ("black", "mirror")
    assert resolve_wrap_modes(tagged, "clamp", "repeat") == ("clamp", "repeat")


def test04_unknown_wrap_token_warns(tmp_path):
    stage, mat, tex = _texture_stage(tmp_path)
    tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("tile")
    warnings = []
    m = read_material(mat, 0, warnings)
    assert m.inputs["diffuseColor"]["wrapS"] == "useMetadata"
    assert any("inputs:wrapS = 'tile'" in w and str(tex.GetPath()) in w for w in warnings)


# ---------------------------------------------------------------- st networks

def _texture_stage(tmp_path, reader_fallback=None, varname="st"):
    stage = Usd.Stage.CreateNew(str(tmp_path / "t.usda"))
    mat = UsdShade.Material.Define(stage, "/M")
    surf = UsdShade.Shader.Define(stage, "/M/S")
    surf.CreateIdAttr("UsdPreviewSurface")
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    tex = UsdShade.Shader.Define(stage, "/M/T")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath("./tex.png"))
    tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        tex.ConnectableAPI(), "rgb")
    reader = UsdShade.Shader.Define(stage, "/M/R")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set(varname)
    if reader_fallback is not None:
        reader.CreateInput("fallback", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*reader_fallback))
    reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    st = tex.CreateInput("st", Sdf.ValueTypeNames.Float2)
    st.ConnectToSource(reader.ConnectableAPI(), "result")
    return stage, mat, tex


def _transform2d(stage, path, src, output, scale=None, rotation=None, translation=None):
    node = UsdShade.Shader.Define(stage, path)
    node.CreateIdAttr("UsdTransform2d")
    node.CreateInput("in", Sdf.ValueTypeNames.Float2).ConnectToSource(src.ConnectableAPI(),
                                                                      output)
    if scale is not None:
        node.CreateInput("scale", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*scale))
    if rotation is not None:
        node.CreateInput("rotation", Sdf.ValueTypeNames.Float).Set(rotation)
    if translation is not None:
        node.CreateInput("translation", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*translation))
    node.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    return node


def _apply(m, s, t):
    return m[0] * s + m[1] * t + m[2], m[3] * s + m[4] * t + m[5]


def test05_transform2d_is_folded_into_the_record(tmp_path):
    stage, mat, tex = _texture_stage(tmp_path)
    reader = UsdShade.Shader(stage.GetPrimAtPath("/M/R"))
    xf = _transform2d(stage, "/M/X", reader, "result", scale=(2, 3), rotation=90,
                      translation=(0.5, 0.25))
    tex.GetInput("st").ConnectToSource(xf.ConnectableAPI(), "result")
    rec = read_material(mat, 0, []).inputs["diffuseColor"]
    assert rec["st_primvar"] == "st" and rec["st_fallback"] == (0.0, 0.0)
    m = rec["st_transform"]
    # in * scale * rotate + translation: (1, 0) -> (2, 0) -> (0, 2) -> (0.5, 2.25)
    assert _apply(m, 1, 0) == pytest.approx((0.5, 2.25))
    assert _apply(m, 0, 1) == pytest.approx((0.5 - 3, 0.25))
    # two nodes in a chain compose: the outer one applies last
    outer = _transform2d(stage, "/M/X2", xf, "result", translation=(1, 0))
    tex.GetInput("st").ConnectToSource(outer.ConnectableAPI(), "result")
    m2 = read_material(mat, 0, []).inputs["diffuseColor"]["st_transform"]
    assert _apply(m2, 1, 0) == pytest.approx((1.5, 2.25))


def _quad_scene(rec, res=(32, 32)):
    pts = padded_points([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    uv = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], np.float32)
    quad = Mesh("/quad", pts, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), uvs=uv)
    xf = np.eye(4)
    xf[2, 3] = 10.0
    cam = Camera("/cam", xf, focal_length=180, horizontal_aperture=36, vertical_aperture=36)
    mat = Material("/M", diffuse=(0, 0, 0), emission=(0.25, 0.25, 0.25),
                   use_specular_workflow=True, inputs={"emissiveColor": rec})
    return FrameScene(time=1.0, meshes=[quad], instances=[Instance("/quad", 0, np.eye(4))],
                      materials=[mat], camera=cam, resolution=res, meters_per_unit=1.0)


def _render(fs):
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.max_depth, st.seed, st.threads = 4, 1, 1, 2
    st.integrator = "pt"
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


BLOCKS = np.array([[[0.9, 0.1, 0.1], [0.1, 0.8, 0.1]],
                   [[0.1, 0.1, 0.7], [0.6, 0.5, 0.05]]], np.float32)


def _block_texture(tmp_path, name="b.exr", attrs=None):
    big = np.ascontiguousarray(np.repeat(np.repeat(BLOCKS, 4, 0), 4, 1))   # flat 4x4 blocks
    return _write(str(tmp_path / name), big, oiio.FLOAT, attrs)


def _expected(m, wrap):
    """Pixel value at the centre of each image quadrant: st at the quadrant
    centre, transformed by m, wrapped, then the flat block it lands in."""
    out = {}
    for r in range(2):
        for c in range(2):
            s, t = (c + 0.5) / 2, 1 - (r + 0.5) / 2
            s2, t2 = _apply(m, s, t)
            if wrap == "black" and not (0 <= s2 <= 1 and 0 <= t2 <= 1):
                out[r, c] = np.zeros(3)
                continue
            s2, t2 = s2 % 1.0, t2 % 1.0
            out[r, c] = BLOCKS[int((1 - t2) * 2), int(s2 * 2)]
    return out


@pytest.mark.parametrize("m,wrap", [
    ((1, 0, 0.5, 0, 1, 0), "repeat"),                  # translation by half the texture
    ((1, 0, 0.5, 0, 1, 0), "black"),                   # ... off its edge: black
    ((0, -1, 0, 1, 0, 0), "repeat"),                   # 90 degrees counter-clockwise
    ((1, 0, 0, 0, 1, 0), "repeat"),                    # identity
])
def test06_st_transform_moves_the_texture(tmp_path, m, wrap):
    path = _block_texture(tmp_path)
    rec = {"texture": path, "output": "rgb", "wrapS": wrap, "wrapT": wrap,
           "scale": (1, 1, 1, 1), "bias": (0, 0, 0, 0), "sourceColorSpace": "raw",
           "st_transform": m}
    img = _render(_quad_scene(rec))
    for (r, c), want in _expected(m, wrap).items():
        y, x = 8 + 16 * r, 8 + 16 * c
        np.testing.assert_allclose(img[y, x], want, rtol=1e-4, atol=1e-6, err_msg=str((r, c)))


def test07_use_metadata_wraps_black_without_metadata_and_by_the_file_with_it(tmp_path):
    m = (1, 0, 0.5, 0, 1, 0)
    for name, attrs, wrap in (("plain.exr", None, "black"),
                              ("tx.exr", {"wrapmodes": "periodic,periodic"}, "repeat")):
        path = _block_texture(tmp_path, name, attrs)
        rec = {"texture": path, "output": "rgb", "wrapS": "useMetadata",
               "wrapT": "useMetadata", "sourceColorSpace": "raw", "st_transform": m}
        img = _render(_quad_scene(rec))
        for (r, c), want in _expected(m, wrap).items():
            np.testing.assert_allclose(img[8 + 16 * r, 8 + 16 * c], want, rtol=1e-4, atol=1e-6)


# ---------------------------------------------------------------- primvar reader fallback

def _mesh_with_material(stage, mat, name, st=None):
    mesh = UsdGeom.Mesh.Define(stage, name)
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    if st is not None:
        pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                     UsdGeom.Tokens.vertex)
        pv.Set(st)
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    return mesh


def test08_missing_primvar_uses_the_readers_fallback(tmp_path):
    stage, mat, _ = _texture_stage(tmp_path, reader_fallback=(0.75, 0.25), varname="uvA")
    _mesh_with_material(stage, mat, "/without", st=[(0, 0), (1, 0), (1, 1), (0, 1)])
    fs = load_frame(stage, 0)
    mesh = next(m for m in fs.meshes if m.name == "/without")
    assert mesh.uvs is not None
    np.testing.assert_allclose(mesh.uvs, np.tile([0.75, 0.25], (len(mesh.uvs), 1)))
    assert any(w.startswith("/without: has no primvar uvA") and "/M/T" in w and
               "(0.75, 0.25)" in w for w in fs.warnings), fs.warnings


def test09_present_primvar_is_read_and_default_fallback_is_zero(tmp_path):
    stage, mat, _ = _texture_stage(tmp_path)          # varname st, fallback not authored
    st = [(0, 0), (1, 0), (1, 1), (0, 1)]
    _mesh_with_material(stage, mat, "/with", st=st)
    _mesh_with_material(stage, mat, "/bare")
    fs = load_frame(stage, 0)
    meshes = {m.name: m for m in fs.meshes}
    np.testing.assert_allclose(meshes["/with"].uvs, meshes["/with"].points[:, :2])
    np.testing.assert_allclose(meshes["/bare"].uvs, 0.0)          # the spec's (0, 0)
    assert not any(w.startswith("/with:") for w in fs.warnings)
