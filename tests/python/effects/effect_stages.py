"""Small stages, one per effect, written by the effects tests with usd-core.

``build(path, **options)`` writes a room — floor, back wall, a rect light above, a
camera looking at the floor from the front (metres, Y up, 48x36, frames 1..3) — and adds
what the options ask for. Each option switches on one effect (or one negative case), so
a test states exactly what its stage holds.
"""
from __future__ import annotations

from pathlib import Path
from typing import Dict, Optional

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender, UsdShade, UsdVol, Vt


def write_texture(path: Path, rgb=(0.8, 0.2, 0.2), size: int = 4) -> str:
    """A tiny RGB texture file (PNG, through OpenImageIO)."""
    import OpenImageIO as oiio
    img = np.ones((size, size, 3), dtype=np.float32) * np.asarray(rgb, np.float32)
    img[::2, ::2] = 1.0
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(size, size, 3, oiio.UINT8))
    out.write_image(img)
    out.close()
    return str(path)


def _quad(stage, path, pts, material=None, uvs=False):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreateSubdivisionSchemeAttr("none")
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    if uvs:
        pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                  UsdGeom.Tokens.vertex)
        pv.Set([Gf.Vec2f(0, 0), Gf.Vec2f(1, 0), Gf.Vec2f(1, 1), Gf.Vec2f(0, 1)])
    if material is not None:
        UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(material)
    return m


def _box(stage, path, lo, hi, material=None):
    """A closed axis-aligned box mesh (outward faces)."""
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreateSubdivisionSchemeAttr("none")
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    pts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
           (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4,
                                   2, 3, 7, 6, 0, 4, 7, 3, 1, 2, 6, 5])
    if material is not None:
        UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(material)
    return m


