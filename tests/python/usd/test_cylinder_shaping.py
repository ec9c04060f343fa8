"""UsdLux CylinderLight and ShapingAPI through the USD reader and the core scene."""
from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom, UsdLux

from cmlt import _core as core
from cmlt.scene import Camera, FrameScene, Instance, Light, Material
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame
from support.scenes import quad


def _stage():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    cyl = UsdLux.CylinderLight.Define(stage, "/World/tube")
    cyl.CreateRadiusAttr(0.1)
    cyl.CreateLengthAttr(2.0)
    cyl.CreateTreatAsLineAttr(True)
    rect = UsdLux.RectLight.Define(stage, "/World/spot")
    shaping = UsdLux.ShapingAPI.Apply(rect.GetPrim())
    shaping.CreateShapingConeAngleAttr(30.0)
    shaping.CreateShapingConeSoftnessAttr(0.25)
    shaping.CreateShapingFocusAttr(2.0)
    shaping.CreateShapingFocusTintAttr(Gf.Vec3f(0.5, 0.25, 0.0))
    cam = UsdGeom.Camera.Define(stage, "/World/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    return stage


def test_reader_fills_cylinder_and_shaping():
    scene = load_frame(_stage(), 0)
    L = {l.name.rsplit("/", 1)[-1]: l for l in scene.lights}
    tube, spot = L["tube"], L["spot"]
    assert tube.kind == "cylinder" and tube.treat_as_point
    assert (tube.length, tube.radius) == (2.0, 0.1) or np.allclose((tube.length, tube.radius), (2.0, 0.1))
    assert tube.cone_angle == 180.0 and tube.focus == 0.0
    assert np.isclose(spot.cone_angle, 30.0) and np.isclose(spot.cone_softness, 0.25)
    assert np.isclose(spot.focus, 2.0)
    assert np.allclose(spot.focus_tint, (0.5, 0.25, 0.0))


def _lit_floor(lights):
    """A 4 m floor (y = 0) under ``lights``, seen from 2 m above, 24 x 24 pixels."""
    cam_xf = np.eye(4)
    cam_xf[:3, :3] = DOWN
    cam_xf[:3, 3] = (0, 2, 0)
    return FrameScene(
        time=1.0, meshes=[quad("/floor", (0, 0, 0), (0, 0, 2), (2, 0, 0), 0)],
        instances=[Instance("/floor", 0, np.eye(4))],
        materials=[Material("/floor", diffuse=(0.5, 0.5, 0.5))], lights=lights,
        camera=Camera("/cam", cam_xf, focal_length=20, horizontal_aperture=36,
                      vertical_aperture=36),
        resolution=(24, 24), meters_per_unit=1.0)


#: local -Z (where lights and cameras face) -> world -Y
DOWN = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]


def _at(x, y, z, rotation=None):
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = rotation
    m[:3, 3] = (x, y, z)
    return m


def test_core_accepts_cylinder_and_shaping_no_nan():
    """Cylinder lights (a degenerate one too: zero radius and length) and shaped
    lights (a NaN cone angle too) are accepted by the core and render without a
    non-finite sample in PT and BDPT; the floor under them is lit."""
    lights = [
        Light("/tube", "cylinder", _at(0, 1, 0), (1.0, 2.0, 3.0), radius=0.1, length=2.0),
        Light("/flat_tube", "cylinder", _at(0.5, 1, 0), (1.0, 2.0, 3.0), radius=0.0,
              length=0.0),
        Light("/spot", "rect", _at(-0.5, 1, 0.5, DOWN), (5.0, 5.0, 5.0), cone_angle=30.0,
              cone_softness=0.5, focus=1.0, focus_tint=(0.2, 0.2, 0.2)),
        Light("/nan_cone", "sphere", _at(0.5, 1, -0.5), (5.0, 5.0, 5.0),
              cone_angle=float("nan")),
    ]
    scene = SceneBridge(core).update(_lit_floor(lights))
    assert scene.light_count == 4
    for integrator in ("pt", "bdpt"):
        st = core.RenderSettings()
        st.width = st.height = 24
        st.spp, st.seed, st.threads, st.max_depth, st.integrator = 16, 2, 2, 2, integrator
        r = core.render(scene, st)
        img = np.asarray(r.image)
        assert np.isfinite(img).all(), integrator
        assert r.stats["nan_samples"] == 0, integrator
        assert img.mean() > 0.01, integrator           # the lights reach the floor
