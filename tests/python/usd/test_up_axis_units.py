"""Conform: a Z-up stage in centimetres renders as the same shot authored Y-up
in metres. The two stages are built here from one description: every point of
the Z-up one is 100 R p (R: 90 degrees about X, +Y to +Z), its camera and sun
are rotated by R (no scale), and its clipping range is in centimetres. The
lights are a sun and a lat-long textured DomeLight_1 whose poleAxis is left at
its default (``scene``: the stage's up axis), so only the up-axis rule puts its
sky overhead. Same seed, same primary samples: the images agree pixel for pixel
within float rounding; a legacy DomeLight (+Y pole in its own space, as UsdLux
specifies) without the authored rotation puts the sky sideways and must not
agree, and with ``OrientToStageUpAxis`` it must."""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux

import cmlt._core as core
from cmlt.color import load_config, set_config
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage

from support.scenes import uv_sphere

RES = (32, 24)


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


@pytest.fixture(scope="module")
def sky(tmp_path_factory):
    """Lat-long sky: blue above the horizon brightening towards the zenith, a warm
    patch at one longitude, dark brown ground below (rows from the top)."""
    import OpenImageIO as oiio
    h, w = 32, 64
    img = np.zeros((h, w, 3), np.float32)
    for r in range(h):
        if r < h // 2:
            img[r] = np.array((0.2, 0.4, 1.0)) * (1.0 + 2.0 * (h // 2 - r) / h)
        else:
            img[r] = (0.15, 0.08, 0.04)
    img[10:14, 40:46] = (8.0, 6.0, 3.0)
    path = str(tmp_path_factory.mktemp("sky") / "sky.exr")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(w, h, 3, oiio.FLOAT))
    out.write_image(img)
    out.close()
    return path


def _to_z_up(p):
    p = np.asarray(p, np.float64).reshape(-1, 3)
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)       # R = rotateX(90)


def _stage(path, sky, z_up, dome="DomeLight_1", orient=False):
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if z_up else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01 if z_up else 1.0)
    k = 100.0 if z_up else 1.0

    def points(p):
        p = _to_z_up(p) if z_up else np.asarray(p, np.float64).reshape(-1, 3)
        return [Gf.Vec3f(*(k * q)) for q in p]

    ground = UsdGeom.Mesh.Define(stage, "/World/Ground")
    ground.CreatePointsAttr(points([(-4, 0, -4), (4, 0, -4), (4, 0, 4), (-4, 0, 4)]))
    ground.CreateFaceVertexCountsAttr([4])
    ground.CreateFaceVertexIndicesAttr([0, 3, 2, 1])          # facing +Y (up)
    ground.CreateSubdivisionSchemeAttr("none")
    ground.CreateDisplayColorAttr([(0.5, 0.5, 0.5)])
    pts, tris, _ = uv_sphere(0.8, 12, 24)
    ball = UsdGeom.Mesh.Define(stage, "/World/Ball")
    ball.CreatePointsAttr(points(pts + np.array([0.6, 0.8, 0.0])))
    ball.CreateFaceVertexCountsAttr([3] * len(tris))
    ball.CreateFaceVertexIndicesAttr([int(i) for i in tris.reshape(-1)])
    ball.CreateSubdivisionSchemeAttr("none")
    ball.CreateDisplayColorAttr([(0.7, 0.3, 0.1)])

    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(24.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(27.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1 * k, 1000.0 * k))
    cam.AddTranslateOp().Set(Gf.Vec3d(*(k * (_to_z_up([0, 1.2, 6])[0] if z_up
                                                else np.array([0, 1.2, 6])))))
    cam.AddRotateXOp().Set(90.0 - 5.0 if z_up else -5.0)      # a little down at the ball
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.CreateIntensityAttr(20000.0)
    if z_up:                           # R rotY(30) rotX(-50): rotateX(90) is the first op
        sun.AddRotateXOp(opSuffix="up").Set(90.0)
    sun.AddRotateYOp().Set(30.0)
    sun.AddRotateXOp().Set(-50.0)
    if dome == "DomeLight_1":
        d = UsdLux.DomeLight_1.Define(stage, "/World/Sky")
    else:
        d = UsdLux.DomeLight.Define(stage, "/World/Sky")
        if orient:
            d.OrientToStageUpAxis()
    d.CreateTextureFileAttr(sky)
    d.CreateIntensityAttr(1.0)
    stage.GetRootLayer().Save()
    return path


def _render(path):
    fs = load_frame(open_stage(path), None)
    st = core.RenderSettings()
    st.width, st.height = RES
    st.spp, st.max_depth, st.seed, st.threads = 16, 3, 5, 2
    st.integrator = "pt"
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


def _close(a, b):
    """Relative mean absolute pixel difference."""
    return float(np.abs(a - b).mean() / np.abs(a).mean())


@pytest.fixture(scope="module")
def y_up(sky, tmp_path_factory):
    return _render(_stage(str(tmp_path_factory.mktemp("yup") / "y.usda"), sky, False))


def test01_z_up_centimetres_renders_as_y_up_metres(y_up, sky, tmp_path):
    z = _render(_stage(str(tmp_path / "z.usda"), sky, True))
    assert np.isfinite(z).all() and y_up.mean() > 0.05
    # the sky is in view: the top rows are blue, the ground below them is not
    assert y_up[:3, :, 2].mean() > 1.5 * y_up[:3, :, 0].mean()
    assert _close(y_up, z) < 0.02, _close(y_up, z)
    np.testing.assert_allclose(z.reshape(-1, 3).mean(0), y_up.reshape(-1, 3).mean(0), rtol=0.01)


def test02_legacy_dome_keeps_its_y_pole_and_orient_to_up_axis_fixes_it(y_up, sky, tmp_path):
    sideways = _render(_stage(str(tmp_path / "legacy.usda"), sky, True, dome="DomeLight"))
    assert _close(y_up, sideways) > 0.2, _close(y_up, sideways)
    oriented = _render(_stage(str(tmp_path / "oriented.usda"), sky, True, dome="DomeLight",
                              orient=True))
    assert _close(y_up, oriented) < 0.02, _close(y_up, oriented)


def test03_pole_axis_tokens(tmp_path, sky):
    from cmlt.usd.lights import dome_pole_axis
    stage = Usd.Stage.Open(_stage(str(tmp_path / "t.usda"), sky, True))
    prim = stage.GetPrimAtPath("/World/Sky")
    assert dome_pole_axis(prim) == "Z"                        # scene, on a Z-up stage
    prim.GetAttribute("poleAxis").Set("Y")
    assert dome_pole_axis(prim) == "Y"
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    prim.GetAttribute("poleAxis").Set("Z")
    assert dome_pole_axis(prim) == "Z"
    prim.GetAttribute("poleAxis").Set("scene")
    assert dome_pole_axis(prim) == "Y"
