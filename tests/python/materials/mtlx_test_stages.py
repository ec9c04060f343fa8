"""Builders shared by the MaterialX tests: small stages, MaterialX documents
and UsdShade networks of ND_* nodes, written by the tests themselves."""
from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
from pxr import Sdf, Usd, UsdGeom, UsdLux, UsdShade

import cmlt._core as core
from cmlt.color import get_config
from cmlt.shot.bridge import SceneBridge


def acescg(rgb):
    return np.asarray(get_config().to_rendering_space(np.asarray([rgb], np.float32),
                                                      "lin_rec709"), np.float64)[0]


def srgb_to_acescg(rgb):
    return np.asarray(get_config().to_rendering_space(np.asarray([rgb], np.float32),
                                                      "srgb_texture"), np.float64)[0]


def write_png(path, pixels):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(path)
    assert out.open(path, oiio.ImageSpec(w, h, c, oiio.UINT8)), out.geterror()
    assert out.write_image(np.ascontiguousarray(pixels.astype(np.uint8)))
    out.close()
    return path


def red_blue_png(path):
    """8x8, left half pure red, right half pure blue."""
    px = np.zeros((8, 8, 3), np.uint8)
    px[:, :4, 0] = 255
    px[:, 4:, 2] = 255
    return write_png(path, px)


def stage(path=None, camera=True):
    st = Usd.Stage.CreateNew(path) if path else Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    if camera:
        cam = UsdGeom.Camera.Define(st, "/Cam")
        cam.CreateFocalLengthAttr(180.0)          # 36 mm at 10 m: a 2 m object fills it
        cam.CreateHorizontalApertureAttr(36.0)
        cam.CreateVerticalApertureAttr(36.0)
        cam.AddTranslateOp().Set((0, 0, 10))
    return st


