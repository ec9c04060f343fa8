"""Colour management: config loading, authored colours -> ACEScg, output
conversion, EXR header attributes, display/view.

Reference values come from three independent places: a processor built
directly with PyOpenColorIO (not through cmlt), the published Rec.709 -> AP1
matrix, and matrices computed here from CIE xy chromaticities with a Bradford
adaptation.
"""
from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import PyOpenColorIO as ocio
import pytest

import cmlt  # noqa: F401  (registers plugins before pxr is used)
from cmlt import color
from cmlt.color import ColorError, load_config

# Rec.709 (D65) -> ACEScg (AP1, ACES white), Bradford CAT, as published
# (e.g. the ACES documentation and colour-science); row 1 is 0.6131 0.3395 0.0474.
REC709_TO_AP1 = np.array([[0.6131, 0.3395, 0.0474],
                          [0.0702, 0.9164, 0.0135],
                          [0.0206, 0.1096, 0.8698]])
AP1_CHROMATICITIES = [0.713, 0.293, 0.165, 0.830, 0.128, 0.044, 0.32168, 0.33767]

BRADFORD = np.array([[0.8951, 0.2664, -0.1614],
                     [-0.7502, 1.7135, 0.0367],
                     [0.0389, -0.0685, 1.0296]])


@pytest.fixture(scope="module")
def cfg():
    saved = os.environ.pop("OCIO", None)
    try:
        yield load_config()
    finally:
        if saved is not None:
            os.environ["OCIO"] = saved


@pytest.fixture(scope="module")
def raw_ocio():
    """The same built-in config, loaded without cmlt."""
    return ocio.Config.CreateFromFile("ocio://studio-config-latest")


def ocio_apply(config, src, dst, rgb):
    cpu = config.getProcessor(src, dst).getDefaultCPUProcessor()
    arr = np.array(rgb, dtype=np.float32).reshape(-1, 3).copy()
    cpu.applyRGB(arr)
    return arr.reshape(np.shape(rgb))


def rgb_to_xyz(chroma):
    """RGB -> XYZ matrix and white XYZ from 8 chromaticities."""
    xy = np.asarray(chroma, dtype=np.float64).reshape(4, 2)
    P = np.array([[x / y, 1.0, (1 - x - y) / y] for x, y in xy[:3]]).T
    white = np.array([xy[3, 0] / xy[3, 1], 1.0, (1 - xy[3].sum()) / xy[3, 1]])
    return P * np.linalg.solve(P, white), white


def matrix_between(src_chroma, dst_chroma):
    A, wa = rgb_to_xyz(src_chroma)
    B, wb = rgb_to_xyz(dst_chroma)
    cat = np.linalg.inv(BRADFORD) @ np.diag((BRADFORD @ wb) / (BRADFORD @ wa)) @ BRADFORD
    return np.linalg.inv(B) @ cat @ A


def srgb_eotf(v):
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


# -- 1. the config -------------------------------------------------------------------

def test01_builtin_config_is_the_latest_aces_studio_config(cfg):
    resolved = ocio.ResolveConfigPath("ocio://studio-config-latest")
    assert cfg.source == "built-in"
    assert cfg.location == "ocio://studio-config-latest"
    assert "ocio://" + cfg.name == resolved
    assert cfg.name.startswith("studio-config-v")
    assert cfg.rendering_space == "ACEScg"
    assert cfg.ocio.getColorSpace("scene_linear").getName() == "ACEScg"


def test02_ocio_env_and_explicit_path(tmp_path, monkeypatch, raw_ocio):
    path = tmp_path / "studio.ocio"
    path.write_text(raw_ocio.serialize())
    monkeypatch.setenv("OCIO", str(path))
    from_env = load_config()
    assert from_env.source == "$OCIO" and from_env.location == str(path)
    assert from_env.rendering_space == "ACEScg"
    # an explicit path wins over $OCIO
    monkeypatch.setenv("OCIO", str(tmp_path / "missing.ocio"))
    explicit = load_config(path)
    assert explicit.source == "--ocio-config"


def test03_config_errors_name_the_path_and_where_it_came_from(tmp_path, monkeypatch):
    missing = tmp_path / "nope.ocio"
    with pytest.raises(ColorError, match=r"nope\.ocio.*--ocio-config"):
        load_config(missing)
    broken = tmp_path / "broken.ocio"
    broken.write_text("ocio_profile_version: 2\nroles: [this is not yaml for a config\n")
    monkeypatch.setenv("OCIO", str(broken))
    with pytest.raises(ColorError, match=r"broken\.ocio.*\$OCIO"):
        load_config()


