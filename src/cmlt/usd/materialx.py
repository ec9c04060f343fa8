"""MaterialX surfaces -> :class:`cmlt.scene.Material` (cmlt's UsdPreviewSurface model).

Two ways a stage carries MaterialX:

* UsdShade networks whose shader ids are MaterialX node definitions
  (``ND_open_pbr_surface_surfaceshader``, ``ND_image_color3`` ...), reached
  through the material's ``outputs:mtlx:surface`` (what usdMtlx and the DCC
  exporters write);
* ``.mtlx`` documents referenced from the stage
  (``references = @looks.mtlx@</MaterialX/Materials/Wood>``). usd-core ships
  no MaterialX file-format plugin, so such a reference does not compose
  ("Cannot determine file format"); the document is read here with the
  ``materialx`` package instead, through USD's asset resolver (it may sit in
  a ``.usdz``), and the binding's target path is mapped to the document's
  material (``/MaterialX/Materials/<name>``, usdMtlx's layout).

Both become one small graph (:class:`Node`), walked from the surface shader.

Mapping (``open_pbr_surface`` / ``standard_surface`` -> UsdPreviewSurface):

======================================  =====================================
base_color x base_weight (base)          diffuseColor (a texture: its scale)
base_metalness (metalness)               metallic
specular_roughness                       roughness
specular_ior (specular_IOR)              ior
specular_weight x specular_color         folded into the specular workflow
                                         (F0 = lerp(F0(ior) w c, base, metal),
                                         diffuse = (1 - metal) base) when base
                                         and metalness are constants, else
                                         ignored with a warning
coat_weight (coat), coat_roughness       clearcoat, clearcoatRoughness (white,
                                         IOR 1.5: coat_color/coat_ior warn)
transmission_weight (transmission)       opacity = 1 - transmission (the
                                         dielectric lobe, ior = specular_ior)
emission_luminance x emission_color      emissiveColor
(emission x emission_color)
geometry_opacity (opacity)               presence: with constant base and
                                         metalness exactly (specular workflow,
                                         ior 1 pass-through), else a cut-out at
                                         0.5 (opacityThreshold), with a warning
geometry_normal (normal) <- normalmap    normal (tangent-space map)
======================================  =====================================

Nodes understood in front of those inputs: ``image`` / ``tiledimage`` (file
with its colour space, default, address modes; ``texcoord``, ``place2d``,
``geompropvalue`` texture coordinates folded into the st transform / the st
primvar), ``normalmap``, ``geompropvalue`` (a primvar per vertex, like
UsdPrimvarReader), ``constant``, ``dot``, ``convert``, ``extract`` /
``separate3`` (one channel of a texture), ``multiply`` by a constant (folded
into the texture's scale). Anything else falls back to the input's value or
default, with a warning naming the node and the input. MaterialX's own
``UsdPreviewSurface`` / ``UsdUVTexture`` / ``UsdPrimvarReader`` nodes map
one to one.
"""
from __future__ import annotations

import math
from typing import Any, Dict, List, Optional

from ..scene import Material
from .color import to_rendering_space
from .mtlx_documents import MtlxMaterialRef, mtlx_binding, mtlx_references
from .mtlx_eval import CHANNELS, Const, Prim, Tex, Mapper, scale_rec
from .mtlx_graph import Node, UsdNode, as_float, as_tuple, mtlx_library

__all__ = ["read_materialx_network", "mtlx_binding", "mtlx_references", "MtlxMaterialRef",
           "SURFACE_IDS", "mtlx_library", "map_surface", "read_mtlx_material"]

#: MaterialX surface shaders mapped onto the core's model
SURFACES = ("open_pbr_surface", "standard_surface", "UsdPreviewSurface")
SURFACE_IDS = ("ND_open_pbr_surface_surfaceshader", "ND_standard_surface_surfaceshader",
               "ND_UsdPreviewSurface_surfaceshader")

# ---------------------------------------------------------------- surfaces

_DEFAULTS = {"diffuseColor": (0.18, 0.18, 0.18), "emissiveColor": (0.0, 0.0, 0.0),
             "specularColor": (0.0, 0.0, 0.0), "metallic": 0.0, "roughness": 0.5,
             "clearcoat": 0.0, "clearcoatRoughness": 0.01, "opacity": 1.0,
             "opacityThreshold": 0.0, "ior": 1.5, "useSpecularWorkflow": 0}

