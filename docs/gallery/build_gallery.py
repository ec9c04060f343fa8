"""``make gallery``: build the gallery's assets, render them with ``cmlt render``
and write ``docs/gallery/*.png`` and ``docs/gallery/README.md`` (each image with
the command that made it).

Nothing is downloaded. The assets are written here from code, in the forms
production assets come in: a chess set in centimetres on a Z-up stage with
OpenPBR materials in a referenced ``.mtlx`` document and a ``look`` variant set;
a ball of Catmull-Clark subdivision surfaces on a floor delivered as a ``.usdz``
package (its texture inside), a torus coloured through ``UsdPrimvarReader_float3``,
a ``lighting`` variant that switches the lights off; and a portrait whose texture
is a photograph shipped in a PyPI package (matplotlib's sample data, Grace Hopper).

    python docs/gallery/build_gallery.py [--assets-only] [--spp N] [--scale S]

``--assets-only`` writes the stages into ``renders/gallery/assets`` and prints the
commands without rendering. Renders are small (a few minutes in all on two
cores); ``--scale`` multiplies their resolution.
"""
from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdUtils

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
ASSETS = os.path.join("renders", "gallery", "assets")
OUT = os.path.join("renders", "gallery")

sys.path.insert(0, HERE)
from gallery_geometry import (bind, box, camera, lathe, look_at,  # noqa: E402
                              preview_surface, sky_texture, torus, write_image)


# ---------------------------------------------------------------- chess (Z-up, cm)

MTLX_LOOKS = {
    # name: open_pbr_surface inputs
    "ivory": {"base_color": "0.85, 0.82, 0.74", "specular_roughness": "0.3",
              "coat_weight": "0.6", "coat_roughness": "0.05", "coat_ior": "1.5"},
    "ebony": {"base_color": "0.03, 0.03, 0.035", "specular_roughness": "0.35",
              "coat_weight": "1", "coat_roughness": "0.03", "coat_ior": "1.5"},
    "maple": {"base_color": "0.72, 0.50, 0.28", "specular_roughness": "0.45"},
    "walnut": {"base_color": "0.25, 0.13, 0.06", "specular_roughness": "0.4",
               "coat_weight": "0.5", "coat_roughness": "0.1", "coat_ior": "1.5"},
    "brass": {"base_color": "0.95, 0.75, 0.4", "base_metalness": "1",
              "specular_roughness": "0.25"},
    "board_light": {"base_color": "0.8, 0.78, 0.72", "specular_roughness": "0.2"},
    "board_dark": {"base_color": "0.12, 0.2, 0.14", "specular_roughness": "0.2"},
}


def mtlx_document():
    parts = ['<?xml version="1.0"?>', '<materialx version="1.39" colorspace="lin_rec709">']
    for name, inputs in MTLX_LOOKS.items():
        parts.append(f'  <open_pbr_surface name="SR_{name}" type="surfaceshader">')
        for k, v in inputs.items():
            t = "color3" if "," in v else "float"
            parts.append(f'    <input name="{k}" type="{t}" value="{v}" />')
        parts.append("  </open_pbr_surface>")
        parts.append(f'  <surfacematerial name="{name}" type="material">')
        parts.append(f'    <input name="surfaceshader" type="surfaceshader" '
                     f'nodename="SR_{name}" />')
        parts.append("  </surfacematerial>")
    parts.append("</materialx>")
    return "\n".join(parts) + "\n"


PAWN = [(1.5, 0), (1.5, 0.4), (1.1, 0.7), (0.6, 1.1), (0.5, 2.2), (0.9, 2.5), (0.45, 2.7),
        (0.85, 3.2), (0.9, 3.7), (0.6, 4.2), (0.25, 4.45)]
ROOK = [(1.8, 0), (1.8, 0.5), (1.3, 0.9), (0.95, 1.4), (0.85, 3.6), (1.25, 3.9), (1.25, 4.9),
        (0.95, 4.9), (0.9, 4.6)]
KING = [(1.9, 0), (1.9, 0.5), (1.4, 0.9), (0.85, 1.5), (0.65, 4.6), (1.15, 4.9), (0.75, 5.2),
        (1.05, 6.0), (0.55, 6.5), (0.3, 6.9), (0.3, 7.6), (0.12, 7.9)]