def test04_config_without_acescg_is_rejected(tmp_path):
    cfg = ocio.Config.CreateRaw()            # only "raw"
    path = tmp_path / "raw.ocio"
    path.write_text(cfg.serialize())
    with pytest.raises(ColorError, match="no ACEScg"):
        load_config(path)


def test05_stage_color_configuration(tmp_path, monkeypatch, raw_ocio):
    from pxr import Sdf, Usd
    monkeypatch.delenv("OCIO", raising=False)
    (tmp_path / "show.ocio").write_text(raw_ocio.serialize())
    stage = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    stage.SetColorConfiguration(Sdf.AssetPath("show.ocio"))     # relative to the layer
    stage.SetColorManagementSystem("OCIO")
    cfg = load_config(stage=stage)
    assert cfg.source == "stage colorConfiguration"
    assert cfg.location == str(tmp_path / "show.ocio")
    stage.SetColorManagementSystem("somethingElse")               # not ours: ignored
    assert load_config(stage=stage).source == "built-in"


# -- 2. authored colours -> ACEScg ---------------------------------------------------------

@pytest.mark.parametrize("name", ["lin_rec709", "Linear Rec.709 (sRGB)", "lin_rec709_scene",
                                  None, "", "unknown"])
def test06_linear_rec709_red_matches_ocio_and_published_matrix(cfg, raw_ocio, name):
    got = color.to_rendering_space((1.0, 0.0, 0.0), name, config=cfg)
    assert isinstance(got, tuple) and len(got) == 3
    expected_ocio = ocio_apply(raw_ocio, "Linear Rec.709 (sRGB)", "ACEScg", [1.0, 0.0, 0.0])
    np.testing.assert_allclose(got, expected_ocio, atol=1e-6)
    np.testing.assert_allclose(got, REC709_TO_AP1[:, 0], atol=1e-4)


def test07_whole_rec709_matrix(cfg):
    M = np.array([color.to_rendering_space(e, "lin_rec709", config=cfg) for e in np.eye(3)]).T
    np.testing.assert_allclose(M, REC709_TO_AP1, atol=1e-4)
    np.testing.assert_allclose(M[0], [0.6131, 0.3395, 0.0474], atol=1e-4)


@pytest.mark.parametrize("name,bit_depth", [("sRGB", None), ("srgb_rec709", None),
                                            ("sRGB Encoded Rec.709 (sRGB)", None),
                                            ("srgb_tx", None), ("auto", np.uint8), ("auto", 8)])
def test08_srgb_texture_values(cfg, raw_ocio, name, bit_depth):
    rng = np.random.default_rng(1)
    tex = (rng.integers(0, 256, size=(4, 5, 3)) / 255.0).astype(np.float32)
    tex[0, 0] = 128 / 255.0
    got = color.to_rendering_space(tex, name, bit_depth=bit_depth, config=cfg)
    assert got.dtype == np.float32 and got.shape == tex.shape
    expected_ocio = ocio_apply(raw_ocio, "sRGB Encoded Rec.709 (sRGB)", "ACEScg", tex)
    np.testing.assert_allclose(got, expected_ocio, atol=1e-6)
    expected_formula = srgb_eotf(tex) @ REC709_TO_AP1.T
    np.testing.assert_allclose(got, expected_formula, atol=1e-4)
    # sRGB 128/255 is 0.2158605 linear; grey stays grey in AP1
    np.testing.assert_allclose(got[0, 0], [0.2158605] * 3, atol=1e-5)
    assert not np.shares_memory(got, tex)


def test09_auto_is_linear_for_float_textures_and_raw_is_untouched(cfg):
    tex = np.random.default_rng(2).random((3, 3, 3), dtype=np.float32)
    np.testing.assert_allclose(color.to_rendering_space(tex, "auto", bit_depth=np.float32,
                                                        config=cfg),
                               tex @ REC709_TO_AP1.T.astype(np.float32), atol=1e-4)
    np.testing.assert_allclose(color.to_rendering_space(tex, "auto", bit_depth=16, config=cfg),
                               tex @ REC709_TO_AP1.T.astype(np.float32), atol=1e-4)
    normals = np.array([[0.5, 0.5, 1.0], [0.2, 0.9, 0.7]], dtype=np.float32)
    for raw in ("raw", "RAW", "data", "Raw"):
        np.testing.assert_array_equal(color.to_rendering_space(normals, raw, config=cfg), normals)