#: (open_pbr_surface name, standard_surface name) of every input the mapping reads
_NAMES = {
    "base_weight": ("base_weight", "base"), "base_color": ("base_color", "base_color"),
    "metalness": ("base_metalness", "metalness"),
    "specular_weight": ("specular_weight", "specular"),
    "specular_color": ("specular_color", "specular_color"),
    "roughness": ("specular_roughness", "specular_roughness"),
    "ior": ("specular_ior", "specular_IOR"),
    "coat": ("coat_weight", "coat"), "coat_color": ("coat_color", "coat_color"),
    "coat_roughness": ("coat_roughness", "coat_roughness"), "coat_ior": ("coat_ior", "coat_IOR"),
    "transmission": ("transmission_weight", "transmission"),
    "transmission_color": ("transmission_color", "transmission_color"),
    "emission": ("emission_luminance", "emission"),
    "emission_color": ("emission_color", "emission_color"),
    "opacity": ("geometry_opacity", "opacity"), "normal": ("geometry_normal", "normal"),
}


class _Surface:
    """The UsdPreviewSurface inputs being assembled: constants, texture and
    primvar records."""

    def __init__(self):
        self.values: Dict[str, Any] = {}
        self.records: Dict[str, dict] = {}

    def set(self, name, ev, mapper: Mapper, kind: str, node: Node):
        from .shading import PRIMVAR_INPUTS, _primvar_request_record
        if ev is None:
            return
        if isinstance(ev, Const):
            self.values[name] = ev.value
        elif isinstance(ev, Tex):
            rec = dict(ev.rec)
            if kind == "scalar" and rec.get("output") == "rgb":
                rec["output"] = "r"
            self.records[name] = rec
            fb = rec.get("fallback")
            if fb is not None:
                self.values[name] = to_rendering_space(fb[:3], "lin_rec709") \
                    if kind == "colour" else \
                    fb[CHANNELS.index(rec["output"])] if rec["output"] in CHANNELS else fb[0]
        elif isinstance(ev, Prim):
            if not ev.varname:
                mapper.warn(f"{ev.node.path} ({ev.node.category}) names no primvar; {name} "
                            f"uses its default")
                return
            width = 3 if kind == "colour" else 1
            fb = as_tuple(ev.fallback, width) if ev.fallback is not None else \
                as_tuple(_DEFAULTS.get(name, 0.0), width)
            if kind == "colour":
                fb = to_rendering_space(fb, "lin_rec709")
            if name not in PRIMVAR_INPUTS:
                mapper.warn(f"input {name} reads primvar {ev.varname} through {ev.node.path}, "
                            f"which cmlt cannot vary over a surface for {name}; using "
                            f"{tuple(round(x, 6) for x in fb)}")
                self.values[name] = fb if width == 3 else fb[0]
                return
            self.records[name] = _primvar_request_record(name, ev.varname, fb, ev.node.path,
                                                         ev.node.category)
            self.values[name] = fb if width == 3 else fb[0]

    def constant(self, name):
        """The constant of ``name`` if it is one (no texture, no primvar)."""
        return None if name in self.records else self.values.get(name, _DEFAULTS[name])


