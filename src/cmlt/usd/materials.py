"""UsdShade materials -> :class:`cmlt.scene.Material` (UsdPreviewSurface)."""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from pxr import Sdf, UsdGeom, UsdShade

from ..scene import Material
from .color import to_rendering_space
from .shading import (COLOR_INPUTS, PRIMVAR_INPUTS, PrimvarRequest,  # noqa: F401 (re-exported)
                      _input_value, _plain, _shader_id,
                      _transform2d_matrix, _value_source)

DEFAULT_MATERIAL_NAME = "<default>"

# UsdPreviewSurface inputs and their shader defaults.
PREVIEW_DEFAULTS = {
    "diffuseColor": (0.18, 0.18, 0.18),
    "emissiveColor": (0.0, 0.0, 0.0),
    "useSpecularWorkflow": 0,
    "specularColor": (0.0, 0.0, 0.0),
    "metallic": 0.0,
    "roughness": 0.5,
    "clearcoat": 0.0,
    "clearcoatRoughness": 0.01,
    "opacity": 1.0,
    "opacityMode": "transparent",
    "opacityThreshold": 0.0,
    "ior": 1.5,
    "normal": (0.0, 0.0, 1.0),
    "displacement": 0.0,
    "occlusion": 1.0,
}
_TEXTURE_CHANNELS = {"r": 0, "g": 1, "b": 2, "a": 3}

#: UsdPrimvarReader_* shader ids -> the width of their ``result``
PRIMVAR_READERS = {
    "UsdPrimvarReader_float": 1, "UsdPrimvarReader_int": 1, "UsdPrimvarReader_float2": 2,
    "UsdPrimvarReader_float3": 3, "UsdPrimvarReader_normal": 3, "UsdPrimvarReader_point": 3,
    "UsdPrimvarReader_vector": 3, "UsdPrimvarReader_float4": 4,
}


def _fit_width(values, width: int) -> Tuple[float, ...]:
    v = tuple(float(x) for x in (values if isinstance(values, (tuple, list)) else (values,)))
    if not v:
        v = (0.0,)
    if len(v) == 1:
        return v * width
    return (v + (0.0,) * width)[:width]


def _asset_path(shader: UsdShade.Shader, name: str) -> Optional[str]:
    inp = shader.GetInput(name)
    if not inp:
        return None
    value, _, _ = _value_source(inp)
    if isinstance(value, Sdf.AssetPath):
        return value.resolvedPath or value.path or None
    return str(value) if value else None


#: UsdUVTexture wrap tokens (``useMetadata``: the file's metadata, else black)
WRAP_MODES = ("black", "clamp", "repeat", "mirror", "useMetadata")
#: identity of the st transform (2x3, row-major a, b, tx, c, d, ty)
IDENTITY_ST = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)


def _compose(outer: Tuple[float, ...], inner: Tuple[float, ...]) -> Tuple[float, ...]:
    """outer(inner(st)) for 2x3 affine matrices."""
    a, b, tx, c, d, ty = outer
    e, f, ux, g, h, uy = inner
    return (a * e + b * g, a * f + b * h, a * ux + b * uy + tx,
            c * e + d * g, c * f + d * h, c * ux + d * uy + ty)


def _st_network(tex: UsdShade.Shader, warnings: Optional[List[str]] = None) -> dict:
    """What feeds a UsdUVTexture's ``st``: the primvar (``st_primvar``, the
    UsdPrimvarReader_float2's ``varname``) and its ``fallback`` (used where a
    mesh lacks that primvar; the reader's default is (0, 0)), through any
    chain of UsdTransform2d nodes folded into ``st_transform``. An unconnected
    ``st`` reads the mesh's texture coordinates (``st``, else a texCoord2f
    primvar); another kind of node in the chain is warned about and ignored."""
    out = {"st_primvar": None, "st_fallback": None, "st_transform": IDENTITY_ST}
    inp = tex.GetInput("st")
    xf = IDENTITY_ST
    seen = set()
    while inp:
        _, src, _ = _value_source(inp)
        if src is None or str(src.GetPath()) in seen:
            break
        seen.add(str(src.GetPath()))
        sid = _shader_id(src)
        if sid == "UsdTransform2d":
            xf = _compose(xf, _transform2d_matrix(src))     # st' = xf(node(in))
            inp = src.GetInput("in")
            continue
        if sid.startswith("UsdPrimvarReader"):
            vn = src.GetInput("varname")
            if vn:
                name, _, _ = _value_source(vn)
                out["st_primvar"] = str(name) if name else None
            fb = _input_value(src, "fallback", (0.0, 0.0))
            fb = tuple(fb) if isinstance(fb, tuple) else (float(fb), float(fb))
            out["st_fallback"] = (tuple(float(x) for x in fb) + (0.0, 0.0))[:2]
            break
        if warnings is not None:
            warnings.append(f"{tex.GetPath()}: inputs:st is driven by unsupported shader "
                            f"{src.GetPath()} ({sid or 'no id'}); reading the mesh's st "
                            f"instead")
        break
    out["st_transform"] = tuple(float(v) for v in xf)
    return out