@pytest.mark.parametrize("name", ["lin_ap1", "ACEScg", "lin_ap1_scene", "scene_linear"])
def test10_acescg_input_is_identity(cfg, name):
    v = (0.25, 0.5, 0.75)
    np.testing.assert_allclose(color.to_rendering_space(v, name, config=cfg), v, atol=1e-6)


def test11_aces2065_input(cfg, raw_ocio):
    v = np.array([[0.3, 0.6, 0.1]], dtype=np.float32)
    got = color.to_rendering_space(v, "ACES2065-1", config=cfg)
    np.testing.assert_allclose(got, ocio_apply(raw_ocio, "ACES2065-1", "ACEScg", v), atol=1e-6)
    assert not np.allclose(got, v, atol=1e-3)          # AP0 -> AP1 is not the identity


def test12_rgba_keeps_alpha(cfg):
    rgba = np.array([[[1.0, 0.0, 0.0, 0.25]]], dtype=np.float32)
    got = color.to_rendering_space(rgba, "lin_rec709", config=cfg)
    np.testing.assert_allclose(got[0, 0, :3], REC709_TO_AP1[:, 0], atol=1e-4)
    assert got[0, 0, 3] == np.float32(0.25)


def test13_unknown_colour_space_names_it_and_the_prim(cfg):
    with pytest.raises(ColorError, match=r"'lin_rec907'.*/World/Looks/Red"):
        color.to_rendering_space((1, 0, 0), "lin_rec907", prim="/World/Looks/Red", config=cfg)
    with pytest.raises(ColorError, match="'bogus'"):
        color.to_rendering_space(np.zeros((2, 2, 3)), "bogus", config=cfg)


# -- 3. output ---------------------------------------------------------------------------

@pytest.mark.parametrize("space", ["lin_rec709", "ACES2065-1", "Linear Rec.2020", "lin_p3d65"])
def test14_round_trip_is_identity(cfg, space):
    x = np.random.default_rng(3).random((8, 8, 3), dtype=np.float32) * 4.0
    there = color.to_rendering_space(x, space, config=cfg)
    back = color.from_rendering_space(there, space, config=cfg)
    np.testing.assert_allclose(back, x, rtol=1e-5, atol=1e-5)


def test15_default_output_is_acescg_unchanged(cfg):
    x = np.random.default_rng(4).random((4, 4, 3), dtype=np.float32)
    np.testing.assert_array_equal(color.from_rendering_space(x, config=cfg), x)
    np.testing.assert_array_equal(color.from_rendering_space(x, "ACEScg", config=cfg), x)


# -- 4. EXR header ---------------------------------------------------------------------------

def test16_header_attributes_for_acescg(cfg):
    attrs = color.header_attributes(config=cfg)
    assert attrs["oiio:ColorSpace"] == "lin_ap1_scene"
    assert attrs["chromaticities"] == pytest.approx(AP1_CHROMATICITIES, abs=1e-9)
    assert color.header_attributes("ACEScg", config=cfg) == attrs
    rec709 = color.header_attributes("lin_rec709", config=cfg)
    assert rec709["oiio:ColorSpace"] == "lin_rec709_scene"
    assert rec709["chromaticities"] == pytest.approx([0.64, 0.33, 0.30, 0.60, 0.15, 0.06,
                                                      0.3127, 0.3290])
    assert color.header_attributes("ACES2065-1", config=cfg)["oiio:ColorSpace"] == "lin_ap0_scene"


@pytest.mark.parametrize("space", ["lin_rec709", "Linear Rec.2020", "lin_p3d65",
                                   "ACES2065-1", "Linear AdobeRGB"])
def test17_chromaticity_table_agrees_with_ocio(cfg, raw_ocio, space):
    """Each tabulated gamut, turned into an RGB->AP1 matrix with Bradford,
    equals the matrix OCIO applies: the table and the config agree."""
    chroma = cfg.chromaticities(space)
    assert chroma is not None
    expected = matrix_between(chroma, AP1_CHROMATICITIES)
    got = ocio_apply(raw_ocio, cfg.resolve(space), "ACEScg", np.eye(3)).T
    np.testing.assert_allclose(got, expected, atol=2e-5)


