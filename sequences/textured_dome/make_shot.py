"""Writes shot.usda (textured objects under an HDR dome, moving camera) next to this file.

Run ``make_assets.py`` first (it writes textures/), then
``.venv/bin/python sequences/textured_dome/make_shot.py``. Helpers come from
``sequences/static_flicker/make_shot.py``. The shot:

* ``Lights/Sky``: a DomeLight with ``inputs:texture:file = textures/sky.exr`` (lat-long
  HDR with a sun blob; default orientation: +Y pole);
* ``Geometry/Ground``: a 1200 x 1200 cm quad, checker texture (UsdUVTexture, st 0..12, repeat);
* ``Geometry/Ball``: a UV-sphere mesh (r = 40 cm) with the stripes texture;
* ``Geometry/Chrome``: a smaller smooth metallic sphere (reflects the sky);
* ``Camera``: orbits the objects over frames 1..24 (one sample per frame).
"""
import importlib.util
import math
import os

import numpy as np
from pxr import Gf, Sdf, UsdGeom, UsdLux, UsdShade, Vt

HERE = os.path.dirname(os.path.abspath(__file__))
_spec = importlib.util.spec_from_file_location(
    "static_flicker_make_shot", os.path.join(HERE, "..", "static_flicker", "make_shot.py"))
kit = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(kit)

FRAMES = range(kit.FIRST, kit.LAST + 1)


def textured(stage, root, name, file, roughness=0.6):
    """UsdPreviewSurface whose diffuseColor comes from a UsdUVTexture read at st."""
    base = f"/{root}/Looks/{name}"
    mat = UsdShade.Material.Define(stage, base)
    sh = UsdShade.Shader.Define(stage, f"{base}/Surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(roughness)
    sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    reader = UsdShade.Shader.Define(stage, f"{base}/St")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
    tex = UsdShade.Shader.Define(stage, f"{base}/Tex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(file))
    tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("repeat")
    tex.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("repeat")
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI().CreateOutput("result", Sdf.ValueTypeNames.Float2))
    rgb = tex.ConnectableAPI().CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(rgb)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def chrome(stage, root):
    base = f"/{root}/Looks/Chrome"
    mat = UsdShade.Material.Define(stage, base)
    sh = UsdShade.Shader.Define(stage, f"{base}/Surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.9, 0.9, 0.92))
    sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(1.0)
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.08)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def mesh(stage, path, pts, faces, st, normals=None):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts]))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([len(f) for f in faces]))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for f in faces for i in f]))
    m.CreateSubdivisionSchemeAttr("none")
    if normals is not None:
        m.CreateNormalsAttr(Vt.Vec3fArray([Gf.Vec3f(*n) for n in normals]))
        m.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                              UsdGeom.Tokens.vertex)
    pv.Set(Vt.Vec2fArray([Gf.Vec2f(*t) for t in st]))
    lo, hi = np.min(pts, 0), np.max(pts, 0)
    m.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo), Gf.Vec3f(*hi)]))
    return m


def uv_sphere(r, n_theta=32, n_phi=64):
    pts, nrm, st = [], [], []
    for i in range(n_theta + 1):
        th = math.pi * i / n_theta
        for j in range(n_phi + 1):
            ph = 2 * math.pi * j / n_phi
            d = (math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph))
            pts.append(tuple(r * c for c in d))
            nrm.append(d)
            st.append((2.0 * j / n_phi, 1.0 - i / n_theta))
    faces = []
    for i in range(n_theta):
        for j in range(n_phi):
            a, b = i * (n_phi + 1) + j, (i + 1) * (n_phi + 1) + j
            faces.append((a, b, b + 1, a + 1))   # counter-clockwise seen from outside
    return np.array(pts), faces, st, nrm


def main():
    path = os.path.join(HERE, "shot.usda")
    root = "TexturedDome"
    stage = kit.new_stage(path, root, "Textured objects under an HDR dome (textures/sky.exr); "
                          "the camera orbits. Frames 1..24 at 24 fps, centimetres, Y up.\n"
                          "Generated by make_shot.py (after make_assets.py); see notes.md.")
    g = f"/{root}/Geometry"
    ground = mesh(stage, f"{g}/Ground",
                  np.array([(-600, 0, 600), (600, 0, 600), (600, 0, -600), (-600, 0, -600)], float),
                  [(0, 1, 2, 3)], [(0, 0), (12, 0), (12, 12), (0, 12)])
    kit.bind(ground, textured(stage, root, "Checker", "./textures/checker.png", roughness=0.8))
    pts, faces, st, nrm = uv_sphere(40.0)
    ball = mesh(stage, f"{g}/Ball", pts, faces, st, nrm)
    UsdGeom.Xformable(ball).AddTranslateOp().Set(Gf.Vec3d(-35, 40, 0))
    kit.bind(ball, textured(stage, root, "Stripes", "./textures/stripes.png", roughness=0.5))
    ch = UsdGeom.Sphere.Define(stage, f"{g}/Chrome")
    ch.CreateRadiusAttr(25.0)
    ch.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-25), Gf.Vec3f(25)]))
    UsdGeom.Xformable(ch).AddTranslateOp().Set(Gf.Vec3d(50, 25, 30))
    kit.bind(ch, chrome(stage, root))

    dome = UsdLux.DomeLight.Define(stage, f"/{root}/Lights/Sky")
    dome.CreateTextureFileAttr(Sdf.AssetPath("./textures/sky.exr"))
    dome.CreateTextureFormatAttr("latlong")
    dome.CreateIntensityAttr(1.0)

    cam = kit.camera(stage, f"/{root}/Camera", eye=(0, 120, 320), target=(0, 30, 0), focal=30.0)
    op = UsdGeom.Xformable(cam).GetOrderedXformOps()[0]
    for f in FRAMES:
        a = math.radians(-40 + 80 * (f - kit.FIRST) / (kit.LAST - kit.FIRST))
        eye = (320 * math.sin(a), 110 + 20 * math.cos(2 * a), 320 * math.cos(a))
        op.Set(kit.look_at(eye, (0, 30, 0)), f)
    kit.render_settings(stage, f"/{root}/Camera", res=(128, 128), spp=64)
    stage.GetRootLayer().Save()


if __name__ == "__main__":
    main()
