"""Subdivision surfaces in the stage reader: meshes whose subdivisionScheme
is catmullClark (USD's default), loop or bilinear are refined with
OpenSubdiv (level 2 unless ``cmlt:subdivisionLevel`` or
``set_default_subdiv_level`` says otherwise) onto their limit surface, with
creases and corners honoured, materials per authored face kept and primvars
carried along."""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade

import cmlt._core as core
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, stage_info
from cmlt.usd import mesh_subdivision as usd_mesh

CUBE_IDX = [0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5]
CUBE_PTS = [(x, y, z) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]
EDGES = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5),
         (2, 6), (3, 7)]


def _stage(scheme=None, creased=False, level=None):
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    m = UsdGeom.Mesh.Define(st, "/Cube")
    m.CreatePointsAttr(CUBE_PTS)
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr(CUBE_IDX)
    if scheme is not None:
        m.CreateSubdivisionSchemeAttr(scheme)
    if creased:
        m.CreateCreaseIndicesAttr([v for e in EDGES for v in e])
        m.CreateCreaseLengthsAttr([2] * 12)
        m.CreateCreaseSharpnessesAttr([10.0] * 12)
    if level is not None:
        m.GetPrim().CreateAttribute(usd_mesh.SUBDIV_LEVEL_ATTR, Sdf.ValueTypeNames.Int).Set(level)
    cam = UsdGeom.Camera.Define(st, "/Cam")
    cam.CreateFocalLengthAttr(100.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0)
    cam.AddTranslateOp().Set((0, 0, 10))
    return st, m


def _cube(fs):
    return next(x for x in fs.meshes if x.name == "/Cube")


@pytest.fixture(autouse=True)
def default_level():
    yield
    usd_mesh.set_default_subdiv_level(2)


def test01_default_catmull_clark_is_refined_to_a_round_limit():
    st, _ = _stage()                                  # no scheme authored: catmullClark
    fs = load_frame(st, 0)
    c = _cube(fs)
    assert len(c.indices) == 6 * 16 * 2               # level 2: 16 quads per face
    d = np.linalg.norm(c.points.astype(np.float64), axis=1)
    assert d.min() > 0.8 and d.max() < 0.87           # the cage spans 1 .. 1.73
    assert c.normals is not None and np.isfinite(c.normals).all()
    np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0, atol=1e-5)
    assert (np.einsum("ij,ij->i", c.normals, c.points) > 0.9 * d).all()   # outward, round
    notes = stage_info(st).notes
    assert any(n.startswith("/Cube: subdivisionScheme is catmullClark; refined with "
                            "OpenSubdiv to level 2") for n in notes), notes


def test02_levels_from_the_prim_and_the_api():
    st, _ = _stage(level=0)
    assert len(_cube(load_frame(st, 0)).points) == 8          # the control cage
    st, _ = _stage(level=3)
    assert len(_cube(load_frame(st, 0)).indices) == 6 * 64 * 2
    usd_mesh.set_default_subdiv_level(1)
    st, _ = _stage()
    assert len(_cube(load_frame(st, 0)).indices) == 6 * 4 * 2
    st, _ = _stage(scheme="none")
    assert len(_cube(load_frame(st, 0)).indices) == 12        # polygons: as authored
    with pytest.raises(ValueError, match="0..6"):
        usd_mesh.set_default_subdiv_level(9)


def test03_loop_and_bilinear():
    st, _ = _stage(scheme="bilinear")
    c = _cube(load_frame(st, 0))
    assert np.abs(c.points).max(axis=1).min() == pytest.approx(1.0, abs=1e-6)   # still a cube
    st, _ = _stage(scheme="loop")                     # Loop needs triangles: warned, Catmull-Clark
    fs = load_frame(st, 0)
    c = _cube(fs)
    assert len(c.indices) == 6 * 16 * 2 and np.isfinite(c.points).all()
    assert any(w.startswith("/Cube: subdivisionScheme loop needs triangles") for w in fs.warnings)
    tri = Usd.Stage.CreateInMemory()                  # a tetrahedron: Loop proper
    t = UsdGeom.Mesh.Define(tri, "/Tet")
    t.CreatePointsAttr([(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)])
    t.CreateFaceVertexCountsAttr([3] * 4)
    t.CreateFaceVertexIndicesAttr([0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2])
    t.CreateSubdivisionSchemeAttr("loop")
    m = load_frame(tri, 0).meshes[0]
    assert len(m.indices) == 4 * 16                   # 4 triangles per triangle per level
    d = np.linalg.norm(m.points, axis=1)
    assert d.max() < 0.5 and d.max() / d.min() < 1.3       # far inside the cage, round