def test18_exr_header_round_trip_through_oiio(cfg, tmp_path):
    path = str(tmp_path / "frame.exr")
    spec = oiio.ImageSpec(8, 4, 3, oiio.FLOAT)
    cfg.set_header_attributes(spec)
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec), out.geterror()
    out.write_image(np.ones((4, 8, 3), dtype=np.float32))
    out.close()
    back = oiio.ImageInput.open(path)
    rspec = back.spec()
    back.close()
    assert rspec.getattribute("oiio:ColorSpace") == "lin_ap1_scene"
    assert rspec.getattribute("colorInteropID") == "lin_ap1_scene"
    assert rspec.getattribute("chromaticities") == pytest.approx(AP1_CHROMATICITIES, abs=1e-6)
    assert cfg.colorspace_of_header(rspec) == "ACEScg"


def test19_exr_writer_takes_header_attributes(cfg, tmp_path):
    """The frame writer (cmlt.io.exr) accepts header_attributes() as is."""
    from cmlt.io.exr import write_exr
    path = str(tmp_path / "f.exr")
    write_exr(path, np.zeros((4, 8, 3), np.float32), colorspace=None,
              attributes=color.header_attributes("lin_rec709", config=cfg))
    inp = oiio.ImageInput.open(path)
    rspec = inp.spec()
    inp.close()
    assert rspec.getattribute("oiio:ColorSpace") == "lin_rec709_scene"
    assert rspec.getattribute("chromaticities") == pytest.approx(
        [0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290], abs=1e-6)


# -- 5. display / view ---------------------------------------------------------------------------

def test20_display_defaults_and_mid_grey(cfg, raw_ocio):
    assert cfg.default_display() == "sRGB - Display"
    view = cfg.default_view()
    assert view == raw_ocio.getDefaultView("sRGB - Display")
    grey = np.full((2, 2, 3), 0.18, dtype=np.float32)
    got = color.display_transform(grey, config=cfg)
    dvt = ocio.DisplayViewTransform(src="ACEScg", display="sRGB - Display", view=view)
    cpu = raw_ocio.getProcessor(dvt).getDefaultCPUProcessor()
    ref = grey.reshape(-1, 3).copy()
    cpu.applyRGB(ref)
    np.testing.assert_allclose(got.reshape(-1, 3), ref, atol=1e-6)
    # a tone-mapped view: not a plain sRGB encoding of 0.18 (0.4613)
    assert abs(float(got[0, 0, 0]) - 0.4613) > 0.05
    u8 = color.display_transform(grey, dtype=np.uint8, config=cfg)
    assert u8.dtype == np.uint8 and int(u8[0, 0, 0]) == int(np.rint(ref[0, 0] * 255))


def test21_unknown_display_or_view(cfg):
    with pytest.raises(ColorError, match="unknown display 'CRT'.*sRGB - Display"):
        color.display_transform(np.zeros((1, 1, 3)), "CRT", config=cfg)
    with pytest.raises(ColorError, match="unknown view 'Filmic'"):
        color.display_transform(np.zeros((1, 1, 3)), None, "Filmic", config=cfg)


# -- 6. what USD says ------------------------------------------------------------------------------

def test22_authored_colorspace():
    from pxr import Sdf, Usd, UsdShade
    stage = Usd.Stage.CreateInMemory()
    looks = stage.DefinePrim("/Looks", "Scope")
    shader = UsdShade.Shader.Define(stage, "/Looks/M/S")
    plain = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    plain.Set((1, 0, 0))
    assert color.authored_colorspace(plain) == "lin_rec709_scene"          # USD's default
    assert color.authored_colorspace(shader.GetPrim()) == "lin_rec709_scene"
    Usd.ColorSpaceAPI.Apply(looks).CreateColorSpaceNameAttr("srgb_rec709_scene")
    assert color.authored_colorspace(plain) == "srgb_rec709_scene"         # inherited
    plain.GetAttr().SetColorSpace("lin_ap1_scene")
    assert color.authored_colorspace(plain.GetAttr()) == "lin_ap1_scene"   # own metadata wins
    cfg = color.get_config()
    assert cfg.resolve(color.authored_colorspace(plain)) == "ACEScg"


def test23_texture_colorspace():
    from pxr import Sdf, Usd, UsdShade
    stage = Usd.Stage.CreateInMemory()
    tex = UsdShade.Shader.Define(stage, "/T")
    tex.CreateIdAttr("UsdUVTexture")
    f = tex.CreateInput("file", Sdf.ValueTypeNames.Asset)
    f.Set(Sdf.AssetPath("albedo.png"))
    assert color.texture_colorspace(tex) == "auto"
    f.GetAttr().SetColorSpace("srgb_rec709_scene")
    assert color.texture_colorspace(tex) == "srgb_rec709_scene"
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
    assert color.texture_colorspace(tex) == "raw"
    assert color.resolve("raw") is None
