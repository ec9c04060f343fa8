"""Writes shot.usda (a static shot with hard lighting) next to this file.

Run it after editing: ``.venv/bin/python sequences/static_flicker/make_shot.py``.
The .usda is committed; this script makes it reproducible. It is written
with usd-core (pxr); the small helpers here (``new_stage``, ``box``,
``material``, ``render_settings``, ``look_at``) are also used by
``sequences/moving_light`` and ``sequences/door_ajar``.
"""
import math
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender, UsdShade, Vt

HERE = os.path.dirname(os.path.abspath(__file__))
FIRST, LAST = 1, 24


# --- helpers (shared with the other sequences) -------------------------------------------

def new_stage(path, root, doc):
    """A stage in centimetres, Y up, 24 fps, frames 1..24, with render settings
    found through ``renderSettingsPrimPath``."""
    if os.path.exists(path):
        os.remove(path)
    stage = Usd.Stage.CreateNew(path)
    stage.SetStartTimeCode(FIRST)
    stage.SetEndTimeCode(LAST)
    stage.SetTimeCodesPerSecond(24)
    stage.SetFramesPerSecond(24)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().documentation = doc
    prim = UsdGeom.Xform.Define(stage, f"/{root}").GetPrim()
    Usd.ModelAPI(prim).SetKind("assembly")
    stage.SetDefaultPrim(prim)
    UsdGeom.Scope.Define(stage, f"/{root}/Geometry")
    UsdGeom.Scope.Define(stage, f"/{root}/Lights")
    UsdGeom.Scope.Define(stage, f"/{root}/Looks")
    return stage


def material(stage, root, name, rgb, roughness=1.0):
    """A diffuse UsdPreviewSurface material."""
    mat = UsdShade.Material.Define(stage, f"/{root}/Looks/{name}")
    sh = UsdShade.Shader.Define(stage, f"/{root}/Looks/{name}/Surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*rgb))
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(roughness))
    sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def bind(prim, mat):
    UsdShade.MaterialBindingAPI.Apply(prim.GetPrim()).Bind(mat)