def _texture_record(tex: UsdShade.Shader, output: str,
                    warnings: Optional[List[str]] = None) -> dict:
    def val(name, default):
        return _input_value(tex, name, default)

    st_info = _st_network(tex, warnings)
    wraps = {}
    for name in ("wrapS", "wrapT"):
        w = str(val(name, "useMetadata"))
        if w not in WRAP_MODES:
            if warnings is not None:
                warnings.append(f"{tex.GetPath()}: inputs:{name} = '{w}' is not one of "
                                f"{', '.join(WRAP_MODES)}; using useMetadata")
            w = "useMetadata"
        wraps[name] = w
    file_attr = tex.GetInput("file")
    unresolved = None
    if file_attr:
        raw, _, _ = _value_source(file_attr)
        if isinstance(raw, Sdf.AssetPath) and raw.path and not raw.resolvedPath:
            unresolved = raw.path
    return {
        "texture": _asset_path(tex, "file"),
        "shader": str(tex.GetPath()),
        "output": output,
        "wrapS": wraps["wrapS"],
        "wrapT": wraps["wrapT"],
        "scale": val("scale", (1.0, 1.0, 1.0, 1.0)),
        "bias": val("bias", (0.0, 0.0, 0.0, 0.0)),
        "sourceColorSpace": val("sourceColorSpace", "auto"),
        "st_primvar": st_info["st_primvar"],
        "st_fallback": st_info["st_fallback"],
        "st_transform": st_info["st_transform"],
        "fallback": val("fallback", None),
        "unresolved": unresolved,
    }


def _fallback_constant(name: str, record: dict):
    """Flat value for an input driven by a texture: the texture's authored
    fallback (picked by the connected output), else the shader default."""
    default = PREVIEW_DEFAULTS.get(name)
    fb = record.get("fallback")
    if fb is None:
        return default
    fb = tuple(fb) + (0.0,) * (4 - len(fb))
    out = record.get("output", "rgb")
    if out in _TEXTURE_CHANNELS:
        c = fb[_TEXTURE_CHANNELS[out]]
        return (c, c, c) if isinstance(default, tuple) else c
    if isinstance(default, tuple):
        return fb[:3]
    return fb[0]


def _primvar_record(material: str, name: str, reader: UsdShade.Shader, sid: str,
                    warnings: List[str]):
    """(inputs record, constant) for a surface input driven by a
    UsdPrimvarReader_*. The constant is the reader's ``fallback`` (the spec's
    default: zeros), what the input takes where a gprim lacks the primvar and
    what inputs that cannot vary per hit (emission, ior, normal ...) keep,
    with a warning. Colour constants are returned in the rendering space."""
    varname = ""
    vn = reader.GetInput("varname")
    if vn:
        raw, _, _ = _value_source(vn)
        varname = str(raw) if raw else ""
    rpath = str(reader.GetPath())
    default = PREVIEW_DEFAULTS.get(name)
    width = 3 if isinstance(default, tuple) and len(default) == 3 else 1
    colour = name in COLOR_INPUTS
    fb_raw = _input_value(reader, "fallback", 0.0)
    fb = _fit_width(fb_raw if fb_raw is not None else 0.0, width)
    if colour:
        fb_attr = reader.GetInput("fallback")
        fb = to_rendering_space(fb, fb_attr.GetAttr() if fb_attr else None,
                                prim=reader.GetPrim())
    rec = {"shader": rpath, "id": sid, "primvar": varname, "fallback": fb}
    constant = fb if width == 3 else fb[0]
    if not varname:
        warnings.append(f"{material}: input {name} is read by {rpath} ({sid}) without a "
                        f"varname; using its fallback {_fmt(fb)}")
        return rec, constant
    if name not in PRIMVAR_INPUTS:
        warnings.append(f"{material}: input {name} reads primvar {varname} through {rpath} "
                        f"({sid}), which cmlt cannot vary over a surface for {name}; using "
                        f"the reader's fallback {_fmt(fb)}")
        return rec, constant
    rec["primvar_request"] = PrimvarRequest(varname, PRIMVAR_INPUTS[name], colour, tuple(fb),
                                            rpath)
    return rec, constant