def build_chess(d):
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "looks.mtlx"), "w") as f:
        f.write(mtlx_document())
    sky_texture(os.path.join(d, "sky.exr"), sun_az=-60.0, sun_el=30.0)
    path = os.path.join(d, "chess.usda")
    st = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(st, 0.01)                  # centimetres
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(1)
    root = UsdGeom.Xform.Define(st, "/Chess").GetPrim()
    st.SetDefaultPrim(root)
    looks = {}
    for name in MTLX_LOOKS:
        m = st.DefinePrim(f"/Chess/Looks/{name}", "Material")
        m.GetReferences().AddReference("./looks.mtlx", Sdf.Path(f"/MaterialX/Materials/{name}"))
        looks[name] = m
    # board: 8x8 squares of 5 cm, light and dark meshes, 1 cm thick frame
    for shade in ("light", "dark"):
        pts, counts, idx = [], [], []
        for i in range(8):
            for j in range(8):
                if ((i + j) % 2 == 0) != (shade == "dark"):
                    continue
                x0, y0 = -20 + 5 * i, -20 + 5 * j
                b = len(pts)
                pts += [(x0, y0, 0), (x0 + 5, y0, 0), (x0 + 5, y0 + 5, 0), (x0, y0 + 5, 0)]
                counts.append(4)
                idx += [b, b + 1, b + 2, b + 3]
        m = UsdGeom.Mesh.Define(st, f"/Chess/Board/{shade}")
        m.CreatePointsAttr(pts)
        m.CreateFaceVertexCountsAttr(counts)
        m.CreateFaceVertexIndicesAttr(idx)
        m.CreateSubdivisionSchemeAttr("none")
        bind(m.GetPrim(), UsdShade.Material(looks[f"board_{shade}"]))
    frame = box(st, "/Chess/Board/frame", (-22, -22, -2), (22, 22, -0.01))
    table = box(st, "/Chess/Table", (-200, -200, -4), (200, 200, -2))
    # pieces: a row of pawns, rooks at the corners, kings, for both sides
    for side, row_pawn, row_back in (("White", 1, 0), ("Black", 6, 7)):
        grp = UsdGeom.Xform.Define(st, f"/Chess/{side}")
        for i in range(8):
            p = lathe(st, f"/Chess/{side}/pawn{i}", PAWN)
            p.AddTranslateOp().Set(Gf.Vec3d(-17.5 + 5 * i, -17.5 + 5 * row_pawn, 0))
        for i in (0, 7):
            r = lathe(st, f"/Chess/{side}/rook{i}", ROOK)
            r.AddTranslateOp().Set(Gf.Vec3d(-17.5 + 5 * i, -17.5 + 5 * row_back, 0))
        k = lathe(st, f"/Chess/{side}/king", KING)
        k.AddTranslateOp().Set(Gf.Vec3d(2.5, -17.5 + 5 * row_back, 0))
    # the look variant set: which materials the sides, the frame and table get
    vset = root.GetVariantSets().AddVariantSet("look")
    for variant, (white, black, trim) in (("classic", ("ivory", "ebony", "walnut")),
                                          ("wood", ("maple", "walnut", "brass"))):
        vset.AddVariant(variant)
        vset.SetVariantSelection(variant)
        with vset.GetVariantEditContext():
            for side, look in (("White", white), ("Black", black)):
                bind(st.OverridePrim(f"/Chess/{side}"), UsdShade.Material(looks[look]))
            bind(st.OverridePrim("/Chess/Board/frame"), UsdShade.Material(looks[trim]))
    vset.SetVariantSelection("classic")
    _, _ = preview_surface(st, "/Chess/Looks/TableTop", diffuseColor=(0.35, 0.33, 0.3),
                           roughness=0.8)
    bind(table.GetPrim(), UsdShade.Material.Get(st, "/Chess/Looks/TableTop"))
    # lights: a DomeLight_1 (poleAxis scene: the stage's +Z) and a sun
    dome = UsdLux.DomeLight_1.Define(st, "/Chess/Lights/Sky")
    dome.CreateTextureFileAttr("./sky.exr")
    dome.CreateIntensityAttr(0.6)
    sun = UsdLux.DistantLight.Define(st, "/Chess/Lights/Sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateAngleAttr(2.0)
    sun.CreateNormalizeAttr(True)
    sun.AddRotateZOp().Set(-35.0)
    sun.AddRotateXOp().Set(50.0)
    camera(st, "/Chess/Camera", (6, -44, 27), (0, -1, 1), (0, 0, 1), focal=35.0)
    st.GetRootLayer().Save()
    return path


# ---------------------------------------------------------------- ball (Y-up, m, usdz)

def build_floor_usdz(d):
    src = os.path.join(d, "floor_src")
    os.makedirs(os.path.join(src, "tex"), exist_ok=True)
    n = 256
    y, x = np.mgrid[0:n, 0:n]
    check = ((x // 32 + y // 32) % 2).astype(np.float32)
    grain = 0.06 * np.sin(x * 0.35 + 3 * np.sin(y * 0.05))
    rgb = np.stack([0.55 + 0.25 * check + grain, 0.42 + 0.2 * check + grain,
                    0.3 + 0.12 * check + grain], -1)
    write_image(os.path.join(src, "tex", "floor.png"),
                (np.clip(rgb, 0, 1) * 255).astype(np.uint8), oiio.UINT8)
    st = Usd.Stage.CreateNew(os.path.join(src, "floor.usda"))
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    root = UsdGeom.Xform.Define(st, "/Floor").GetPrim()
    st.SetDefaultPrim(root)
    m = UsdGeom.Mesh.Define(st, "/Floor/Plane")
    m.CreatePointsAttr([(-4, 0, -4), (4, 0, -4), (4, 0, 4), (-4, 0, 4)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    m.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                         UsdGeom.Tokens.vertex).Set(
        [(0, 0), (4, 0), (4, 4), (0, 4)])
    mat, surf = preview_surface(st, "/Floor/Looks/Wood", roughness=0.55)
    tex = UsdShade.Shader.Define(st, "/Floor/Looks/Wood/Tex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./tex/floor.png")
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("repeat")
    tex.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("repeat")
    rd = UsdShade.Shader.Define(st, "/Floor/Looks/Wood/St")
    rd.CreateIdAttr("UsdPrimvarReader_float2")
    rd.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(rd.ConnectableAPI(),
                                                                      "result")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        tex.ConnectableAPI(), "rgb")
    bind(m.GetPrim(), mat)
    st.GetRootLayer().Save()
    pkg = os.path.join(d, "floor.usdz")
    if os.path.exists(pkg):
        os.remove(pkg)
    if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(os.path.join(src, "floor.usda")), pkg):
        raise RuntimeError(f"{pkg}: could not write the package")
    shutil.rmtree(src)                   # the package is all the stage has
    return pkg


def build_ball(d):
    os.makedirs(d, exist_ok=True)
    build_floor_usdz(d)
    sky_texture(os.path.join(d, "sky.exr"), sun_az=120.0, sun_el=25.0)
    path = os.path.join(d, "ball.usda")
    st = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(1)
    root = UsdGeom.Xform.Define(st, "/Ball").GetPrim()
    st.SetDefaultPrim(root)
    st.DefinePrim("/Ball/Floor").GetReferences().AddReference("./floor.usdz")
    # a pedestal and a cube cage subdivided into a ball (Catmull-Clark, level 3)
    ped = lathe(st, "/Ball/Pedestal", [(0.42, 0), (0.42, 0.05), (0.3, 0.1), (0.22, 0.35),
                                       (0.3, 0.42), (0.36, 0.45)], z_up=False)
    ball = box(st, "/Ball/Sphere", (-0.4, 0.45, -0.4), (0.4, 1.25, 0.4), subdiv="catmullClark")
    ball.GetPrim().CreateAttribute("cmlt:subdivisionLevel", Sdf.ValueTypeNames.Int).Set(3)
    copper, _ = preview_surface(st, "/Ball/Looks/Copper", diffuseColor=(0.95, 0.62, 0.45),
                                metallic=1.0, roughness=0.28)
    stone, _ = preview_surface(st, "/Ball/Looks/Stone", diffuseColor=(0.55, 0.55, 0.52),
                               roughness=0.7, clearcoat=0.3, clearcoatRoughness=0.2)
    bind(ball.GetPrim(), copper)
    bind(ped.GetPrim(), stone)
    # a torus coloured by its displayColor through UsdPrimvarReader_float3
    tor = torus(st, "/Ball/Torus")
    tor.AddTranslateOp().Set(Gf.Vec3d(1.15, 0.16, 0.35))
    mat, surf = preview_surface(st, "/Ball/Looks/ByColor", roughness=0.35, clearcoat=1.0,
                                clearcoatRoughness=0.05)
    rd = UsdShade.Shader.Define(st, "/Ball/Looks/ByColor/Color")
    rd.CreateIdAttr("UsdPrimvarReader_float3")
    rd.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayColor")
    rd.CreateOutput("result", Sdf.ValueTypeNames.Float3)
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        rd.ConnectableAPI(), "result")
    bind(tor.GetPrim(), mat)
    # lighting variant: a studio rect light and the sky, or nothing (--default-light)
    vset = root.GetVariantSets().AddVariantSet("lighting")
    vset.AddVariant("studio")
    vset.AddVariant("none")
    vset.SetVariantSelection("studio")
    with vset.GetVariantEditContext():
        dome = UsdLux.DomeLight_1.Define(st, "/Ball/Lights/Sky")
        dome.CreateTextureFileAttr("./sky.exr")
        dome.CreateIntensityAttr(0.5)
        key = UsdLux.RectLight.Define(st, "/Ball/Lights/Key")
        key.CreateWidthAttr(1.5)
        key.CreateHeightAttr(1.5)
        key.CreateIntensityAttr(6.0)
        key.AddTransformOp().Set(look_at((-2.2, 2.8, 2.0), (0, 0.6, 0), (0, 1, 0)))
    vset.SetVariantSelection("studio")
    camera(st, "/Ball/Camera", (0.6, 1.45, 4.2), (0.35, 0.55, 0), (0, 1, 0), focal=40.0,
           clip=(0.05, 1000))
    st.GetRootLayer().Save()
    return path


# ---------------------------------------------------------------- portrait (PyPI image)

def build_portrait(d):
    import matplotlib.cbook as cbook
    os.makedirs(d, exist_ok=True)
    photo = os.path.join(d, "grace_hopper.jpg")
    with cbook.get_sample_data("grace_hopper.jpg") as src, open(photo, "wb") as dst:
        dst.write(src.read())
    spec = oiio.ImageInput.open(photo).spec()
    aspect = spec.height / spec.width
    path = os.path.join(d, "portrait.usda")
    st = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(1)
    root = UsdGeom.Xform.Define(st, "/Portrait").GetPrim()
    st.SetDefaultPrim(root)
    w, h = 0.6, 0.6 * aspect
    canvas = UsdGeom.Mesh.Define(st, "/Portrait/Canvas")
    canvas.CreatePointsAttr([(-w / 2, 1.5 - h / 2, 0.01), (w / 2, 1.5 - h / 2, 0.01),
                             (w / 2, 1.5 + h / 2, 0.01), (-w / 2, 1.5 + h / 2, 0.01)])
    canvas.CreateFaceVertexCountsAttr([4])
    canvas.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    canvas.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(canvas).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                              UsdGeom.Tokens.vertex).Set(
        [(0, 0), (1, 0), (1, 1), (0, 1)])
    mat, surf = preview_surface(st, "/Portrait/Looks/Photo", roughness=0.6)
    tex = UsdShade.Shader.Define(st, "/Portrait/Looks/Photo/Tex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./grace_hopper.jpg")
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    rd = UsdShade.Shader.Define(st, "/Portrait/Looks/Photo/St")
    rd.CreateIdAttr("UsdPrimvarReader_float2")
    rd.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(rd.ConnectableAPI(),
                                                                      "result")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        tex.ConnectableAPI(), "rgb")
    bind(canvas.GetPrim(), mat)
    gold, _ = preview_surface(st, "/Portrait/Looks/Gilt", diffuseColor=(0.9, 0.7, 0.35),
                              metallic=1.0, roughness=0.3)
    t = 0.06
    for name, lo, hi in (("top", (-w / 2 - t, 1.5 + h / 2, -0.02), (w / 2 + t, 1.5 + h / 2 + t, 0.04)),
                         ("bottom", (-w / 2 - t, 1.5 - h / 2 - t, -0.02), (w / 2 + t, 1.5 - h / 2, 0.04)),
                         ("left", (-w / 2 - t, 1.5 - h / 2, -0.02), (-w / 2, 1.5 + h / 2, 0.04)),
                         ("right", (w / 2, 1.5 - h / 2, -0.02), (w / 2 + t, 1.5 + h / 2, 0.04))):
        b = box(st, f"/Portrait/Frame/{name}", lo, hi)
        bind(b.GetPrim(), gold)
    wall = box(st, "/Portrait/Wall", (-3, 0, -0.3), (3, 3, -0.02))
    floor = box(st, "/Portrait/Floor", (-3, -0.1, -0.3), (3, 0, 3))
    paint, _ = preview_surface(st, "/Portrait/Looks/Paint", diffuseColor=(0.32, 0.42, 0.4),
                               roughness=0.9)
    oak, _ = preview_surface(st, "/Portrait/Looks/Oak", diffuseColor=(0.45, 0.3, 0.18),
                             roughness=0.5)
    bind(wall.GetPrim(), paint)
    bind(floor.GetPrim(), oak)
    lamp = UsdLux.RectLight.Define(st, "/Portrait/Lamp")
    lamp.CreateWidthAttr(0.8)
    lamp.CreateHeightAttr(0.3)
    lamp.CreateIntensityAttr(30.0)
    lamp.AddTransformOp().Set(look_at((0.5, 2.6, 1.6), (0, 1.5, 0), (0, 1, 0)))
    fill = UsdLux.DomeLight.Define(st, "/Portrait/Fill")
    fill.CreateIntensityAttr(0.3)
    camera(st, "/Portrait/Camera", (-0.45, 1.42, 1.35), (0, 1.48, 0), (0, 1, 0), focal=40.0,
           clip=(0.05, 100))
    st.GetRootLayer().Save()
    return path


