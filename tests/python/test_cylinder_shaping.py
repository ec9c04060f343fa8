"""UsdLux CylinderLight and ShapingAPI through the USD reader and the core scene."""
from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom, UsdLux

from cmlt import _core as core
from cmlt.usd import load_frame


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


def test_core_accepts_cylinder_and_shaping_no_nan():
    s = core.Scene()
    s.add_light("cylinder", np.eye(4), (1.0, 2.0, 3.0), radius=0.1, length=2.0)
    s.add_light("cylinder", np.eye(4), (1.0, 2.0, 3.0), radius=0.0, length=0.0)
    s.add_light("rect", np.eye(4), (5.0, 5.0, 5.0), cone_angle=30.0, cone_softness=0.5,
                focus=1.0, focus_tint=(0.2, 0.2, 0.2))
    s.add_light("sphere", np.eye(4), (5.0, 5.0, 5.0), cone_angle=float("nan"))