def _fmt(v) -> str:
    return "(" + ", ".join(f"{x:g}" for x in v) + ")" if isinstance(v, tuple) else f"{v:g}"


def find_preview_surface(material: UsdShade.Material) -> Optional[UsdShade.Shader]:
    """The UsdPreviewSurface of a material: the universal surface output, else
    any render context's surface output that is a UsdPreviewSurface."""
    try:
        src, _, _ = material.ComputeSurfaceSource()
    except Exception:                                    # pragma: no cover
        src = None
    if src and _shader_id(src) == "UsdPreviewSurface":
        return src
    for out in material.GetSurfaceOutputs():
        for sinfo in out.GetConnectedSources()[0]:
            shader = UsdShade.Shader(sinfo.source.GetPrim())
            if shader and _shader_id(shader) == "UsdPreviewSurface":
                return shader
    return None


def read_material(material: UsdShade.Material, time, warnings: List[str]) -> Material:
    """Build a Material from a UsdShade.Material. A network without a
    UsdPreviewSurface gives the default grey and a warning."""
    path = str(material.GetPath())
    shader = find_preview_surface(material)
    if shader is None:
        # MaterialX: a network of ND_* nodes, or a referenced .mtlx document
        from .materialx import read_materialx_network
        found, mx_mat = read_materialx_network(material, time, warnings)
        if mx_mat is not None:
            return mx_mat
        if found:                                        # MaterialX, but unmappable: warned
            return Material(name=path, inputs={"unsupported": True})
        warnings.append(f"{path}: no UsdPreviewSurface surface shader (unsupported shader "
                        f"network); rendered with the default grey material")
        return Material(name=path, inputs={"unsupported": True})
    values: Dict[str, object] = {}
    inputs: Dict[str, object] = {}
    converted = set()                     # values already in the rendering space
    for inp in shader.GetInputs():
        name = inp.GetBaseName()
        value, src, output = _value_source(inp)
        if src is not None:
            sid = _shader_id(src)
            if sid in PRIMVAR_READERS:
                rec, fb = _primvar_record(path, name, src, sid, warnings)
                inputs[name] = rec
                values[name] = fb
                if isinstance(fb, tuple):
                    converted.add(name)
                continue
            if sid == "UsdUVTexture":
                rec = _texture_record(src, output or "rgb", warnings)
                if rec.get("unresolved"):
                    warnings.append(f"{path}: texture {rec['unresolved']} for {name} "
                                    f"(shader {rec['shader']}) cannot be resolved; using "
                                    "the fallback value")
                inputs[name] = rec
                values[name] = _fallback_constant(name, rec)
            else:
                inputs[name] = {"shader": str(src.GetPath()), "id": sid, "output": output}
                values[name] = PREVIEW_DEFAULTS.get(name)
                warnings.append(f"{path}: input {name} is connected to unsupported shader "
                                f"{src.GetPath()} ({sid or 'no id'}); using the default value")
            continue
        if value is None:
            continue
        v = _plain(value)
        inputs[name] = v
        values[name] = v

    def color(name):
        v = values.get(name, PREVIEW_DEFAULTS[name])
        if not isinstance(v, tuple) or len(v) < 3:
            v = PREVIEW_DEFAULTS[name]
        if name in converted:
            return tuple(float(x) for x in v[:3])
        attr = shader.GetInput(name)
        # the input's colorSpace metadata, else ColorSpaceAPI up namespace, else lin_rec709
        with np.errstate(over="ignore", invalid="ignore"):
            out = to_rendering_space(v[:3], attr.GetAttr() if attr else None,
                                     prim=shader.GetPrim())
        if not all(math.isfinite(float(c)) for c in out):
            warnings.append(f"{path}: input {name} is not finite in the rendering space "
                            f"({_fmt_components(v[:3])}); using the default")
            return to_rendering_space(PREVIEW_DEFAULTS[name], None, prim=shader.GetPrim())
        if min(float(c) for c in out) < 0.0:
            warnings.append(f"{path}: input {name} has negative components in the rendering "
                            f"space ({_fmt_components(out)}); clamped to 0")
            out = tuple(max(0.0, float(c)) for c in out)
        return out

    def scalar(name):
        v = values.get(name, PREVIEW_DEFAULTS[name])
        if isinstance(v, tuple):
            v = v[0] if v else PREVIEW_DEFAULTS[name]
        try:
            f = float(v)
        except (TypeError, ValueError):
            f = float(PREVIEW_DEFAULTS[name])
        if not math.isfinite(f):
            warnings.append(f"{path}: input {name} is {f}; using the default "
                            f"{PREVIEW_DEFAULTS[name]}")
            return float(PREVIEW_DEFAULTS[name])
        return f

    return Material(
        name=path,
        diffuse=color("diffuseColor"),
        emission=color("emissiveColor"),
        specular=color("specularColor"),
        use_specular_workflow=bool(int(scalar("useSpecularWorkflow"))),
        metallic=scalar("metallic"),
        roughness=scalar("roughness"),
        clearcoat=scalar("clearcoat"),
        clearcoat_roughness=scalar("clearcoatRoughness"),
        opacity=scalar("opacity"),
        opacity_threshold=scalar("opacityThreshold"),
        ior=scalar("ior"),
        inputs=inputs,
    )