def material(stage, path, inputs: Optional[Dict[str, object]] = None,
             textures: Optional[Dict[str, str]] = None) -> UsdShade.Material:
    """A UsdPreviewSurface material; ``textures`` connects inputs to UsdUVTextures of the
    given files (read at the st primvar)."""
    mat = UsdShade.Material.Define(stage, path)
    sh = UsdShade.Shader.Define(stage, f"{path}/S")
    sh.CreateIdAttr("UsdPreviewSurface")
    types = {"diffuseColor": Sdf.ValueTypeNames.Color3f, "emissiveColor": Sdf.ValueTypeNames.Color3f,
             "specularColor": Sdf.ValueTypeNames.Color3f, "normal": Sdf.ValueTypeNames.Normal3f,
             "useSpecularWorkflow": Sdf.ValueTypeNames.Int}
    for name, value in (inputs or {}).items():
        t = types.get(name, Sdf.ValueTypeNames.Float)
        sh.CreateInput(name, t).Set(Gf.Vec3f(*value) if isinstance(value, tuple) else value)
    if textures:
        reader = UsdShade.Shader.Define(stage, f"{path}/St")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
        reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
        for k, (name, file) in enumerate(textures.items()):
            tex = UsdShade.Shader.Define(stage, f"{path}/Tex{k}")
            tex.CreateIdAttr("UsdUVTexture")
            tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(file))
            tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
                reader.ConnectableAPI(), "result")
            vector = name in ("diffuseColor", "emissiveColor", "specularColor", "normal")
            out = tex.CreateOutput("rgb" if vector else "r", Sdf.ValueTypeNames.Float3 if vector
                                   else Sdf.ValueTypeNames.Float)
            t = types.get(name, Sdf.ValueTypeNames.Float)
            sh.CreateInput(name, t).ConnectToSource(out)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def build(path, *, move=False, shutter=None, f_stop=0.0, sphere=None, enclose_sphere=False,
          roof=False, extra_material=None, floor_textures=None, floor_uvs=True,
          unused_textured_material=None, dome=None, emissive=False, point_light=False,
          distant_light=False, rect_light=True, volume=False, clearcoat=False,
          cutout=None) -> str:
    """Write the stage; returns its path. Options:

    move             a cube translating along X over frames 1..3
    shutter          (open, close) on the camera
    f_stop           the camera's fStop (focus distance 4 m)
    sphere           inputs of a UsdPreviewSurface on a sphere of radius 0.4 on the floor
    enclose_sphere   a closed opaque box around that sphere (no light reaches it)
    roof             an opaque plate above the sphere, shadowing it from the light
    floor_textures   {input: file} textured inputs of the floor material
    floor_uvs        the floor mesh has an st primvar
    unused_textured_material  a file: a textured material bound to nothing
    dome             None, "plain" or a texture file: a DomeLight
    emissive         an emissive quad on the back wall
    point_light / distant_light   a SphereLight treatAsPoint / a DistantLight of angle 0
    rect_light       the rect light above the floor
    volume           a UsdVol.Volume prim (not simulated)
    clearcoat        the back wall's material has clearcoat 1
    cutout           inputs (opacity, opacityThreshold) of a quad in front of the wall
    """
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    stage.SetTimeCodesPerSecond(24)
    UsdGeom.Xform.Define(stage, "/World")
    looks = "/World/Looks"
    white = material(stage, f"{looks}/White", {"diffuseColor": (0.7, 0.7, 0.7)})
    floor_mat = white
    if floor_textures:
        floor_mat = material(stage, f"{looks}/Floor", {"diffuseColor": (0.7, 0.7, 0.7)},
                             textures=floor_textures)
    _quad(stage, "/World/Floor", [(-3, 0, 3), (3, 0, 3), (3, 0, -3), (-3, 0, -3)], floor_mat,
          uvs=floor_uvs)
    wall_mat = white
    if clearcoat:
        wall_mat = material(stage, f"{looks}/Coated", {"diffuseColor": (0.5, 0.5, 0.7),
                                                      "clearcoat": 1.0})
    _quad(stage, "/World/Back", [(-3, 0, -3), (3, 0, -3), (3, 4, -3), (-3, 4, -3)], wall_mat)
    if rect_light:
        light = UsdLux.RectLight.Define(stage, "/World/Light")
        light.CreateIntensityAttr(20.0)
        light.CreateWidthAttr(1.0)
        light.CreateHeightAttr(1.0)
        x = UsdGeom.Xformable(light)
        x.AddTranslateOp().Set(Gf.Vec3d(0, 3.5, 0))
        x.AddRotateXYZOp().Set(Gf.Vec3f(-90, 0, 0))
    if point_light:
        pl = UsdLux.SphereLight.Define(stage, "/World/Point")
        pl.CreateIntensityAttr(50.0)
        pl.CreateTreatAsPointAttr(True)
        UsdGeom.Xformable(pl).AddTranslateOp().Set(Gf.Vec3d(1, 3, 1))
    if distant_light:
        dl = UsdLux.DistantLight.Define(stage, "/World/Sun")
        dl.CreateAngleAttr(0.0)
        dl.CreateIntensityAttr(2.0)
        UsdGeom.Xformable(dl).AddRotateXYZOp().Set(Gf.Vec3f(-60, 20, 0))
    if dome is not None:
        d = UsdLux.DomeLight.Define(stage, "/World/Dome")
        d.CreateIntensityAttr(0.5)
        if dome != "plain":
            d.CreateTextureFileAttr(Sdf.AssetPath(dome))
    if move:
        cube = _box(stage, "/World/Cube", (-0.3, 0, -0.3), (0.3, 0.6, 0.3), white)
        op = UsdGeom.Xformable(cube).AddTranslateOp()
        for t, x in ((1, -1.0), (2, 0.0), (3, 1.0)):
            op.Set(Gf.Vec3d(x, 0, 0), Usd.TimeCode(t))
    if sphere is not None:
        smat = material(stage, f"{looks}/Sphere", sphere)
        s = UsdGeom.Sphere.Define(stage, "/World/Ball")
        s.CreateRadiusAttr(0.4)
        UsdGeom.Xformable(s).AddTranslateOp().Set(Gf.Vec3d(0.5, 0.41, 0.5))
        UsdShade.MaterialBindingAPI.Apply(s.GetPrim()).Bind(smat)
        if enclose_sphere:
            _box(stage, "/World/Crate", (-0.05, 0.0, -0.05), (1.05, 1.0, 1.05), white)
        if roof:
            _quad(stage, "/World/Roof", [(-1.5, 1.2, 2.0), (2.5, 1.2, 2.0), (2.5, 1.2, -1.5),
                                         (-1.5, 1.2, -1.5)], white)
            _quad(stage, "/World/RoofBelow", [(-1.5, 1.19, -1.5), (2.5, 1.19, -1.5),
                                              (2.5, 1.19, 2.0), (-1.5, 1.19, 2.0)], white)
    if emissive:
        emat = material(stage, f"{looks}/Glow", {"diffuseColor": (0, 0, 0),
                                                 "emissiveColor": (4.0, 4.0, 4.0)})
        _quad(stage, "/World/Panel", [(-1, 1, -2.99), (1, 1, -2.99), (1, 2, -2.99),
                                      (-1, 2, -2.99)], emat)
    if cutout is not None:
        cmat = material(stage, f"{looks}/Leaf", dict({"diffuseColor": (0.2, 0.6, 0.2)}, **cutout))
        _quad(stage, "/World/Leaf", [(-1, 0.2, 1), (0, 0.2, 1), (0, 1.2, 1), (-1, 1.2, 1)], cmat)
    if extra_material is not None:
        material(stage, f"{looks}/Extra", extra_material)
    if unused_textured_material is not None:
        material(stage, f"{looks}/Unused", {}, textures={"diffuseColor": unused_textured_material})
    if volume:
        UsdVol.Volume.Define(stage, "/World/Smoke")
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(24.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(27.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 100))
    if f_stop:
        cam.CreateFStopAttr(float(f_stop))
        cam.CreateFocusDistanceAttr(4.0)
    if shutter is not None:
        cam.CreateShutterOpenAttr(float(shutter[0]))
        cam.CreateShutterCloseAttr(float(shutter[1]))
    cx = UsdGeom.Xformable(cam)
    cx.AddTranslateOp().Set(Gf.Vec3d(0, 2.0, 6.0))
    cx.AddRotateXYZOp().Set(Gf.Vec3f(-15, 0, 0))
    rs = UsdRender.Settings.Define(stage, "/Render/Settings")
    rs.CreateResolutionAttr(Gf.Vec2i(48, 36))
    rs.CreateCameraRel().SetTargets([cam.GetPath()])
    stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().Save()
    return str(path)


def inspect(path, *extra):
    """``cmlt inspect PATH --json`` as a dict (through cmlt.cli.main, no subprocess)."""
    import contextlib
    import io
    import json

    from cmlt.cli import main
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["inspect", str(path), "--json", *extra])
    assert code == 0, buf.getvalue()
    return json.loads(buf.getvalue())
