"""UsdShade materials -> :class:`cmlt.scene.Material` (UsdPreviewSurface)."""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from pxr import UsdGeom, UsdShade

from ..scene import Material
from .color import to_rendering_space
from .preview_inputs import (PREVIEW_DEFAULTS, PRIMVAR_READERS, fallback_constant,
                             primvar_record, texture_record)
from .shading import PrimvarRequest, _plain, _shader_id, _value_source

DEFAULT_MATERIAL_NAME = "<default>"


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
                rec, fb = primvar_record(path, name, src, sid, warnings)
                inputs[name] = rec
                values[name] = fb
                if isinstance(fb, tuple):
                    converted.add(name)
                continue
            if sid == "UsdUVTexture":
                rec = texture_record(src, output or "rgb", warnings)
                if rec.get("unresolved"):
                    warnings.append(f"{path}: texture {rec['unresolved']} for {name} "
                                    f"(shader {rec['shader']}) cannot be resolved; using "
                                    "the fallback value")
                inputs[name] = rec
                values[name] = fallback_constant(name, rec)
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
                from .materialx import read_mtlx_material
                m = read_mtlx_material(mat, self.time, self.warnings) or \
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