def _fmt_components(v) -> str:
    return ", ".join(f"{float(c):g}" for c in v)


def bound_material(prim):
    """The material bound to ``prim`` for final renders (purpose 'full',
    falling back to all-purpose bindings), or None. A binding whose target
    does not exist because it lies under a reference to a ``.mtlx``
    document (which usd-core cannot compose) gives a
    :class:`cmlt.usd.materialx.MtlxMaterialRef` instead."""
    try:
        mat, rel = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial(UsdShade.Tokens.full)
    except Exception:                                    # pragma: no cover
        return None
    if mat and mat.GetPrim().IsValid():
        return mat
    targets = rel.GetTargets() if rel else []
    if targets:
        from .materialx import mtlx_binding
        return mtlx_binding(prim.GetStage(), targets[0])
    return None


#: the request of a gprim without a material whose displayColor varies over it
def _display_request() -> PrimvarRequest:
    return PrimvarRequest("displayColor", 3, True, (0.18, 0.18, 0.18), "displayColor")


def display_color_varies(prim, time) -> bool:
    """``primvars:displayColor`` has more than one distinct value over the gprim."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    if not pv or not pv.HasAuthoredValue():
        return False
    if pv.GetInterpolation() == UsdGeom.Tokens.constant:
        return False
    v = pv.Get(time)
    if v is None or len(v) < 2:
        return False
    import numpy as np
    a = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    return bool((a != a[0]).any())


def display_color(prim, time) -> Optional[Tuple[float, float, float]]:
    """``primvars:displayColor`` as a single colour (the mean if not constant)."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    if not pv or not pv.HasAuthoredValue():
        return None
    v = pv.ComputeFlattened(time)
    if v is None or len(v) == 0:
        return None
    import numpy as np
    a = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    a = a[np.isfinite(a).all(axis=1)]
    if len(a) == 0:
        return None
    return to_rendering_space(a.mean(axis=0), pv.GetAttr(), prim=prim)


def subset_bindings(prim, time) -> List[Tuple[object, UsdShade.Material]]:
    """(face indices, material) for each materialBind GeomSubset of ``prim``."""
    out = []
    try:
        subsets = UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets()
    except Exception:                                    # pragma: no cover
        return out
    for sub in subsets:
        if sub.GetElementTypeAttr().Get() not in (None, UsdGeom.Tokens.face):
            continue
        mat = bound_material(sub.GetPrim())
        idx = sub.GetIndicesAttr().Get(time)
        if mat is None or idx is None:
            continue
        out.append((idx, mat))
    return out


