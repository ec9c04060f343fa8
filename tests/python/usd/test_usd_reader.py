"""Stage reader: tiny stages in tests/data/usd and stages built in tmp_path."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from cmlt.scene import FrameScene
from cmlt.usd import UsdLoadError, load_frame, open_stage, stage_info
from cmlt.color import from_rendering_space
from cmlt.color import to_rendering_space as _to_acescg
import support


def acescg(rgb, source="lin_rec709"):
    """What the reader makes of an (untagged, linear Rec.709) authored colour."""
    return _to_acescg(tuple(float(c) for c in rgb), source)

DATA = str(support.DATA_USD)


def data(name):
    return os.path.join(DATA, name)


def world_points(scene: FrameScene, name: str) -> np.ndarray:
    """World positions (metres) of the instance called ``name``."""
    inst = next(i for i in scene.instances if i.name == name)
    p = scene.meshes[inst.mesh].points.astype(np.float64)
    return (inst.transform @ np.c_[p, np.ones(len(p))].T).T[:, :3]


def tri_normals(points, indices):
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(indices, dtype=np.int64)
    n = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def assert_clean(scene: FrameScene):
    """Contract checks: dtypes, shapes, no NaN, indices in range."""
    for m in scene.meshes:
        assert m.points.dtype == np.float32 and m.points.shape[1] == 3
        assert m.indices.dtype == np.uint32 and m.indices.shape[1] == 3
        assert np.isfinite(m.points).all()
        assert int(m.indices.max()) < len(m.points)
        for a in (m.normals, m.uvs):
            if a is not None:
                assert len(a) == len(m.points) and np.isfinite(a).all()
        assert m.material_ids.dtype == np.uint32 and len(m.material_ids) == len(m.indices)
        assert int(m.material_ids.max()) < len(scene.materials)
    for i in scene.instances:
        assert i.transform.shape == (4, 4) and np.isfinite(i.transform).all()


# --------------------------------------------------------------------- transforms

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


# --------------------------------------------------------------------- instancing

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


# --------------------------------------------------------------------- meshes

def test07_triangulation_and_left_handed():
    scene = load_frame(open_stage(data("polygons.usda")), 0)
    assert_clean(scene)
    meshes = {m.name: m for m in scene.meshes}
    polys = meshes["/World/polys"]
    # quad -> 2, pentagon -> 3, degenerate and hole dropped
    assert len(polys.indices) == 5
    assert set(polys.indices.reshape(-1).tolist()) == set(range(9))
    np.testing.assert_allclose(tri_normals(polys.points, polys.indices), [[0, 0, 1]] * 5, atol=1e-6)
    # triangles cover the quad (area 1) and the pentagon (area 2.5)
    p = polys.points.astype(np.float64)
    t = polys.indices.astype(np.int64)
    area = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    assert area[:2].sum() == pytest.approx(1.0) and area[2:].sum() == pytest.approx(2.5)
    lefty = meshes["/World/lefty"]
    np.testing.assert_allclose(tri_normals(lefty.points, lefty.indices), [[0, 0, -1]] * 2, atol=1e-6)
    assert any("/World/polys: 1 face(s) with fewer than 3 vertices dropped" in w
               for w in scene.warnings)


def test08_face_varying_normals_and_indexed_st_deindexed():
    scene = load_frame(open_stage(data("polygons.usda")), 0)
    m = {m.name: m for m in scene.meshes}["/World/hinge"]
    assert len(m.points) == 8           # the two shared points are split
    P, N, UV = m.points.astype(np.float64), m.normals, m.uvs
    s = 1 / math.sqrt(2)
    first, second = m.indices[:2].reshape(-1), m.indices[2:].reshape(-1)
    np.testing.assert_allclose(N[first], [[0, 0, 1]] * 6, atol=1e-6)
    np.testing.assert_allclose(N[second], [[-s, 0, s]] * 6, atol=1e-6)
    # st: first face (0,0),(1,0),(1,1),(0,1) at its corners, second face all index 4
    for v in set(first.tolist()):
        x, y = P[v, 0], P[v, 1]
        np.testing.assert_allclose(UV[v], [x, y], atol=1e-6)
    np.testing.assert_allclose(UV[second], [[0.5, 0.5]] * 6, atol=1e-6)
    # uniform normals primvar: each triangle's vertices carry its face normal
    u = {m.name: m for m in scene.meshes}["/World/uniform_normals"]
    np.testing.assert_allclose(u.normals[u.indices[0]], [[0, 0, 1]] * 3, atol=1e-6)
    np.testing.assert_allclose(u.normals[u.indices[1]], [[0, 1, 0]] * 3, atol=1e-6)
    np.testing.assert_allclose(u.uvs, u.points[:, :2], atol=1e-6)


def test09_subdivision_cage_noted_and_unsupported_prim_listed():
    stage = open_stage(data("polygons.usda"))
    info = stage_info(stage)
    assert any(n.startswith("/World/cage: subdivisionScheme is catmullClark") for n in info.notes)
    assert ("/World/hair", "BasisCurves",
            "BasisCurves are not supported and are not rendered") in info.ignored
    scene = load_frame(stage, 0)
    assert "/World/hair: BasisCurves are not supported and are not rendered" in scene.warnings
    cage = {m.name: m for m in scene.meshes}["/World/cage"]
    assert cage.normals is not None           # smooth-shaded cage
    report = info.format()
    assert "/World/hair [BasisCurves]" in report and "metersPerUnit 1" in report


def test10_intrinsic_shapes_tessellated(tmp_path):
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Sphere.Define(stage, "/s").CreateRadiusAttr(2.0)
    UsdGeom.Cube.Define(stage, "/c").CreateSizeAttr(3.0)
    cyl = UsdGeom.Cylinder.Define(stage, "/cy")
    cyl.CreateRadiusAttr(0.5)
    cyl.CreateHeightAttr(4.0)
    cyl.CreateAxisAttr("X")
    cap = UsdGeom.Capsule.Define(stage, "/ca")
    cap.CreateRadiusAttr(1.0)
    cap.CreateHeightAttr(2.0)
    UsdGeom.Cone.Define(stage, "/co")
    pl = UsdGeom.Plane.Define(stage, "/pl")
    pl.CreateWidthAttr(4.0)
    pl.CreateLengthAttr(6.0)
    pl.CreateAxisAttr("Y")
    scene = load_frame(stage, 0)
    assert_clean(scene)
    m = {x.name: x for x in scene.meshes}
    r = np.linalg.norm(m["/s"].points, axis=1)
    np.testing.assert_allclose(r, 2.0, rtol=1e-6)
    # smooth normals = radial on a sphere, and triangles face outwards
    np.testing.assert_allclose(m["/s"].normals, m["/s"].points / 2.0, atol=1e-5)
    for name in ("/s", "/c", "/cy", "/ca", "/co"):
        P = m[name].points.astype(np.float64)
        tn = tri_normals(P, m[name].indices)
        centroid = P[m[name].indices.astype(np.int64)].mean(axis=1)
        assert (np.einsum("ij,ij->i", tn, centroid) > -1e-9).all(), name
    np.testing.assert_allclose(np.abs(m["/c"].points).max(axis=0), [1.5] * 3)
    np.testing.assert_allclose(m["/cy"].points.max(axis=0), [2.0, 0.5, 0.5], atol=1e-6)
    np.testing.assert_allclose(m["/ca"].points.max(axis=0), [1, 1, 2.0], atol=1e-6)
    np.testing.assert_allclose(m["/pl"].points.max(axis=0), [3.0, 0, 2.0], atol=1e-6)
    np.testing.assert_allclose(m["/pl"].normals, [[0, 1, 0]] * 4)
    assert len(m["/s"].indices) >= 64 * 30


def test11_visibility_and_purpose(tmp_path):
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/a")
    UsdGeom.Sphere.Define(stage, "/a/shown")
    hidden = UsdGeom.Xform.Define(stage, "/a/hidden")
    hidden.CreateVisibilityAttr("invisible")
    UsdGeom.Sphere.Define(stage, "/a/hidden/s")
    UsdGeom.Sphere.Define(stage, "/a/guide").CreatePurposeAttr("guide")
    # asset with both render and proxy: proxy dropped
    UsdGeom.Scope.Define(stage, "/b/render").CreatePurposeAttr("render")
    UsdGeom.Sphere.Define(stage, "/b/render/hi")
    UsdGeom.Scope.Define(stage, "/b/proxy").CreatePurposeAttr("proxy")
    UsdGeom.Sphere.Define(stage, "/b/proxy/lo")
    # proxy alone: kept
    UsdGeom.Scope.Define(stage, "/c/proxy").CreatePurposeAttr("proxy")
    UsdGeom.Sphere.Define(stage, "/c/proxy/lo")
    # animated visibility
    v = UsdGeom.Sphere.Define(stage, "/d").CreateVisibilityAttr()
    v.Set("inherited", 0)
    v.Set("invisible", 1)
    names = {i.name for i in load_frame(stage, 0).instances}
    assert names == {"/a/shown", "/b/render/hi", "/c/proxy/lo", "/d"}
    assert "/d" not in {i.name for i in load_frame(stage, 1).instances}


# --------------------------------------------------------------------- materials

def test12_materials_subsets_textures_display_color():
    scene = load_frame(open_stage(data("materials.usda")), 0)
    assert_clean(scene)
    mats = scene.materials
    byname = {m.name: i for i, m in enumerate(mats)}
    red = mats[byname["/Looks/red"]]
    assert red.diffuse == pytest.approx(acescg((0.8, 0.1, 0.1)))
    assert (red.roughness, red.metallic, red.ior, red.opacity) == pytest.approx((0.3, 0.25, 1.33, 0.75))
    assert red.use_specular_workflow and red.specular == pytest.approx(acescg((0.5, 0.5, 0.5)))
    tex = mats[byname["/Looks/textured"]]
    d = tex.inputs["diffuseColor"]
    assert d["texture"].endswith(os.path.join("tex", "white.ppm")) and os.path.isabs(d["texture"])
    assert (d["wrapS"], d["wrapT"], d["sourceColorSpace"], d["st_primvar"]) == \
        ("repeat", "mirror", "sRGB", "uvA")
    assert d["scale"] == pytest.approx((2, 2, 2, 1))
    assert tex.diffuse == pytest.approx(acescg((0.2, 0.4, 0.6)))       # the texture's fallback
    assert tex.roughness == pytest.approx(0.4)                 # fallback .g for outputs:g
    meshes = {m.name: m for m in scene.meshes}
    # GeomSubset: face 1 (the triangle) is textured, faces 0 and 2 are red
    ids = meshes["/World/two_faces"].material_ids.tolist()
    r, t = byname["/Looks/red"], byname["/Looks/textured"]
    assert ids == [r, r, t, r, r]
    # the textured material's st primvar (uvA) is the mesh's uv set, not st
    np.testing.assert_allclose(meshes["/World/textured_quad"].uvs,
                               meshes["/World/textured_quad"].points[:, :2])
    painted = mats[meshes["/World/painted"].material_ids[0]]
    assert painted.diffuse == pytest.approx(acescg((0.1, 0.6, 0.2)))
    plain = mats[meshes["/World/plain"].material_ids[0]]
    assert plain.name == "<default>" and plain.diffuse == pytest.approx((0.18, 0.18, 0.18))
    odd = mats[meshes["/World/odd"].material_ids[0]]
    assert odd is plain and sum(m.name == "<default>" for m in mats) == 1
    assert any(w.startswith("/Looks/weird: no UsdPreviewSurface") for w in scene.warnings)
    # emissive material present: no default dome
    assert not any(l.name == "<default dome>" for l in scene.lights)


# --------------------------------------------------------------------- lights

def test13_light_radiance_sizes_and_units():
    scene = load_frame(open_stage(data("lights_units.usda")), 0)
    L = {l.name.rsplit("/", 1)[-1]: l for l in scene.lights}
    assert set(L) == {"rect", "sphere_old_names", "disk", "sun", "tube", "sky"}
    rect = L["rect"]
    # 2 m x 0.5 m authored (cm), x-scale 2: 4 m x 0.5 m; 10 * 2^2 * colour / 2 m^2
    assert (rect.width, rect.height) == pytest.approx((4.0, 0.5))
    assert rect.radiance == pytest.approx(acescg((20.0, 10.0, 5.0)))
    np.testing.assert_allclose(rect.transform[:3, :3], np.eye(3), atol=1e-12)   # rigid
    np.testing.assert_allclose(rect.transform[:3, 3], [0, 0, 3.0])
    assert rect.texture == "tex/rect.exr" and any("tex/rect.exr cannot be resolved" in w
                                                   for w in scene.warnings)
    sph = L["sphere_old_names"]                      # pre-21 attribute names
    assert sph.radius == pytest.approx(0.5) and sph.treat_as_point
    assert sph.radiance[0] == pytest.approx(3.0 / (4 * math.pi * 0.25))
    assert L["disk"].radius == pytest.approx(1.0) and L["disk"].radiance == pytest.approx((1, 1, 1))
    sun = L["sun"]
    omega = 2 * math.pi * (1 - math.cos(math.radians(0.5)))
    # the temperature colour has Rec.709 luminance 1 before conversion to ACEScg
    rec709 = from_rendering_space(np.array([sun.radiance], dtype=np.float32), "lin_rec709")[0]
    lum = 0.2126 * rec709[0] + 0.7152 * rec709[1] + 0.0722 * rec709[2]
    assert lum == pytest.approx(2.0 / omega, rel=1e-5)
    assert sun.radiance[0] > sun.radiance[1] > sun.radiance[2]  # 3000 K is orange
    assert (L["tube"].length, L["tube"].radius) == pytest.approx((1.0, 0.1))
    assert L["sky"].kind == "dome"
    assert any(w.startswith("/World/lights/portal: PortalLight") for w in scene.warnings)


def test14_default_dome_light_with_warning():
    scene = load_frame(open_stage(data("anim.usda")), 1)
    assert len(scene.lights) == 1 and scene.lights[0].kind == "dome"
    assert scene.lights[0].radiance == (1.0, 1.0, 1.0)
    assert any("no lights and no emissive materials" in w for w in scene.warnings)
    lit = load_frame(open_stage(data("lights_units.usda")), 0)
    assert not any("no lights" in w for w in lit.warnings)


# --------------------------------------------------------------------- camera

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


# --------------------------------------------------------------------- bad input

def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test19_missing_file(tmp_path):
    with pytest.raises(UsdLoadError, match=r"nope\.usda: no such file"):
        open_stage(str(tmp_path / "nope.usda"))


def test20_unreadable_layer(tmp_path):
    p = write(tmp_path, "broken.usda", '#usda 1.0\ndef Xform "a" (\n')
    with pytest.raises(UsdLoadError) as e:
        open_stage(p)
    assert "broken.usda" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("meta, message", [
    ("timeCodesPerSecond = 0", "timeCodesPerSecond is 0; it must be > 0"),
    ("timeCodesPerSecond = -24", "timeCodesPerSecond is -24; it must be > 0"),
    ("startTimeCode = 10\n endTimeCode = 1", "startTimeCode 10 is after endTimeCode 1"),
])
def test21_bad_time_metadata(tmp_path, meta, message):
    p = write(tmp_path, "t.usda", f"#usda 1.0\n(\n {meta}\n)\n")
    with pytest.raises(UsdLoadError, match=message) as e:
        open_stage(p)
    assert "t.usda" in str(e.value)


def test22_unresolved_reference_warns_naming_layer(tmp_path):
    p = write(tmp_path, "refs.usda", '#usda 1.0\ndef Xform "A" (\n references = @gone.usda@\n)\n'
              '{\n}\ndef Sphere "ok"\n{\n}\n')
    stage = open_stage(p)
    info = stage_info(stage)
    assert any("gone.usda" in w and "refs.usda" in w for w in info.warnings)
    scene = load_frame(stage, 0)
    assert any("gone.usda" in w and "refs.usda" in w for w in scene.warnings)
    assert [i.name for i in scene.instances] == ["/ok"]      # the rest loads


def mesh_stage(tmp_path, points, counts, indices, time_samples=False, name="m.usda"):
    stage = Usd.Stage.CreateNew(str(tmp_path / name))
    m = UsdGeom.Mesh.Define(stage, "/World/rock")
    m.CreateSubdivisionSchemeAttr("none")
    if time_samples:
        m.CreatePointsAttr().Set(points, 12)
    else:
        m.CreatePointsAttr(points)
    m.CreateFaceVertexCountsAttr(counts)
    m.CreateFaceVertexIndicesAttr(indices)
    UsdGeom.Sphere.Define(stage, "/World/fine")
    stage.GetRootLayer().Save()
    return open_stage(str(tmp_path / name))


def test23_out_of_range_indices_warn_and_skip(tmp_path):
    pts = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    stage = mesh_stage(tmp_path, pts, [3], [0, 1, 1500], time_samples=True)
    scene = load_frame(stage, 12)
    assert ("/World/rock: faceVertexIndices refers to point 1500 but points has 3 entries "
            "(time 12); not rendered") in scene.warnings
    assert [i.name for i in scene.instances] == ["/World/fine"]


def test24_counts_inconsistent_with_indices(tmp_path):
    stage = mesh_stage(tmp_path, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3, 3], [0, 1, 2])
    scene = load_frame(stage, 0)
    assert any(w.startswith("/World/rock: faceVertexCounts sums to 6 but faceVertexIndices "
                            "has 3 entries") for w in scene.warnings)
    assert [i.name for i in scene.instances] == ["/World/fine"]


def test25_nan_points_warn_and_drop_faces(tmp_path):
    nan = float("nan")
    pts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (nan, 0, 0)]
    stage = mesh_stage(tmp_path, pts, [3, 3], [0, 1, 2, 1, 3, 2])
    scene = load_frame(stage, 0)
    assert_clean(scene)
    assert any(w.startswith("/World/rock: 1 of 4 points are NaN/Inf") for w in scene.warnings)
    rock = {m.name: m for m in scene.meshes}["/World/rock"]
    assert rock.indices.tolist() == [[0, 1, 2]]
    # all points bad: the mesh is skipped, with a warning naming it
    stage = mesh_stage(tmp_path, [(nan, 0, 0)] * 3, [3], [0, 1, 2], name="m2.usda")
    scene = load_frame(stage, 0)
    assert "/World/rock" not in {i.name for i in scene.instances}
    assert any(w.startswith("/World/rock:") and "NaN" in w for w in scene.warnings)


def test26_missing_camera_path_is_an_error():
    stage = open_stage(data("anim.usda"))
    with pytest.raises(UsdLoadError, match=r"camera /World/nocam does not exist"):
        load_frame(stage, 1, camera="/World/nocam")
    with pytest.raises(UsdLoadError, match=r"camera /World/mover is a Xform, not a Camera"):
        load_frame(stage, 1, camera="/World/mover")
    with pytest.raises(UsdLoadError, match=r"render settings /nope does not exist"):
        load_frame(stage, 1, render_settings="/nope")


def test27_usdz_opens(tmp_path):
    from pxr import UsdUtils
    src = tmp_path / "a.usda"
    stage = Usd.Stage.CreateNew(str(src))
    UsdGeom.Cube.Define(stage, "/box")
    stage.GetRootLayer().Save()
    z = str(tmp_path / "a.usdz")
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(src)), z)
    scene = load_frame(open_stage(z), 0)
    assert [i.name for i in scene.instances] == ["/box"]


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


def test29_large_mesh_is_fast(tmp_path):
    import time
    n = 400                                 # 160k quads -> 320k triangles, faceVarying st
    g = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1)), -1).reshape(-1, 2)
    pts = np.c_[g, np.zeros(len(g))].astype(np.float32)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    v0 = (j * (n + 1) + i).reshape(-1)
    quads = np.stack([v0, v0 + 1, v0 + n + 2, v0 + n + 1], 1).reshape(-1)
    stage = Usd.Stage.CreateInMemory()
    m = UsdGeom.Mesh.Define(stage, "/grid")
    m.CreateSubdivisionSchemeAttr("none")           # a polygon mesh
    from pxr import Vt
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
    m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(n * n, 4, dtype=np.int32)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(quads.astype(np.int32)))
    st = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                              UsdGeom.Tokens.faceVarying)
    st.Set(Vt.Vec2fArray.FromNumpy((pts[quads][:, :2] / n).astype(np.float32)))
    t0 = time.perf_counter()
    scene = load_frame(stage, 0)
    elapsed = time.perf_counter() - t0
    grid = scene.meshes[0]
    assert len(grid.indices) == 2 * n * n
    assert len(grid.points) == (n + 1) ** 2       # equal st values per point: no split
    np.testing.assert_allclose(grid.uvs * n, grid.points[:, :2], atol=1e-3)
    assert elapsed < 5.0


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


def test32_concave_polygon_ear_clipped():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    m = UsdGeom.Mesh.Define(stage, "/L")
    m.CreateSubdivisionSchemeAttr("none")
    # an L-shaped hexagon, counter-clockwise, starting at a vertex that cannot see
    # the whole polygon (a fan from it would leave the L)
    m.CreatePointsAttr([(2, 1, 0), (1, 1, 0), (1, 2, 0), (0, 2, 0), (0, 0, 0), (2, 0, 0)])
    m.CreateFaceVertexCountsAttr([6])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 4, 5])
    scene = load_frame(stage, 0)
    mesh = scene.meshes[0]
    assert len(mesh.indices) == 4
    np.testing.assert_allclose(tri_normals(mesh.points, mesh.indices), [[0, 0, 1]] * 4, atol=1e-6)
    p = mesh.points.astype(np.float64)
    t = mesh.indices.astype(np.int64)
    area = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    assert area.sum() == pytest.approx(3.0)
    c = p[t].mean(axis=1)
    assert not ((c[:, 0] > 1) & (c[:, 1] > 1)).any()       # nothing in the L's notch
    assert any("/L: 1 concave polygon(s) triangulated by ear clipping" in w for w in scene.warnings)
