"""UsdPrimvarReader_* as inputs of UsdPreviewSurface: the value is read per
vertex from the gprim's primvar (constant, uniform, vertex and faceVarying
interpolation, indexed or not), converted to the rendering space for colour
inputs and interpolated at every hit by the core; a gprim without the primvar
gets the reader's fallback with a warning naming it. The Utah-teapot case
(displayColor routed through a material) renders in its colour, not grey."""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade

import cmlt._core as core
from cmlt.color import get_config, load_config, set_config
from cmlt.shot.bridge import SceneBridge
from cmlt.shot.material_table import primvar_layout
from cmlt.usd import load_frame

GREEN = (0.1, 0.7, 0.1)
RED = (0.8, 0.05, 0.05)
BLUE = (0.05, 0.05, 0.8)


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def acescg(rgb):
    return np.asarray(get_config().to_rendering_space(np.asarray([rgb], np.float32),
                                                      "lin_rec709"), np.float64)[0]


def _stage():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(180.0)         # 36 mm at 10 m: the 2 m quad fills the frame
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0)
    cam.AddTranslateOp().Set((0, 0, 10))
    return stage


def _quad(stage, path, z=0.0, two_faces=False):
    """[-1, 1]^2 at depth z facing the camera; two faces split at x = 0."""
    m = UsdGeom.Mesh.Define(stage, path)
    if two_faces:
        m.CreatePointsAttr([(-1, -1, z), (0, -1, z), (1, -1, z), (1, 1, z), (0, 1, z), (-1, 1, z)])
        m.CreateFaceVertexCountsAttr([4, 4])
        m.CreateFaceVertexIndicesAttr([0, 1, 4, 5, 1, 2, 3, 4])
    else:
        m.CreatePointsAttr([(-1, -1, z), (1, -1, z), (1, 1, z), (-1, 1, z)])
        m.CreateFaceVertexCountsAttr([4])
        m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateSubdivisionSchemeAttr("none")
    return m


def _material(stage, path, connections, constants=None):
    """A UsdPreviewSurface whose inputs ``connections`` = {input: (reader id,
    varname, fallback or None, input type)} are read by primvar readers."""
    mat = UsdShade.Material.Define(stage, path)
    surf = UsdShade.Shader.Define(stage, path + "/Surf")
    surf.CreateIdAttr("UsdPreviewSurface")
    for name, (value, vtype) in (constants or {}).items():
        surf.CreateInput(name, vtype).Set(value)
    for k, (name, (rid, varname, fallback, vtype)) in enumerate(connections.items()):
        r = UsdShade.Shader.Define(stage, f"{path}/Reader{k}")
        r.CreateIdAttr(rid)
        if varname is not None:
            r.CreateInput("varname", Sdf.ValueTypeNames.String).Set(varname)
        out_type = {"UsdPrimvarReader_float": Sdf.ValueTypeNames.Float,
                    "UsdPrimvarReader_int": Sdf.ValueTypeNames.Int,
                    "UsdPrimvarReader_float3": Sdf.ValueTypeNames.Float3,
                    "UsdPrimvarReader_float4": Sdf.ValueTypeNames.Float4}[rid]
        if fallback is not None:
            r.CreateInput("fallback", out_type).Set(fallback)
        r.CreateOutput("result", out_type)
        surf.CreateInput(name, vtype).ConnectToSource(r.ConnectableAPI(), "result")
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    return mat


def _bind(mesh, mat):
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)


def _primvar(mesh, name, vtype, interp, values, indices=None):
    pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(name, vtype, interp)
    pv.Set(values)
    if indices is not None:
        pv.SetIndices(indices)
    return pv


def _render(fs, spp=16):
    st = core.RenderSettings()
    st.pixel_filter = "box"    # per-pixel analytic expectation: the one-pixel box
    st.width, st.height = fs.resolution
    st.spp, st.max_depth, st.seed, st.threads = spp, 2, 3, 2
    st.integrator = "pt"
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


def _mesh(fs, name):
    return next(m for m in fs.meshes if m.name == name)


def _values(fs, name, varname):
    pvs = _mesh(fs, name).primvars
    return next(v for k, v in pvs.items() if k.varname == varname)


