"""Stage reader, meshes: triangulation and winding, primvars, subdivision cages,
intrinsic shapes, visibility and purpose, bad topology and points, a large mesh, concave
polygons."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from cmlt.usd import load_frame, open_stage, stage_info
from support.usd_checks import assert_clean, data, tri_normals


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