def quad(st, path, z=0.0, half=1.0):
    m = UsdGeom.Mesh.Define(st, path)
    h = half
    m.CreatePointsAttr([(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                         UsdGeom.Tokens.vertex).Set(
        [(0, 0), (1, 0), (1, 1), (0, 1)])
    return m


def sphere(st, path, radius=1.0):
    s = UsdGeom.Sphere.Define(st, path)
    s.CreateRadiusAttr(radius)
    return s


def bind_path(prim, target):
    UsdShade.MaterialBindingAPI.Apply(prim)
    prim.CreateRelationship("material:binding").SetTargets([Sdf.Path(target)])


def emitter_behind(st, rgb=(1.0, 0.0, 0.0), z=-1.0):
    """A big emissive UsdPreviewSurface quad behind the scene (no dome then)."""
    q = quad(st, "/Backdrop", z=z, half=3.0)
    mat = UsdShade.Material.Define(st, "/Looks/Backdrop")
    s = UsdShade.Shader.Define(st, "/Looks/Backdrop/S")
    s.CreateIdAttr("UsdPreviewSurface")
    s.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
    s.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set((0, 0, 0))
    mat.CreateSurfaceOutput().ConnectToSource(s.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).Bind(mat)
    return q


def distant_light(st, direction_deg_about_y, intensity=1.0):
    """A distant light whose light travels along -Z rotated by the angle about Y."""
    l = UsdLux.DistantLight.Define(st, "/Sun")
    l.CreateIntensityAttr(intensity)
    l.CreateAngleAttr(0.01)
    l.CreateNormalizeAttr(True)                 # irradiance = intensity
    l.AddRotateYOp().Set(direction_deg_about_y)
    return l


def render(fs, spp=16, depth=1, integrator="pt", seed=5, pixel_filter=None):
    s = core.RenderSettings()
    if pixel_filter:
        s.pixel_filter = pixel_filter
    s.width, s.height = fs.resolution
    s.spp, s.max_depth, s.seed, s.threads = spp, depth, seed, 2
    s.integrator = integrator
    return np.asarray(core.render(SceneBridge(core).update(fs), s).image, np.float64)


# ---------------------------------------------------------------- MaterialX documents

def mtlx_document(shader_xml, material="M", extra_xml="", colorspace="lin_rec709"):
    return f'''<?xml version="1.0"?>
<materialx version="1.39" colorspace="{colorspace}">
{extra_xml}
{shader_xml}
  <surfacematerial name="{material}" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR" />
  </surfacematerial>
</materialx>
'''


def surface_xml(category, inputs):
    """``inputs``: {name: (type, value string)} or {name: (type, None, nodename)}."""
    lines = [f'  <{category} name="SR" type="surfaceshader">']
    for name, spec in inputs.items():
        if len(spec) == 3:
            lines.append(f'    <input name="{name}" type="{spec[0]}" nodename="{spec[2]}" />')
        else:
            lines.append(f'    <input name="{name}" type="{spec[0]}" value="{spec[1]}" />')
    lines.append(f'  </{category}>')
    return "\n".join(lines)


def stage_with_mtlx(tmp_path, doc_text, geometry="quad", doc_name="look.mtlx",
                    via="scope", res=(24, 24), backdrop=None, light=None):
    """A stage whose geometry is bound to the document's material M through a
    reference usd-core cannot compose: ``via`` 'scope' (a Scope referencing
    </MaterialX>, bound to /Mtl/Materials/M) or 'material' (a Material prim
    referencing </MaterialX/Materials/M>)."""
    d = str(tmp_path)
    with open(os.path.join(d, doc_name), "w") as f:
        f.write(doc_text)
    path = os.path.join(d, "shot.usda")
    st = stage(path)
    geo = quad(st, "/Geo") if geometry == "quad" else sphere(st, "/Geo")
    if via == "scope":
        st.DefinePrim("/Mtl", "Scope").GetReferences().AddReference(
            "./" + doc_name, Sdf.Path("/MaterialX"))
        bind_path(geo.GetPrim(), "/Mtl/Materials/M")
    else:
        st.DefinePrim("/Look", "Material").GetReferences().AddReference(
            "./" + doc_name, Sdf.Path("/MaterialX/Materials/M"))
        bind_path(geo.GetPrim(), "/Look")
    if backdrop is not None:
        emitter_behind(st, backdrop)
    if light is not None:
        distant_light(st, light)
    st.GetRootLayer().Save()
    return path


# ---------------------------------------------------------------- UsdShade ND networks

_TYPES = {"float": Sdf.ValueTypeNames.Float, "color3": Sdf.ValueTypeNames.Color3f,
          "vector2": Sdf.ValueTypeNames.Float2, "vector3": Sdf.ValueTypeNames.Float3,
          "integer": Sdf.ValueTypeNames.Int, "string": Sdf.ValueTypeNames.String,
          "filename": Sdf.ValueTypeNames.Asset, "boolean": Sdf.ValueTypeNames.Bool,
          "color4": Sdf.ValueTypeNames.Color4f}


def nd_shader(st, path, node_id, inputs=None, out_type="color3"):
    """A UsdShade shader with a MaterialX node id; ``inputs`` {name: (type,
    value)} or {name: (type, shader, output)} connections."""
    s = UsdShade.Shader.Define(st, path)
    s.CreateIdAttr(node_id)
    s.CreateOutput("out", _TYPES.get(out_type, Sdf.ValueTypeNames.Token))
    for name, spec in (inputs or {}).items():
        inp = s.CreateInput(name, _TYPES[spec[0]])
        if len(spec) == 3:
            inp.ConnectToSource(spec[1].ConnectableAPI(), spec[2])
        else:
            inp.Set(spec[1])
    return s


def nd_material(st, path, surface_id, inputs):
    mat = UsdShade.Material.Define(st, path)
    surf = nd_shader(st, path + "/SR", surface_id, inputs, out_type="surfaceshader")
    mat.CreateSurfaceOutput("mtlx").ConnectToSource(surf.ConnectableAPI(), "out")
    return mat
