"""``--default-light``: what lights a stage without lights or emissive materials.
Two diffuse quads of albedo 0.5 (no specular), one facing the camera, one turned
60 degrees towards the left; the pixel values are the irradiance each default
puts on them over pi, times the albedo:

* ``dome`` (white, radiance 1): 0.5 on both (the furnace hides the turn);
* ``headlight`` (irradiance pi along the view): 0.5 and 0.5 cos 60 = 0.25;
* ``dome-key`` (fill 0.25, key 0.8 pi from the camera's upper left):
  0.125 + 0.4 cos(key, n) on each."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

import cmlt._core as core
from cmlt.cli import main
from cmlt.color import load_config, set_config
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage, UsdLoadError

W, H = 48, 32


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _stage(path, with_light=False):
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(24.0)
    cam.AddTranslateOp().Set((0, 0, 10))
    mat = UsdShade.Material.Define(stage, "/World/Mat")
    surf = UsdShade.Shader.Define(stage, "/World/Mat/Surf")
    surf.CreateIdAttr("UsdPreviewSurface")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set((0.5, 0.5, 0.5))
    surf.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
    surf.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set((0, 0, 0))
    surf.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    for name, x, turn in (("Facing", -1.5, 0.0), ("Turned", 1.5, -60.0)):
        q = UsdGeom.Mesh.Define(stage, f"/World/{name}")
        q.CreatePointsAttr([(-0.6, -0.6, 0), (0.6, -0.6, 0), (0.6, 0.6, 0), (-0.6, 0.6, 0)])
        q.CreateFaceVertexCountsAttr([4])
        q.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        q.CreateSubdivisionSchemeAttr("none")
        q.AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
        q.AddRotateYOp().Set(turn)             # normal (sin turn, 0, cos turn)
        UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).Bind(mat)
    if with_light:
        UsdLux.SphereLight.Define(stage, "/World/Lamp").AddTranslateOp().Set((0, 3, 3))
    stage.GetRootLayer().Save()
    return path


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    return _stage(str(tmp_path_factory.mktemp("deflights") / "lightless.usda"))


def _patches(path, kind, spp=16):
    fs = load_frame(open_stage(path), None, resolution=(W, H), default_light=kind)
    st = core.RenderSettings()
    st.width, st.height = W, H
    st.spp, st.max_depth, st.seed, st.threads = spp, 1, 2, 2
    st.integrator = "pt"
    img = np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)
    # the quads' centres project to columns 14 (facing) and 34 (turned), row 16
    facing = img[14:19, 12:17, :3].mean(axis=(0, 1))
    turned = img[14:19, 33:36, :3].mean(axis=(0, 1))
    return fs, facing, turned


def test01_dome_hides_the_turn(shot):
    fs, facing, turned = _patches(shot, "dome")
    assert [l.name for l in fs.lights] == ["<default dome>"]
    assert any("adding a white dome light" in w for w in fs.warnings)
    # one quad does not see the other much: both about 0.5 (grey stays grey in ACEScg)
    np.testing.assert_allclose(facing, 0.5, rtol=0.04)
    np.testing.assert_allclose(turned, 0.5, rtol=0.06)


def test02_headlight_follows_the_camera(shot):
    fs, facing, turned = _patches(shot, "headlight")
    (light,) = fs.lights
    assert light.kind == "distant"
    # travels along the camera's view (its -Z) and the camera's -Z: the same direction
    np.testing.assert_allclose(light.transform[:3, 2], fs.camera.transform[:3, 2], atol=1e-9)
    assert any("adding a headlight" in w for w in fs.warnings)
    np.testing.assert_allclose(facing, 0.5, rtol=0.03)
    np.testing.assert_allclose(turned, 0.5 * math.cos(math.radians(60)), rtol=0.05)


def test03_dome_and_key(shot):
    # two lights, one picked per sample: more samples for the same noise (about 1 %)
    fs, facing, turned = _patches(shot, "dome-key", spp=256)
    assert sorted(l.kind for l in fs.lights) == ["distant", "dome"]
    key_to_light = np.array([-1.0, 1.0, 1.0]) / math.sqrt(3.0)     # camera frame = world
    n_turned = np.array([math.sin(math.radians(-60)), 0.0, math.cos(math.radians(-60))])
    want_facing = 0.25 * 0.5 + 0.8 * 0.5 * key_to_light @ np.array([0.0, 0.0, 1.0])
    want_turned = 0.25 * 0.5 + 0.8 * 0.5 * key_to_light @ n_turned
    np.testing.assert_allclose(facing, want_facing, rtol=0.04)
    np.testing.assert_allclose(turned, want_turned, rtol=0.04)
    assert turned.mean() > 1.15 * facing.mean()          # the key light shows the turn


def test04_a_stage_with_a_light_gets_none(tmp_path):
    path = _stage(str(tmp_path / "lit.usda"), with_light=True)
    for kind in ("dome", "headlight", "dome-key"):
        fs = load_frame(open_stage(path), None, default_light=kind)
        assert [l.name for l in fs.lights] == ["/World/Lamp"]


def test05_flag(shot, tmp_path, capsys):
    out = str(tmp_path / "h.exr")
    assert main(["render", shot, "--out", out, "--spp", "1", "--res", "16x12", "--threads",
                 "2", "--default-light", "headlight", "--log-json"]) == 0
    assert "adding a headlight" in capsys.readouterr().out
    assert main(["render", shot, "--out", out, "--default-light", "sun"]) == 2
    assert "--default-light" in capsys.readouterr().err
    with pytest.raises(UsdLoadError, match="default light 'sun'"):
        load_frame(open_stage(shot), None, default_light="sun")