class MaterialTable:
    """The frame's material list; each material prim appears once."""

    def __init__(self, time, warnings: List[str]):
        self.time = time
        self.warnings = warnings
        self.materials: List[Material] = []
        self._index: Dict[str, int] = {}

    def default(self) -> int:
        return self._add_special(DEFAULT_MATERIAL_NAME, Material(name=DEFAULT_MATERIAL_NAME))

    def _add_special(self, key: str, mat: Material) -> int:
        i = self._index.get(key)
        if i is None:
            i = len(self.materials)
            self.materials.append(mat)
            self._index[key] = i
        return i

    def display(self, rgb) -> int:
        key = "<displayColor %.6g %.6g %.6g>" % tuple(rgb)
        return self._add_special(key, Material(name=key, diffuse=tuple(rgb)))

    def display_per_vertex(self) -> int:
        """The material of gprims without one whose displayColor varies:
        diffuse read per hit from displayColor (as Storm's fallback does)."""
        key = "<displayColor primvar>"
        req = _display_request()
        rec = {"shader": "displayColor", "id": "displayColor", "primvar": req.varname,
               "fallback": req.fallback, "primvar_request": req}
        return self._add_special(key, Material(name=key, diffuse=req.fallback,
                                               inputs={"diffuseColor": rec}))

    def material(self, mat) -> int:
        key = str(mat.GetPath())
        i = self._index.get(key)
        if i is None:
            if isinstance(mat, UsdShade.Material):
                m = read_material(mat, self.time, self.warnings)
            else:                                        # a .mtlx document's material
                m = mat.read(self.time, self.warnings) or \
                    Material(name=key, inputs={"unsupported": True})
            if m.inputs.get("unsupported"):
                i = self.default()
            else:
                i = len(self.materials)
                self.materials.append(m)
            self._index[key] = i
        return i

    def for_prim(self, prim) -> int:
        """Material index for a gprim without subsets."""
        mat = bound_material(prim)
        if mat is not None:
            return self.material(mat)
        if display_color_varies(prim, self.time):
            return self.display_per_vertex()
        dc = display_color(prim, self.time)
        if dc is not None:
            return self.display(dc)
        return self.default()

    def primvar_requests(self, prim) -> Tuple[PrimvarRequest, ...]:
        """What the materials ``prim`` uses (its binding, its GeomSubsets'
        bindings, else the per-vertex displayColor material) read per vertex
        through UsdPrimvarReaders, each request once, in material order."""
        mats = [bound_material(prim)] + [m for _, m in subset_bindings(prim, self.time)]
        indices = [self.material(m) for m in mats if m is not None]
        if mats[0] is None:
            indices.insert(0, self.for_prim(prim))
        out: Dict[PrimvarRequest, None] = {}
        for i in indices:
            for v in self.materials[i].inputs.values():
                req = v.get("primvar_request") if isinstance(v, dict) else None
                if req is not None:
                    out.setdefault(req, None)
        return tuple(out)

    def uv_primvar_name(self, prim) -> Optional[str]:
        """The st primvar name the bound material's textures read, if any."""
        return self.uv_primvar(prim)[0]

    def uv_primvar(self, prim) -> Tuple[Optional[str], Optional[Tuple[float, float]], str]:
        """(primvar name, the UsdPrimvarReader_float2's fallback, reader shader
        path) that the bound material's textures read their st from, or
        (None, None, '') when no texture names a primvar."""
        mats = [bound_material(prim)] + [m for _, m in subset_bindings(prim, self.time)]
        for mat in mats:
            if mat is None:
                continue
            i = self.material(mat)
            for v in self.materials[i].inputs.values():
                if isinstance(v, dict) and v.get("st_primvar"):
                    return v["st_primvar"], v.get("st_fallback"), str(v.get("shader", ""))
        return None, None, ""

    def has_emission(self) -> bool:
        for m in self.materials:
            if any(c > 0 for c in m.emission):
                return True
            if isinstance(m.inputs.get("emissiveColor"), dict):
                return True
        return False