def _map_physical(node: Node, mapper: Mapper, std: bool) -> _Surface:
    k = 1 if std else 0

    def nm(key):
        return _NAMES[key][k]

    out = _Surface()
    ev = mapper.eval

    def cval(key, kind):
        """The constant value of an input, or None when something drives it."""
        src = node.input(nm(key))
        return None if src.node is not None else mapper.const(src, kind)

    # base colour x weight -> diffuseColor
    base = ev(node, nm("base_color"), "colour")
    w = cval("base_weight", "scalar")
    if w is None:
        mapper.warn(f"{node.path}: input {nm('base_weight')} is driven by a node; using 1")
        w = 1.0
    if isinstance(base, Const):
        base = Const(tuple(c * w for c in base.value))
    elif isinstance(base, Tex) and w != 1.0:
        base = Tex(scale_rec(base.rec, w))
    out.set("diffuseColor", base, mapper, "colour", node)
    out.set("metallic", ev(node, nm("metalness"), "scalar"), mapper, "scalar", node)
    out.set("roughness", ev(node, nm("roughness"), "scalar"), mapper, "scalar", node)
    ior = cval("ior", "scalar")
    if ior is None:
        mapper.warn(f"{node.path}: input {nm('ior')} is driven by a node; using 1.5")
        ior = 1.5
    out.values["ior"] = ior

    # specular weight / colour: the specular workflow, exactly, for constant bases
    sw = cval("specular_weight", "scalar")
    sc = cval("specular_color", "colour")
    plain_spec = sw is not None and abs(sw - 1.0) < 1e-6 and sc is not None and _is_white(sc)
    foldable = out.constant("diffuseColor") is not None and out.constant("metallic") is not None

    # coat
    out.set("clearcoat", ev(node, nm("coat"), "scalar"), mapper, "scalar", node)
    out.set("clearcoatRoughness", ev(node, nm("coat_roughness"), "scalar"), mapper, "scalar",
            node)
    cc = cval("coat_color", "colour")
    if cc is None or not _is_white(cc):
        if _nonzero(out.values.get("clearcoat"), "clearcoat" in out.records):
            mapper.warn(f"{node.path}: input {nm('coat_color')} is not white; cmlt's coat is "
                        f"white (ignored)")
    ci = cval("coat_ior", "scalar")
    if ci is not None and abs(ci - 1.5) > 1e-3 and \
            _nonzero(out.values.get("clearcoat"), "clearcoat" in out.records):
        mapper.warn(f"{node.path}: input {nm('coat_ior')} = {ci:g}; cmlt's coat has IOR 1.5")

    # transmission -> (1 - opacity) dielectric lobe
    tr = cval("transmission", "scalar")
    if tr is None:
        mapper.warn(f"{node.path}: input {nm('transmission')} is driven by a node; "
                    f"transmission is constant in cmlt, using 0")
        tr = 0.0
    tr = min(max(tr, 0.0), 1.0)
    tc = cval("transmission_color", "colour")
    if tr > 0 and (tc is None or not _is_white(tc)):
        mapper.warn(f"{node.path}: input {nm('transmission_color')} is not white; cmlt's "
                    f"transmission is white (ignored)")

    # emission
    lum = cval("emission", "scalar")
    if lum is None:
        mapper.warn(f"{node.path}: input {nm('emission')} is driven by a node; using 0")
        lum = 0.0
    if lum > 0:
        ec = ev(node, nm("emission_color"), "colour")
        if isinstance(ec, Const):
            ec = Const(tuple(c * lum for c in ec.value))
        elif isinstance(ec, Tex):
            ec = Tex(scale_rec(ec.rec, lum))
        elif isinstance(ec, Prim):
            ec = Prim(ec.varname, ec.fallback, ec.node)
        out.set("emissiveColor", ec, mapper, "colour", node)
    else:
        out.values["emissiveColor"] = (0.0, 0.0, 0.0)

    # normal map
    nsrc = node.input(nm("normal"))
    if nsrc.node is not None:
        nev = mapper.eval_source(nsrc, node, nm("normal"), "vector", 0)
        if isinstance(nev, Tex):
            out.records["normal"] = nev.rec
        elif nev is not None:
            mapper.warn(f"{node.path}: input {nm('normal')} is not a tangent-space normal map; "
                        f"ignored")

    # presence (opacity)
    pres_src = node.input(nm("opacity"))
    pres = None
    if pres_src.node is not None:
        pres = mapper.eval_source(pres_src, node, nm("opacity"), "scalar", 0)
    else:
        pv = pres_src.value
        pres = Const(sum(as_tuple(pv, 3, 1.0)) / 3.0 if std else as_float(pv, 1.0))

    spec_workflow = False
    if not plain_spec:
        if foldable and sw is not None and sc is not None:
            spec_workflow = True
        else:
            mapper.warn(f"{node.path}: inputs {nm('specular_weight')}/{nm('specular_color')} "
                        f"are not 1/white but the base colour or metalness is driven by a node; "
                        f"specular weight and colour are ignored")

    presence_const = pres.value if isinstance(pres, Const) else None
    if presence_const is not None and presence_const < 1.0:
        if tr > 0:
            mapper.warn(f"{node.path}: both {nm('transmission')} and {nm('opacity')} < 1; "
                        f"cmlt has one transmission lobe, {nm('opacity')} is ignored")
        elif foldable and sw is not None and sc is not None:
            spec_workflow = True
        else:
            mapper.warn(f"{node.path}: constant {nm('opacity')} {presence_const:g} with a "
                        f"base driven by a node: rendered as a cut-out at 0.5")
            out.values["opacity"] = presence_const
            out.values["opacityThreshold"] = 0.5
    elif isinstance(pres, (Tex, Prim)):
        if tr > 0:
            mapper.warn(f"{node.path}: both {nm('transmission')} and a varying {nm('opacity')}; "
                        f"{nm('opacity')} is ignored")
        else:
            out.set("opacity", pres, mapper, "scalar", node)
            out.values["opacityThreshold"] = 0.5
            mapper.warn(f"{node.path}: {nm('opacity')} varies over the surface: rendered as a "
                        f"cut-out at 0.5 (opacityThreshold)")

    if spec_workflow:
        base_c = out.constant("diffuseColor")
        metal = min(max(float(out.constant("metallic")), 0.0), 1.0)
        f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior > 0 else 0.0
        spec = tuple(min(1.0, max(0.0, f0 * sw * c)) for c in sc)
        out.values["specularColor"] = tuple((1 - metal) * s + metal * b
                                            for s, b in zip(spec, base_c))
        out.values["diffuseColor"] = tuple((1 - metal) * b for b in base_c)
        out.values["metallic"] = 0.0
        out.values["useSpecularWorkflow"] = 1
        if presence_const is not None and presence_const < 1.0 and tr == 0:
            out.values["opacity"] = presence_const
            out.values["ior"] = 1.0                    # presence: a pass-through
    if tr > 0:
        out.values["opacity"] = 1.0 - tr

    _warn_unmapped(node, mapper, std)
    return out