def _coverage(st):
    fs = load_frame(st, 0, resolution=(48, 48))
    s = core.RenderSettings()
    s.pixel_filter = "box"    # per-pixel analytic expectation: the one-pixel box
    s.width, s.height = fs.resolution
    s.spp, s.max_depth, s.seed, s.threads = 4, 1, 1, 2
    s.integrator = "pt"
    img = np.asarray(core.render(SceneBridge(core).update(fs), s).image, np.float64)
    # the white dome is 1 where no geometry is; the grey cube's direct light is lower
    return float((img.mean(axis=2) < 0.9).mean())


def test04_creased_edges_stay_sharp():
    st, _ = _stage(creased=True)
    c = _cube(load_frame(st, 0))
    np.testing.assert_allclose(np.abs(c.points).max(axis=1), 1.0, atol=1e-5)   # on the faces
    # rendered: the sharp cube covers its square (2 m at 9 m, f 100 mm, 36 mm aperture:
    # 2 / 3.24 of the frame's width), the smooth limit clearly less
    sharp, smooth = _coverage(st), _coverage(_stage()[0])
    assert sharp == pytest.approx((2 / (9 * 0.36)) ** 2, abs=0.02)
    assert smooth < sharp - 0.08


def test05_materials_follow_the_authored_face():
    st, m = _stage()
    looks = {}
    for name, rgb in (("Red", (0.8, 0.1, 0.1)), ("Grey", (0.5, 0.5, 0.5))):
        mat = UsdShade.Material.Define(st, f"/Looks/{name}")
        sh = UsdShade.Shader.Define(st, f"/Looks/{name}/S")
        sh.CreateIdAttr("UsdPreviewSurface")
        sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
        mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        looks[name] = mat
    api = UsdShade.MaterialBindingAPI.Apply(m.GetPrim())
    api.Bind(looks["Grey"])
    sub = api.CreateMaterialBindSubset("front", [1])        # face 1: z = +1
    UsdShade.MaterialBindingAPI.Apply(sub.GetPrim()).Bind(looks["Red"])
    fs = load_frame(st, 0)
    c = _cube(fs)
    red = next(i for i, x in enumerate(fs.materials) if x.name == "/Looks/Red")
    tri_red = c.material_ids == red
    assert tri_red.sum() == 32                              # 16 refined quads, 2 triangles each
    centres = c.points[c.indices[tri_red]].mean(axis=1)
    assert (centres[:, 2] > 0.5).all()                      # all on the +z side


def test06_primvars_are_carried_through_the_refinement():
    st, m = _stage()
    pv = UsdGeom.PrimvarsAPI(m)
    pv.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                     UsdGeom.Tokens.uniform).Set([(1, 0, 0)] + [(0, 0, 1)] * 5)
    st_pv = pv.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    st_pv.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    st_pv.SetIndices([0, 1, 2, 3] * 6)
    fs = load_frame(st, 0)
    c = _cube(fs)
    assert c.uvs is not None
    assert c.uvs.min() >= -1e-6 and c.uvs.max() <= 1 + 1e-6
    # every refined face's corners span part of its face's unit square
    assert np.ptp(c.uvs[:, 0]) > 0.9 and np.ptp(c.uvs[:, 1]) > 0.9
    colours = next(v for k, v in c.primvars.items() if k.varname == "displayColor")
    red_rows = colours[:, 0] > colours[:, 2]
    # the red face (face 0, z = -1) keeps its colour on its 16 refined quads
    tri_red = red_rows[c.indices].all(axis=1)
    assert tri_red.sum() == 32
    assert (c.points[c.indices[tri_red]][..., 2].mean(axis=1) < -0.5).all()
