"""A camera under a scaled transform: its clipping range, focus distance and lens
unit are camera-space lengths and scale with it (the scale_1e-4 and scale_1e5 hard
cases rendered black or half lit when the clipping range ignored the scale)."""
import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

from cmlt.usd import load_frame, open_stage


def _stage(tmp_path, scale, mpu=1.0):
    path = str(tmp_path / f"cam_{scale:g}.usda")
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    root = UsdGeom.Xform.Define(stage, "/World")
    if scale != 1.0:
        root.AddScaleOp().Set(Gf.Vec3f(scale, scale, scale))
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, 1000.0))
    cam.CreateFocusDistanceAttr(3.0)
    cam.CreateFStopAttr(2.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 1, 5))
    box = UsdGeom.Cube.Define(stage, "/World/Box")
    box.CreateSizeAttr(1.0)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e5])
def test01_clipping_focus_and_lens_scale_with_the_camera_transform(tmp_path, scale):
    fs = load_frame(open_stage(_stage(tmp_path, scale)), 1.0, resolution=(8, 8))
    cam = fs.camera
    assert cam.near == pytest.approx(0.05 * scale, rel=1e-6)
    assert cam.far == pytest.approx(1000.0 * scale, rel=1e-6)
    assert cam.focus_distance == pytest.approx(3.0 * scale, rel=1e-6)
    assert cam.lens_unit == pytest.approx(0.1 * scale, rel=1e-6)
    # the pose stays rigid: the translation is scaled, the rotation part is orthonormal
    np.testing.assert_allclose(cam.transform[:3, 3], np.array([0, 1, 5]) * scale, rtol=1e-6)
    np.testing.assert_allclose(cam.transform[:3, :3], np.eye(3), atol=1e-12)


def test02_an_unscaled_camera_keeps_meters_per_unit_exactly(tmp_path):
    fs = load_frame(open_stage(_stage(tmp_path, 1.0, mpu=0.01)), 1.0, resolution=(8, 8))
    assert fs.camera.near == float(np.float32(0.05)) * 0.01
    assert fs.camera.lens_unit == 0.01 / 10.0