def _is_white(rgb) -> bool:
    w = to_rendering_space((1.0, 1.0, 1.0), "lin_rec709")
    return all(abs(a - b) < 1e-4 for a, b in zip(rgb, w))


def _nonzero(v, driven: bool) -> bool:
    return driven or (v is not None and float(v) > 0)


#: inputs the mapping reads (the rest warns when authored off its default)
_READ = {name for pair in _NAMES.values() for name in pair}


def _warn_unmapped(node: Node, mapper: Mapper, std: bool):
    for name in node.authored_inputs():
        if name in _READ:
            continue
        src = node.input(name)
        if src.node is None:
            d = node.default(name)
            if d is None or _same_value(src.value, d):
                continue
            what = f"= {_fmt(src.value)}"
        else:
            what = f"is driven by {src.node.path}"
        mapper.warn(f"{node.path}: input {name} {what} has no mapping in cmlt's "
                    f"UsdPreviewSurface model; ignored")


def _same_value(a, b) -> bool:
    if isinstance(a, (tuple, list)) or isinstance(b, (tuple, list)):
        try:
            return all(abs(float(x) - float(y)) < 1e-6 for x, y in
                       zip(as_tuple(a, 4), as_tuple(b, 4)))
        except (TypeError, ValueError):
            return a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(float(a) - float(b)) < 1e-6
    return a == b


def _fmt(v) -> str:
    if isinstance(v, tuple):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _map_preview(node: Node, mapper: Mapper) -> _Surface:
    """MaterialX's UsdPreviewSurface node: one to one."""
    out = _Surface()
    colour = ("diffuseColor", "emissiveColor", "specularColor")
    for name in ("diffuseColor", "emissiveColor", "specularColor", "metallic", "roughness",
                 "clearcoat", "clearcoatRoughness", "opacity", "opacityThreshold", "ior",
                 "useSpecularWorkflow"):
        kind = "colour" if name in colour else "scalar"
        src = node.input(name)
        if src.node is None:
            if src.value is not None:
                out.values[name] = mapper.const(src, kind)
            continue
        if name in ("opacityThreshold", "ior", "useSpecularWorkflow"):
            mapper.warn(f"{node.path}: input {name} is driven by a node; using its default")
            continue
        out.set(name, mapper.eval(node, name, kind), mapper, kind, node)
    nsrc = node.input("normal")
    if nsrc.node is not None:
        nev = mapper.eval_source(nsrc, node, "normal", "vector", 0)
        if isinstance(nev, Tex):
            rec = dict(nev.rec)
            rec["sourceColorSpace"] = "raw"
            out.records["normal"] = rec
    return out