# ---------------------------------------------------------------- renders

def renders(assets, spp, scale):
    chess = os.path.join(assets, "chess", "chess.usda")
    ball = os.path.join(assets, "ball", "ball.usda")
    portrait = os.path.join(assets, "portrait", "portrait.usda")
    big = f"{int(320 * scale)}x{int(240 * scale)}"
    small = f"{int(160 * scale)}x{int(120 * scale)}"
    common = ["--integrator", "pt", "--spp", str(spp), "--preview", "--quiet"]
    return [
        ("chess_classic", "Chess set, `look` = classic: Z-up stage in centimetres, OpenPBR "
         "materials from a referenced `.mtlx` document, Catmull-Clark pieces, DomeLight_1 "
         "sky (pole on the stage's +Z) and a sun",
         [chess, "--res", big, *common]),
        ("chess_wood", "The same shot with `--variant look=wood` (maple and walnut pieces, "
         "a brass frame)", [chess, "--res", big, "--variant", "look=wood", *common]),
        ("ball", "Subdivided copper ball (cube cage, `cmlt:subdivisionLevel` 3), torus "
         "coloured by displayColor through `UsdPrimvarReader_float3`, floor delivered as "
         "a `.usdz` with its texture inside", [ball, "--res", big, *common]),
        ("portrait", "Grace Hopper's portrait (matplotlib's sample image) as a "
         "`UsdUVTexture` in a gilt frame under a rect light",
         [portrait, "--res", big, *common]),
        ("ball_unlit_dome", "`--variant lighting=none` (no lights): the default white dome, "
         "a furnace", [ball, "--res", small, "--variant", "lighting=none", *common]),
        ("ball_unlit_headlight", "`--variant lighting=none --default-light headlight`",
         [ball, "--res", small, "--variant", "lighting=none", "--default-light", "headlight",
          *common]),
        ("ball_unlit_dome_key", "`--variant lighting=none --default-light dome-key`",
         [ball, "--res", small, "--variant", "lighting=none", "--default-light", "dome-key",
          *common]),
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--assets-only", action="store_true")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--threads", type=int, default=0)
    args = ap.parse_args(argv)
    os.chdir(ROOT)
    from cmlt.usd.diagnostics import capture_usd_diagnostics
    with capture_usd_diagnostics():       # USD's complaints about the .mtlx references
        build_chess(os.path.join(ASSETS, "chess"))
        build_ball(os.path.join(ASSETS, "ball"))
        build_portrait(os.path.join(ASSETS, "portrait"))
    cmlt = shutil.which("cmlt", path=os.path.dirname(sys.executable)) or "cmlt"
    lines = ["# Gallery", "",
             "Rendered by `make gallery` (`docs/gallery/build_gallery.py`) from assets the "
             "script writes into `renders/gallery/assets/` — nothing is downloaded; the "
             "portrait's photograph ships with matplotlib. Each image is the preview "
             "(`sRGB - Display`, the config's default view) of the EXR made by the command "
             "under it, run from the repository root after "
             "`python docs/gallery/build_gallery.py --assets-only`.", ""]
    total = 0.0
    for name, caption, cmd in renders(ASSETS, args.spp, args.scale):
        out = os.path.join(OUT, f"{name}.exr")
        full = ["cmlt", "render", *cmd, "--out", out]
        lines += [f"## {name}", "", caption, "", f"![{name}]({name}.png)", "", "```sh",
                  shlex.join(full), "```", ""]
        if args.assets_only:
            print(shlex.join(full))
            continue
        t0 = time.perf_counter()
        run = [cmlt, *full[1:]] + (["--threads", str(args.threads)] if args.threads else [])
        proc = subprocess.run(run, capture_output=True, text=True)
        if proc.returncode != 0:
            sys.stderr.write(proc.stderr)
            return proc.returncode
        dt = time.perf_counter() - t0
        total += dt
        shutil.copyfile(os.path.join(OUT, f"{name}.png"), os.path.join(HERE, f"{name}.png"))
        print(f"gallery: {name}: {dt:.1f} s")
    if not args.assets_only:
        with open(os.path.join(HERE, "README.md"), "w") as f:
            f.write("\n".join(lines))
        print(f"gallery: {total:.0f} s in all -> docs/gallery/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
