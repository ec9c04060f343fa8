"""Coordinates the renderer cannot trace are refused at scene build, naming the prim
(src/core/scene/coordinate_range.h): beyond +-1e15 in world or object space, or an
instance transform so degenerate (a 1e-30 scale) that its inverse sends the scene's
rays out of Embree's range. Before the guard, Embree aborted the whole process
(``ray.valid()``) on such stages, so the CLI cases run in a subprocess: an abort would
show as a signal, not as the exit status 1 of a named error."""
import os
import subprocess
import sys

import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
FOUND = os.path.join(ROOT, "tests", "data", "fuzz", "embree_ray_valid.usda")


def _render(stage, tmp_path, integrator="pssmlt"):
    out = str(tmp_path / "f.####.exr")
    proc = subprocess.run([sys.executable, "-m", "cmlt", "render", stage, "--frames", "0",
                           "--integrator", integrator, "--spp", "4", "--res", "16x12",
                           "--out", out, "-q"], capture_output=True, text=True, timeout=300)
    return proc, out


def _stage(tmp_path, scale=(1.0, 1.0, 1.0), translate=(0.0, 0.0, 0.0), ground=5.0):
    path = str(tmp_path / "s.usda")
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.Xform.Define(stage, "/World")
    g = ground
    ground = UsdGeom.Mesh.Define(stage, "/World/Ground")
    ground.CreatePointsAttr([(-g, 0, -g), (g, 0, -g), (g, 0, g), (-g, 0, g)])
    ground.CreateFaceVertexCountsAttr([4])
    ground.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    box = UsdGeom.Cube.Define(stage, "/World/Box")
    xf = UsdGeom.Xformable(box)
    xf.AddTranslateOp().Set(Gf.Vec3d(*translate))
    xf.AddScaleOp().Set(Gf.Vec3f(*scale))
    UsdLux.SphereLight.Define(stage, "/World/Lamp").AddTranslateOp().Set(Gf.Vec3d(0, 4, 0))
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 1, 8))
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(0)
    stage.GetRootLayer().Save()
    return path


def _refused(proc, out, prim, words):
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-800:])
    err = [line for line in proc.stderr.splitlines() if line.startswith("cmlt: error")]
    assert len(err) == 1 and prim in err[0] and words in err[0], proc.stderr[-800:]
    assert not os.path.exists(out.replace("####", "0000")), "an image was written"


def test01_the_stage_that_aborted_embree_fails_with_a_named_error(tmp_path):
    proc, out = _render(FOUND, tmp_path)
    _refused(proc, out, "/World/Mesh", "the renderer can trace")


def test02_a_tiny_instance_in_a_huge_scene_fails_naming_the_prim(tmp_path):
    # (a scale of 1e-30 on one axis is made 1e-6 of the largest by the reader; a
    # uniform 1e-12 is kept: rays from the 1e12-unit ground reach 1e24 in the cube's
    # object space)
    proc, out = _render(_stage(tmp_path, scale=(1e-12,) * 3, ground=1e12), tmp_path, "bdpt")
    _refused(proc, out, "/World/Box", "degenerate")


def test03_far_geometry_fails_naming_the_prim(tmp_path):
    proc, out = _render(_stage(tmp_path, translate=(0.0, 3.2e18, 0.0)), tmp_path, "pt")
    _refused(proc, out, "/World/Box", "world-space")


@pytest.mark.parametrize("scale", [(1e-6, 1.0, 1.0), (1e5, 1e5, 1e5)])
def test04_flat_and_large_instances_still_render(tmp_path, scale):
    proc, out = _render(_stage(tmp_path, scale=scale), tmp_path, "bdpt")
    assert proc.returncode == 0, proc.stderr[-800:]
    assert os.path.exists(out.replace("####", "0000"))