def map_surface(node: Node, material: str, warnings: List[str]) -> Optional[Material]:
    """A MaterialX surface shader node -> Material, or None (not a surface we
    map: warned)."""
    mapper = Mapper(material, warnings)
    cat = node.category
    if cat == "open_pbr_surface":
        surf = _map_physical(node, mapper, std=False)
    elif cat == "standard_surface":
        surf = _map_physical(node, mapper, std=True)
    elif cat == "UsdPreviewSurface":
        surf = _map_preview(node, mapper)
    else:
        warnings.append(f"{material}: surface shader {node.path} ({cat or 'unknown node'}) has "
                        f"no mapping in cmlt (open_pbr_surface, standard_surface and "
                        f"UsdPreviewSurface have); rendered with the default grey material")
        return None
    v = surf.values

    def col(name):
        x = v.get(name, _DEFAULTS[name])
        return tuple(float(c) for c in as_tuple(x, 3))

    def sca(name):
        x = as_float(v.get(name, _DEFAULTS[name]), _DEFAULTS[name])
        return x if math.isfinite(x) else float(_DEFAULTS[name])

    inputs: Dict[str, Any] = dict(surf.records)
    inputs["materialx"] = {"shader": node.path, "category": cat}
    for name, rec in surf.records.items():
        if rec.get("unresolved"):
            warnings.append(f"{material}: texture {rec['unresolved']} for {name} (node "
                            f"{rec['shader']}) cannot be resolved; using the fallback value")
    return Material(
        name=material, diffuse=col("diffuseColor"), emission=col("emissiveColor"),
        specular=col("specularColor"),
        use_specular_workflow=bool(int(sca("useSpecularWorkflow"))),
        metallic=sca("metallic"), roughness=sca("roughness"), clearcoat=sca("clearcoat"),
        clearcoat_roughness=sca("clearcoatRoughness"), opacity=sca("opacity"),
        opacity_threshold=sca("opacityThreshold"), ior=sca("ior"), inputs=inputs)


# ---------------------------------------------------------------- UsdShade networks

def mtlx_surface_shader(material):
    """The surface shader of a UsdShade material's ``mtlx`` render context
    (or of its universal output when that is a MaterialX node), or None."""
    from pxr import UsdShade

    from .shading import _shader_id
    try:
        src, _, _ = material.ComputeSurfaceSource(["mtlx"])
    except Exception:                                    # pragma: no cover
        src = None
    if src and _shader_id(src).startswith("ND_"):
        return src
    for out in material.GetSurfaceOutputs():
        for sinfo in out.GetConnectedSources()[0]:
            shader = UsdShade.Shader(sinfo.source.GetPrim())
            if shader and _shader_id(shader).startswith("ND_"):
                return shader
    return None


def read_materialx_network(material, time, warnings: List[str]):
    """(is MaterialX, Material or None) for a UsdShade material whose surface
    is a MaterialX node network or whose prim references a ``.mtlx``
    document; (False, None) for anything else. None with True: the surface
    could not be mapped (warned)."""
    path = str(material.GetPath())
    shader = mtlx_surface_shader(material)
    if shader is not None:
        return True, map_surface(UsdNode(shader), path, warnings)
    ref = mtlx_binding(material.GetPrim().GetStage(), material.GetPath())
    if ref is not None:
        return True, read_mtlx_material(ref, time, warnings, name=path)
    return False, None


def read_mtlx_material(ref: MtlxMaterialRef, time, warnings: List[str],
                       name: Optional[str] = None) -> Optional[Material]:
    """The Material of a ``.mtlx`` document's material that a binding points at
    (None when it cannot be read or mapped: warned, naming ``name`` or the target)."""
    label = name or str(ref.target)
    node = ref.surface_node(label, warnings)
    return None if node is None else map_surface(node, label, warnings)
