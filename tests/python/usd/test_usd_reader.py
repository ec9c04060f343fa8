"""Stage reader: transforms, instancing, cameras and render settings, stage info (tiny
stages in tests/data/usd and stages built in tmp_path). Meshes: test_usd_meshes.py;
materials and lights: test_usd_materials_lights.py; opening files: test_usd_files.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from cmlt.usd import UsdLoadError, load_frame, open_stage, stage_info
from support.usd_checks import assert_clean, data, world_points


def rot_z(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.mark.parametrize("t", [1.0, 3.5, 6.0, 11.0])
def test01_animated_transform_world_positions(t):
    stage = open_stage(data("anim.usda"))
    scene = load_frame(stage, t)
    assert_clean(scene)
    # translate (0..10 over 1..11) then rotateZ (0..90): p_world = T + Rz p
    a = (t - 1.0) / 10.0
    local = np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1)], dtype=np.float64)
    expected = (rot_z(90.0 * a) @ local.T).T + np.array([10.0 * a, 0, 0])
    np.testing.assert_allclose(world_points(scene, "/World/mover/tri"), expected, atol=1e-5)
    # deforming points interpolate too
    wave = world_points(scene, "/World/wave")
    np.testing.assert_allclose(wave[:, 2], 2.0 * a, atol=1e-6)


def test02_static_mesh_cached_deforming_flagged():
    stage = open_stage(data("anim.usda"))
    s1, s2 = load_frame(stage, 1), load_frame(stage, 2)
    m1 = {m.name: m for m in s1.meshes}
    m2 = {m.name: m for m in s2.meshes}
    assert not m1["/World/mover/tri"].deforming and m1["/World/wave"].deforming
    # static mesh: the very same arrays are handed out again
    assert m1["/World/mover/tri"].points is m2["/World/mover/tri"].points
    assert m1["/World/wave"].points is not m2["/World/wave"].points


def test03_meters_per_unit_and_up_axis():
    stage = open_stage(data("lights_units.usda"))
    scene = load_frame(stage, 0)
    assert scene.meters_per_unit == pytest.approx(0.01) and scene.up_axis == "Z"
    box = world_points(scene, "/World/box")          # 100 cm cube at x = 200 cm
    np.testing.assert_allclose(box.min(axis=0), [1.5, -0.5, -0.5], atol=1e-6)
    np.testing.assert_allclose(box.max(axis=0), [2.5, 0.5, 0.5], atol=1e-6)


def test04_instanceable_references_share_one_mesh():
    stage = open_stage(data("instancing.usda"))
    scene = load_frame(stage, 0)
    assert_clean(scene)
    placed = [i for i in scene.instances if i.name.endswith("/geo")]
    assert sorted(i.name for i in placed) == ["/World/a/geo", "/World/b/geo", "/World/c/geo"]
    assert len({i.mesh for i in placed}) == 1
    xs = sorted(i.transform[0, 3] for i in placed)
    assert xs == pytest.approx([10.0, 20.0, 30.0])


def test05_point_instancer_positions():
    stage = open_stage(data("instancing.usda"))
    scene = load_frame(stage, 0)
    inst = {i.name.split(":")[0]: i for i in scene.instances if "[" in i.name}
    assert sorted(inst) == ["/World/scatter[0]", "/World/scatter[1]", "/World/scatter[2]"]
    np.testing.assert_allclose(inst["/World/scatter[0]"].transform[:3, 3], [1, 100, 0])
    np.testing.assert_allclose(inst["/World/scatter[2]"].transform[:3, 3], [0, 100, 3])
    # prototype root scale 2 and the cube's own translate (0,0,5) inside it
    np.testing.assert_allclose(inst["/World/scatter[1]"].transform[:3, 3], [0, 102, 10])
    np.testing.assert_allclose(np.diag(inst["/World/scatter[1]"].transform)[:3], [2, 2, 2])
    assert inst["/World/scatter[0]"].mesh == inst["/World/scatter[2]"].mesh
    # prototypes are not rendered in place
    assert not any(i.name.startswith("/World/scatter/") for i in scene.instances)


def test06_point_instancer_mask_and_bad_proto_index(tmp_path):
    stage = Usd.Stage.CreateNew(str(tmp_path / "pi.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    pi = UsdGeom.PointInstancer.Define(stage, "/pi")
    UsdGeom.Sphere.Define(stage, "/pi/protos/s")
    pi.CreatePrototypesRel().SetTargets([Sdf.Path("/pi/protos/s")])
    pi.CreateProtoIndicesAttr([0, 0, 0, 5])
    pi.CreatePositionsAttr([(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)])
    pi.CreateIdsAttr([10, 11, 12, 13])
    pi.CreateInvisibleIdsAttr([11])
    stage.GetRootLayer().Save()
    scene = load_frame(open_stage(str(tmp_path / "pi.usda")), 0)
    xs = sorted(i.transform[0, 3] for i in scene.instances)
    assert xs == pytest.approx([0.0, 2.0])
    assert any("/pi: protoIndices refers to prototype 5" in w for w in scene.warnings)


def test15_camera_and_render_settings():
    stage = open_stage(data("lights_units.usda"))
    scene = load_frame(stage, 0)
    cam = scene.camera
    assert cam.name == "/World/cam" and scene.resolution == (320, 180)
    # 36 x 24 authored, 16:9 image: aspectRatioConformPolicy's fallback expandAperture
    # keeps the whole vertical aperture and widens the horizontal one to 24 * 16/9
    assert (cam.focal_length, cam.horizontal_aperture, cam.vertical_aperture) == \
        pytest.approx((35, 24 * 320 / 180, 24))
    assert cam.horizontal_aperture_offset == pytest.approx(1.0)
    assert (cam.near, cam.far) == pytest.approx((0.1, 1000.0))
    assert cam.focus_distance == pytest.approx(5.0) and cam.f_stop == pytest.approx(2.8)
    assert (cam.shutter_open, cam.shutter_close) == (-0.25, 0.25)
    assert cam.lens_unit == pytest.approx(0.001)
    # rotateX 90: the camera's -Z looks along world +Y, its +Y is world +Z
    np.testing.assert_allclose(cam.transform[:3, 3], [0, -10, 1], atol=1e-9)
    np.testing.assert_allclose(-cam.transform[:3, 2], [0, 1, 0], atol=1e-9)
    np.testing.assert_allclose(cam.transform[:3, 1], [0, 0, 1], atol=1e-9)
    # resolution argument overrides the settings
    assert load_frame(stage, 0, resolution=(64, 32)).resolution == (64, 32)


def test16_framing_camera_when_absent():
    scene = load_frame(open_stage(data("instancing.usda")), 0)
    cam = scene.camera
    assert cam.name == "<framing>"
    assert any("no camera; using a framing camera" in w for w in scene.warnings)
    # Y-up: looks down -Z, and every instance origin is inside the view frustum
    np.testing.assert_allclose(cam.transform[:3, :3], np.eye(3))
    inv = np.linalg.inv(cam.transform)
    tan_h = 0.5 * cam.horizontal_aperture / cam.focal_length
    tan_v = 0.5 * cam.vertical_aperture / cam.focal_length
    for inst in scene.instances:
        p = inv @ inst.transform[:, 3]
        assert p[2] < -cam.near
        assert abs(p[0] / -p[2]) <= tan_h and abs(p[1] / -p[2]) <= tan_v


def test17_framing_camera_z_up(tmp_path):
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.Sphere.Define(stage, "/s")
    cam = load_frame(stage, 0).camera
    np.testing.assert_allclose(-cam.transform[:3, 2], [0, 1, 0], atol=1e-12)   # looks +Y
    np.testing.assert_allclose(cam.transform[:3, 1], [0, 0, 1], atol=1e-12)    # Z up
    assert cam.transform[1, 3] < -0.05     # in front of the 1 cm sphere


def test18_several_cameras_warn_and_explicit_camera():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Camera.Define(stage, "/c1")
    UsdGeom.Camera.Define(stage, "/c2").CreateFocalLengthAttr(85.0)
    scene = load_frame(stage, 0)
    assert scene.camera.name == "/c1" and any("2 cameras" in w for w in scene.warnings)
    assert load_frame(stage, 0, camera="/c2").camera.focal_length == pytest.approx(85.0)


def test26_missing_camera_path_is_an_error():
    stage = open_stage(data("anim.usda"))
    with pytest.raises(UsdLoadError, match=r"camera /World/nocam does not exist"):
        load_frame(stage, 1, camera="/World/nocam")
    with pytest.raises(UsdLoadError, match=r"camera /World/mover is a Xform, not a Camera"):
        load_frame(stage, 1, camera="/World/mover")
    with pytest.raises(UsdLoadError, match=r"render settings /nope does not exist"):
        load_frame(stage, 1, render_settings="/nope")


def test28_stage_info_counts_and_time():
    info = stage_info(open_stage(data("anim.usda")))
    assert (info.start, info.end, info.fps, info.time_codes_per_second) == (1, 11, 24, 24)
    assert info.has_authored_time_range and info.frame_count == 11
    assert info.prim_counts == {"Xform": 2, "Mesh": 2}
    assert info.meshes == ["/World/mover/tri", "/World/wave"]
    info2 = stage_info(open_stage(data("lights_units.usda")))
    assert info2.render_settings == ["/settings"] and info2.cameras == ["/World/cam"]
    assert len(info2.lights) == 6 and info2.up_axis == "Z" and info2.meters_per_unit == 0.01
    assert ("/World/lights/portal", "PortalLight",
            "PortalLight lights are not supported and are not rendered") in info2.ignored


def test30_nested_instancing_inside_instanceable_assets():
    scene = load_frame(open_stage(data("nested_instancing.usda")), 0)
    assert_clean(scene)
    # 2 placements x 2 trees x (3 leaves + 1 trunk), two shared meshes
    assert len(scene.instances) == 16 and len(scene.meshes) == 2
    leaves = [i for i in scene.instances if i.name.endswith("/leaf")]
    assert len(leaves) == 12 and len({i.mesh for i in leaves}) == 1
    pos = sorted(tuple(np.round(i.transform[:3, 3], 6)) for i in leaves)
    expected = sorted((x, y, z) for x in (0.0, 10.0) for y in (1.0, 2.0, 3.0)
                      for z in (-100.0, 100.0))
    assert pos == expected
    # the first leaf is turned 90 degrees about Z by its quaternion
    first = [i for i in leaves if abs(i.transform[1, 3] - 1.0) < 1e-9]
    for i in first:
        np.testing.assert_allclose(i.transform[:3, :3], rot_z(90.0), atol=1e-3)  # quath


def test31_render_settings_selection(tmp_path):
    stage = Usd.Stage.CreateNew(str(tmp_path / "rs.usda"))
    from pxr import UsdRender
    UsdGeom.Camera.Define(stage, "/camA")
    UsdGeom.Camera.Define(stage, "/camB")
    a = UsdRender.Settings.Define(stage, "/Render/a")
    a.CreateResolutionAttr(Gf.Vec2i(100, 50))
    a.CreateCameraRel().SetTargets(["/camA"])
    b = UsdRender.Settings.Define(stage, "/Render/b")
    b.CreateResolutionAttr(Gf.Vec2i(200, 80))
    b.CreateCameraRel().SetTargets(["/camB"])
    scene = load_frame(stage, 0)                          # first settings prim
    assert (scene.resolution, scene.camera.name) == ((100, 50), "/camA")
    stage.SetMetadata("renderSettingsPrimPath", "/Render/b")   # stage metadata wins
    scene = load_frame(stage, 0)
    assert (scene.resolution, scene.camera.name) == ((200, 80), "/camB")
    scene = load_frame(stage, 0, render_settings="/Render/a", camera="/camB")
    assert (scene.resolution, scene.camera.name) == ((100, 50), "/camB")