DIFFUSE_FROM_DISPLAY = {"diffuseColor": ("UsdPrimvarReader_float3", "displayColor", None,
                                         Sdf.ValueTypeNames.Color3f)}


# ------------------------------------------------------------------ the teapot case

def test01_display_color_through_a_material_renders_green_not_grey():
    stage = _stage()
    q = _quad(stage, "/Teapot")
    _primvar(q, "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.constant, [GREEN])
    _bind(q, _material(stage, "/Looks/Display", DIFFUSE_FROM_DISPLAY))
    fs = load_frame(stage, 0, resolution=(24, 24))
    assert not any("unsupported" in w for w in fs.warnings), fs.warnings
    img = _render(fs)
    want = acescg(GREEN)
    # white dome of radiance 1 over a diffuse quad: the mean is about the albedo
    # (ACEScg (0.30, 0.65, 0.17)), not the default grey 0.18 in every channel
    mean = img.reshape(-1, 3).mean(axis=0)
    assert mean[1] > 1.8 * mean[0] and mean[1] > 3 * mean[2], mean
    # the same as the constant diffuseColor (the per-hit interpolation of a constant
    # primvar is the constant up to float rounding)
    stage2 = _stage()
    q2 = _quad(stage2, "/Teapot")
    m2 = _material(stage2, "/Looks/Const", {}, {"diffuseColor": (GREEN, Sdf.ValueTypeNames.Color3f)})
    _bind(q2, m2)
    ref = _render(load_frame(stage2, 0, resolution=(24, 24)))
    np.testing.assert_allclose(mean, ref.reshape(-1, 3).mean(axis=0), rtol=2e-3)
    assert mean[1] == pytest.approx(want[1], rel=0.15)


# ------------------------------------------------------------------ interpolation

@pytest.mark.parametrize("interp", ["vertex", "uniform", "faceVarying", "faceVaryingIndexed"])
def test02_interpolations_give_the_authored_colour_per_vertex(interp):
    stage = _stage()
    q = _quad(stage, "/Q", two_faces=True)
    t = Sdf.ValueTypeNames.Color3fArray
    if interp == "vertex":        # points 0, 1, 4, 5: left/middle; 2, 3 right
        _primvar(q, "displayColor", t, "vertex", [RED, RED, BLUE, BLUE, RED, RED])
    elif interp == "uniform":
        _primvar(q, "displayColor", t, "uniform", [RED, BLUE])
    elif interp == "faceVarying":
        _primvar(q, "displayColor", t, "faceVarying", [RED] * 4 + [BLUE] * 4)
    else:
        _primvar(q, "displayColor", t, "faceVarying", [RED, BLUE], indices=[0] * 4 + [1] * 4)
    _bind(q, _material(stage, "/Looks/D", DIFFUSE_FROM_DISPLAY))
    fs = load_frame(stage, 0, resolution=(32, 32))
    mesh = _mesh(fs, "/Q")
    vals = _values(fs, "/Q", "displayColor")
    assert vals.shape == (len(mesh.points), 3) and vals.dtype == np.float32
    # every triangle of face 0 (x <= 0) is red at its corners, face 1 blue
    # (vertex: the middle column is red, so the right face blends)
    pts = mesh.points
    for tri in mesh.indices:
        cx = pts[tri, 0].mean()
        corner = vals[tri]
        if interp == "vertex":
            for v in tri:
                want = acescg(RED) if pts[v, 0] <= 0 else acescg(BLUE)
                np.testing.assert_allclose(vals[v], want, rtol=1e-5, atol=1e-6)
        else:
            want = acescg(RED) if cx < 0 else acescg(BLUE)
            np.testing.assert_allclose(corner, np.tile(want, (3, 1)), rtol=1e-5, atol=1e-6)
    img = _render(fs)
    left, right = img[:, 2:10].reshape(-1, 3).mean(0), img[:, 26:30].reshape(-1, 3).mean(0)
    assert left[0] > 4 * left[2], left                   # red side
    assert right[2] > 2 * right[0], right                # blue side (vertex: blended)
    if interp != "vertex":
        assert right[2] > 4 * right[0], right


def test03_vertex_colour_is_interpolated_across_the_surface():
    """Red on the left edge, blue on the right: the red fraction falls off
    linearly across the quad (barycentric interpolation at the hit)."""
    stage = _stage()
    q = _quad(stage, "/Q")
    _primvar(q, "displayColor", Sdf.ValueTypeNames.Color3fArray, "vertex",
             [(1, 0, 0), (0, 0, 1), (0, 0, 1), (1, 0, 0)])
    _bind(q, _material(stage, "/Looks/D", DIFFUSE_FROM_DISPLAY,
                       {"roughness": (1.0, Sdf.ValueTypeNames.Float)}))
    img = _render(load_frame(stage, 0, resolution=(32, 8)), spp=32)
    col = img.mean(axis=0)                               # (32, 3) per column
    frac = col[:, 0] / (col[:, 0] + col[:, 2])           # ACEScg red / (red + blue)
    x = (np.arange(32) + 0.5) / 32
    a, b = np.polyfit(x, frac, 1)
    assert a < -0.6, (a, b)                              # falls across the surface
    assert np.abs(frac - (a * x + b)).max() < 0.08       # and linearly
    assert frac[0] > 0.85 and frac[-1] < 0.15


# ------------------------------------------------------------------ scalar readers

def test04_opacity_from_display_opacity_cuts_out():
    """opacity <- UsdPrimvarReader_float(displayOpacity) with opacityThreshold
    0.5: the left face (opacity 0) shows the red emitter behind, the right
    face (opacity 1) hides it."""
    stage = _stage()
    q = _quad(stage, "/Veil", two_faces=True)
    _primvar(q, "displayOpacity", Sdf.ValueTypeNames.FloatArray, "uniform", [0.0, 1.0])
    mat = _material(stage, "/Looks/Veil",
                    {"opacity": ("UsdPrimvarReader_float", "displayOpacity", 1.0,
                                 Sdf.ValueTypeNames.Float)},
                    {"opacityThreshold": (0.5, Sdf.ValueTypeNames.Float),
                     "diffuseColor": ((0.0, 0.0, 0.0), Sdf.ValueTypeNames.Color3f)})
    _bind(q, mat)
    back = _quad(stage, "/Back", z=-1.0)
    _bind(back, _material(stage, "/Looks/Glow", {},
                          {"emissiveColor": ((1.0, 0.0, 0.0), Sdf.ValueTypeNames.Color3f),
                           "diffuseColor": ((0.0, 0.0, 0.0), Sdf.ValueTypeNames.Color3f)}))
    fs = load_frame(stage, 0, resolution=(32, 32))
    img = _render(fs, spp=4)
    left, right = img[8:24, 4:12].reshape(-1, 3).mean(0), img[8:24, 20:28].reshape(-1, 3).mean(0)
    assert left[0] > 0.5, left                           # the emitter through the cut-out
    assert right[0] < 0.05, right                        # the opaque black face


def test05_int_and_float4_readers():
    stage = _stage()
    q = _quad(stage, "/Q", two_faces=True)
    _primvar(q, "metal", Sdf.ValueTypeNames.IntArray, "uniform", [0, 1])
    _primvar(q, "tint", Sdf.ValueTypeNames.Float4Array, "constant", [(0.2, 0.4, 0.6, 0.9)])
    _bind(q, _material(stage, "/Looks/M", {
        "metallic": ("UsdPrimvarReader_int", "metal", None, Sdf.ValueTypeNames.Float),
        "diffuseColor": ("UsdPrimvarReader_float4", "tint", None, Sdf.ValueTypeNames.Color3f)}))
    fs = load_frame(stage, 0, resolution=(16, 16))
    mesh = _mesh(fs, "/Q")
    metal = _values(fs, "/Q", "metal")
    assert metal.shape == (len(mesh.points), 1)
    for tri in mesh.indices:
        want = 1.0 if mesh.points[tri, 0].mean() > 0 else 0.0
        np.testing.assert_array_equal(metal[tri, 0], want)
    np.testing.assert_allclose(_values(fs, "/Q", "tint"),
                               np.tile(acescg((0.2, 0.4, 0.6)), (len(mesh.points), 1)),
                               rtol=1e-5)
    # the bridge gives each request its own columns
    layout = primvar_layout(fs.materials)
    assert sorted((c, w) for c, w, _ in layout.values()) == [(0, 3), (3, 1)] or \
        sorted((c, w) for c, w, _ in layout.values()) == [(0, 1), (1, 3)]
    img = _render(fs)
    # metallic 1 with a dark tint reflects the white dome tinted: differs from the diffuse face
    assert not np.allclose(img[:, :8].mean((0, 1)), img[:, 8:].mean((0, 1)), rtol=0.05)


# ------------------------------------------------------------------ fallbacks

def test06_missing_primvar_uses_the_fallback_with_a_warning():
    stage = _stage()
    q = _quad(stage, "/Bare")
    _bind(q, _material(stage, "/Looks/D", {"diffuseColor": (
        "UsdPrimvarReader_float3", "displayColor", (0.6, 0.2, 0.1), Sdf.ValueTypeNames.Color3f)}))
    fs = load_frame(stage, 0, resolution=(16, 16))
    vals = _values(fs, "/Bare", "displayColor")
    np.testing.assert_allclose(vals, np.tile(acescg((0.6, 0.2, 0.1)), (len(vals), 1)), rtol=1e-5)
    assert any(w.startswith("/Bare: has no primvar displayColor") and "/Looks/D/Reader0" in w
               for w in fs.warnings), fs.warnings
    assert fs.materials[0].diffuse == pytest.approx(tuple(acescg((0.6, 0.2, 0.1))), rel=1e-5)


def test07_unsupported_inputs_and_missing_varname_warn_naming_the_material():
    stage = _stage()
    q = _quad(stage, "/Q")
    _primvar(q, "displayColor", Sdf.ValueTypeNames.Color3fArray, "constant", [GREEN])
    _bind(q, _material(stage, "/Looks/E", {
        "emissiveColor": ("UsdPrimvarReader_float3", "displayColor", (0.0, 0.0, 0.0),
                          Sdf.ValueTypeNames.Color3f),
        "roughness": ("UsdPrimvarReader_float", None, 0.25, Sdf.ValueTypeNames.Float)}))
    fs = load_frame(stage, 0, resolution=(8, 8))
    assert any(w.startswith("/Looks/E: input emissiveColor reads primvar displayColor")
               for w in fs.warnings), fs.warnings
    assert any(w.startswith("/Looks/E: input roughness is read by /Looks/E/Reader1") and
               "without a varname" in w for w in fs.warnings), fs.warnings
    m = fs.materials[0]
    assert m.emission == (0.0, 0.0, 0.0) and m.roughness == pytest.approx(0.25)


def test08_unbound_mesh_with_varying_display_color_is_coloured_per_vertex():
    stage = _stage()
    q = _quad(stage, "/Q", two_faces=True)
    _primvar(q, "displayColor", Sdf.ValueTypeNames.Color3fArray, "uniform", [RED, BLUE])
    fs = load_frame(stage, 0, resolution=(32, 32))
    assert fs.materials[_mesh(fs, "/Q").material_ids[0]].name == "<displayColor primvar>"
    img = _render(fs)
    left, right = img[:, 2:14].reshape(-1, 3).mean(0), img[:, 18:30].reshape(-1, 3).mean(0)
    assert left[0] > 4 * left[2] and right[2] > 4 * right[0], (left, right)


def test09_intrinsic_sphere_reads_its_constant_primvar():
    stage = _stage()
    s = UsdGeom.Sphere.Define(stage, "/Ball")
    s.CreateRadiusAttr(1.0)
    _primvar(s, "displayColor", Sdf.ValueTypeNames.Color3fArray, "constant", [GREEN])
    _bind(s, _material(stage, "/Looks/D", DIFFUSE_FROM_DISPLAY))
    fs = load_frame(stage, 0, resolution=(16, 16))
    vals = _values(fs, "/Ball", "displayColor")
    np.testing.assert_allclose(vals, np.tile(acescg(GREEN), (len(vals), 1)), rtol=1e-5)
    centre = _render(fs)[6:10, 6:10].reshape(-1, 3).mean(0)
    assert centre[1] > 1.8 * centre[0] and centre[1] > 3 * centre[2], centre