def box(stage, path, lo, hi, mat):
    """A closed axis-aligned box mesh from corner ``lo`` to ``hi`` (object
    space), six quads wound outwards, flat per-face normals."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pts, counts, idx, normals = [], [], [], []
    for axis in range(3):
        for side in (0, 1):
            n = np.zeros(3)
            n[axis] = 1.0 if side else -1.0
            a1, a2 = (axis + 1) % 3, (axis + 2) % 3
            corners = []
            for c1, c2 in ((lo[a1], lo[a2]), (hi[a1], lo[a2]), (hi[a1], hi[a2]), (lo[a1], hi[a2])):
                p = np.zeros(3)
                p[axis] = hi[axis] if side else lo[axis]
                p[a1], p[a2] = c1, c2
                corners.append(p)
            q = np.array(corners)
            if np.dot(np.cross(q[1] - q[0], q[2] - q[0]), n) < 0:
                q = q[::-1]
            assert np.dot(np.cross(q[1] - q[0], q[2] - q[0]), n) > 0
            base = len(pts)
            pts.extend(q.tolist())
            counts.append(4)
            idx.extend(range(base, base + 4))
            normals.extend([n.tolist()] * 4)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreateSubdivisionSchemeAttr("none")
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(idx)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts]))
    mesh.CreateNormalsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in normals]))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo), Gf.Vec3f(*hi)]))
    bind(mesh, mat)
    return mesh


def look_at(eye, target, up=(0, 1, 0)):
    """Transform whose local -Z points from ``eye`` to ``target`` (cameras and
    rect lights look down -Z), as a Gf.Matrix4d (USD row-vector convention)."""
    eye, target, up = (np.asarray(x, float) for x in (eye, target, up))
    z = eye - target
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return Gf.Matrix4d(*x, 0, *y, 0, *z, 0, *eye, 1)


def camera(stage, path, eye, target, focal=35.0, aperture=36.0):
    cam = UsdGeom.Camera.Define(stage, path)
    cam.CreateProjectionAttr("perspective")
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(aperture)
    cam.CreateVerticalApertureAttr(aperture)
    cam.CreateClippingRangeAttr(Gf.Vec2f(5, 10000))
    cam.CreateFStopAttr(0.0)
    UsdGeom.Xformable(cam).AddTransformOp().Set(look_at(eye, target))
    return cam


def render_settings(stage, camera_path, res=(128, 128), spp=32, seed=1):
    UsdGeom.Scope.Define(stage, "/Render")
    rs = UsdRender.Settings.Define(stage, "/Render/Settings")
    rs.CreateCameraRel().SetTargets([Sdf.Path(camera_path)])
    rs.CreateResolutionAttr(Gf.Vec2i(*res))
    rs.CreatePixelAspectRatioAttr(1.0)
    prim = rs.GetPrim()
    prim.AddAppliedSchema("CmltRenderSettingsAPI")
    uni = Sdf.VariabilityUniform
    prim.CreateAttribute("cmlt:integrator", Sdf.ValueTypeNames.Token, False, uni).Set("pt")
    prim.CreateAttribute("cmlt:spp", Sdf.ValueTypeNames.Int, False, uni).Set(spp)
    prim.CreateAttribute("cmlt:seed", Sdf.ValueTypeNames.Int, False, uni).Set(seed)
    return rs


def floor_and_walls(stage, root, looks):
    """A 600 x 600 cm floor slab with a back wall and a red left wall (closed
    10 cm slabs): the bounces give the shot its indirect light."""
    g = f"/{root}/Geometry"
    box(stage, f"{g}/Floor", (-300, -10, -300), (300, 0, 300), looks["floor"])
    box(stage, f"{g}/BackWall", (-300, 0, -310), (300, 300, -300), looks["white"])
    box(stage, f"{g}/LeftWall", (-310, 0, -300), (-300, 300, 300), looks["red"])


def props(stage, root, looks):
    """A cube, a tall block and a sphere standing on the floor."""
    g = f"/{root}/Geometry"
    cube = box(stage, f"{g}/Cube", (-40, 0, -40), (40, 80, 40), looks["white"])
    UsdGeom.Xformable(cube).AddTranslateOp().Set(Gf.Vec3d(-110, 0, 20))
    UsdGeom.Xformable(cube).AddRotateYOp().Set(25.0)
    tall = box(stage, f"{g}/Pillar", (-20, 0, -20), (20, 160, 20), looks["blue"])
    UsdGeom.Xformable(tall).AddTranslateOp().Set(Gf.Vec3d(40, 0, -120))
    sph = UsdGeom.Sphere.Define(stage, f"{g}/Ball")
    sph.CreateRadiusAttr(45.0)
    sph.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-45), Gf.Vec3f(45)]))
    UsdGeom.Xformable(sph).AddTranslateOp().Set(Gf.Vec3d(90, 45, 60))
    bind(sph, looks["white"])


def standard_looks(stage, root):
    return {
        "floor": material(stage, root, "Floor", (0.6, 0.6, 0.58)),
        "white": material(stage, root, "White", (0.75, 0.75, 0.75)),
        "red": material(stage, root, "Red", (0.63, 0.065, 0.05)),
        "blue": material(stage, root, "Blue", (0.1, 0.2, 0.6)),
    }


# --- the shot ------------------------------------------------------------------------------

def main():
    path = os.path.join(HERE, "shot.usda")
    root = "Static"
    stage = new_stage(path, root, "Static shot for cmlt flicker measurements: nothing is "
                      "animated, frames 1..24 at 24 fps, centimetres, Y up.\n"
                      "Generated by make_shot.py; see notes.md.")
    looks = standard_looks(stage, root)
    floor_and_walls(stage, root, looks)
    props(stage, root, looks)
    # one small, bright sphere light up and to the right: hard shadows
    key = UsdLux.SphereLight.Define(stage, f"/{root}/Lights/Key")
    key.CreateRadiusAttr(3.0)
    key.CreateIntensityAttr(15000.0)
    key.CreateColorAttr(Gf.Vec3f(1.0, 0.92, 0.8))
    key.CreateNormalizeAttr(False)
    UsdGeom.Xformable(key).AddTranslateOp().Set(Gf.Vec3d(180, 280, 160))
    camera(stage, f"/{root}/Camera", eye=(60, 260, 520), target=(-10, 40, -20))
    render_settings(stage, f"/{root}/Camera")
    stage.GetRootLayer().Save()


if __name__ == "__main__":
    main()
