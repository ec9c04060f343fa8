"""The stage's ``UsdRender.Product`` and ``UsdRender.Var`` prims: which channels a
frame's EXR holds and, when the product names one, where it goes.

A settings prim's ``products`` relationship names the products; cmlt writes one
EXR per frame, so it reads the first ``raster`` product (a second one, or one of
another type, is a warning). Each of the product's ``orderedVars`` is one layer
of that EXR:

* ``sourceName`` picks the cmlt AOV (:data:`SOURCE_NAMES`; case does not
  matter, so Hydra's ``color``/``normal``/``depth``, Karma's ``C``/``N`` and
  cmlt's own names all work). The beauty is always the EXR's ``R``, ``G``,
  ``B``; a var whose source is the beauty adds nothing. An unknown source is a
  warning naming the RenderVar prim, and that layer is skipped;
* the layer's name is ``driver:parameters:aov:name`` when authored (as husk
  reads it), else the RenderVar prim's name: ``diffuse.R/G/B`` for a colour,
  ``N.X/Y/Z`` for a vector, a single channel ``Z`` for a float;
* ``dataType`` must have as many components as the AOV (3 for colours and
  normals, 1 for depth and the error estimate); a half type (``half``,
  ``color3h``, ...) stores that layer as half floats. A mismatch is a warning
  and the layer is skipped.

``productName`` is the output path pattern when ``--out`` is not given, with
cmlt's frame tokens (``####``, ``$F4``, ``%04d``); relative to the working
directory, as husk resolves it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

from pxr import UsdRender

__all__ = ["RenderLayer", "RenderProduct", "SOURCE_NAMES", "read_render_product"]

#: RenderVar ``sourceName`` (lower case) -> the cmlt AOV it names ("beauty": the image)
SOURCE_NAMES: Dict[str, str] = {
    "color": "beauty", "c": "beauty", "ci": "beauty", "rgb": "beauty", "rgba": "beauty",
    "beauty": "beauty", "c.*": "beauty", "c.*[<l.>o]": "beauty", "lpe:c.*": "beauty",
    "albedo": "albedo", "diffusecolor": "albedo", "diffuse_color": "albedo",
    "normal": "normal", "n": "normal", "nworld": "normal",
    "depth": "depth", "z": "depth", "cameradepth": "depth",
    "variance": "variance",
    "error": "error", "relmse": "error",
}
#: components of each AOV (the beauty is RGB)
_COMPONENTS = {"beauty": 3, "albedo": 3, "normal": 3, "depth": 1, "variance": 3, "error": 1}
#: RenderVar dataType -> (components, half?)
_DATA_TYPES: Dict[str, Tuple[int, bool]] = {
    "float": (1, False), "half": (1, True), "double": (1, False), "int": (1, False),
    "color3f": (3, False), "color3h": (3, True), "color3d": (3, False),
    "float3": (3, False), "half3": (3, True), "double3": (3, False),
    "normal3f": (3, False), "normal3h": (3, True), "vector3f": (3, False),
    "vector3h": (3, True), "point3f": (3, False), "point3h": (3, True),
    "color4f": (4, False), "color4h": (4, True), "float4": (4, False), "half4": (4, True),
}
#: channel suffixes by AOV
_SUFFIXES = {"albedo": ("R", "G", "B"), "variance": ("R", "G", "B"), "normal": ("X", "Y", "Z")}


@dataclass(frozen=True)
class RenderLayer:
    """One RenderVar written as EXR channels."""

    var: str                        # the RenderVar prim path
    aov: str                        # the cmlt AOV (cmlt.io.exr.AOV_CHANNELS)
    name: str                       # layer name: prefix of the channels
    suffixes: Optional[Tuple[str, ...]]     # None: one channel named ``name``
    data_type: str
    half: bool

    def channels(self) -> List[str]:
        return [self.name] if self.suffixes is None else [f"{self.name}.{s}"
                                                          for s in self.suffixes]

    def as_dict(self) -> dict:
        return {"var": self.var, "source": self.aov, "channels": self.channels(),
                "data_type": self.data_type}


@dataclass
class RenderProduct:
    """The product a render writes: its prim, output pattern and layers."""

    path: str
    product_name: str = ""          # '' when not authored
    layers: List[RenderLayer] = field(default_factory=list)
    warnings: List[str] = field(default_factory=list)

    def aovs(self) -> Tuple[str, ...]:
        """The cmlt AOVs the layers need, each once, in layer order."""
        return tuple(dict.fromkeys(layer.aov for layer in self.layers))

    def as_dict(self) -> dict:
        return {"product": self.path, "product_name": self.product_name,
                "layers": [layer.as_dict() for layer in self.layers]}


def _layer_name(var_prim) -> str:
    attr = var_prim.GetAttribute("driver:parameters:aov:name")
    value = attr.Get() if attr and attr.HasAuthoredValue() else None
    return str(value) if value else var_prim.GetName()


def _layer(var_prim, warnings: List[str]) -> Optional[RenderLayer]:
    """The layer of one RenderVar prim, or None (with a warning) when it has none."""
    path = str(var_prim.GetPath())
    if not var_prim.IsA(UsdRender.Var):
        warnings.append(f"{path}: a {var_prim.GetTypeName() or 'typeless'} prim in a render "
                        "product's orderedVars, not a RenderVar; skipped")
        return None
    rv = UsdRender.Var(var_prim)
    source = str(rv.GetSourceNameAttr().Get() or "")
    data_type = str(rv.GetDataTypeAttr().Get() or "color3f")
    aov = SOURCE_NAMES.get(source.strip().lower())
    if aov is None:
        known = sorted({k for k in SOURCE_NAMES if "*" not in k})
        warnings.append(f"{path}: RenderVar sourceName {source!r} is not an AOV cmlt renders "
                        f"(known: {', '.join(known)}); channel skipped")
        return None
    comps, half = _DATA_TYPES.get(data_type, (None, False))
    want = _COMPONENTS[aov]
    if comps is None or comps != want and not (aov == "beauty" and comps == 4):
        warnings.append(f"{path}: RenderVar dataType {data_type!r} does not fit {aov} "
                        f"({want} component{'s' if want > 1 else ''}, e.g. "
                        f"{'color3f' if want == 3 else 'float'}); channel skipped")
        return None
    if aov == "beauty":
        return RenderLayer(path, aov, "", ("R", "G", "B"), data_type, half)
    name = _layer_name(var_prim)
    return RenderLayer(path, aov, name, _SUFFIXES.get(aov) if want == 3 else None,
                       data_type, half)


def read_render_product(stage, settings_prim) -> Optional[RenderProduct]:
    """The product a render of ``settings_prim`` writes (module rules), or
    ``None`` when the settings name no usable product."""
    if stage is None or settings_prim is None:
        return None
    targets = UsdRender.Settings(settings_prim).GetProductsRel().GetForwardedTargets()
    product, skipped = None, []
    for t in targets:
        prim = stage.GetPrimAtPath(t)
        if not prim or not prim.IsA(UsdRender.Product):
            what = "does not exist" if not prim else \
                f"is a {prim.GetTypeName() or 'typeless'} prim, not a RenderProduct"
            skipped.append(f"{settings_prim.GetPath()}: render product {t} {what}; ignored")
            continue
        ptype = str(UsdRender.Product(prim).GetProductTypeAttr().Get() or "raster")
        if ptype != "raster":
            skipped.append(f"{t}: productType {ptype!r} is not written (cmlt writes raster "
                           "EXRs); product ignored")
            continue
        if product is not None:
            skipped.append(f"{t}: a second raster product; cmlt writes one EXR per frame "
                           f"({product.path}); ignored")
            continue
        product = RenderProduct(str(t))
        name = UsdRender.Product(prim).GetProductNameAttr().Get()
        product.product_name = str(name) if name else ""
        for v in UsdRender.Product(prim).GetOrderedVarsRel().GetForwardedTargets():
            var_prim = stage.GetPrimAtPath(v)
            if not var_prim:
                product.warnings.append(f"{t}: RenderVar {v} does not exist; channel skipped")
                continue
            layer = _layer(var_prim, product.warnings)
            if layer is not None and layer.aov != "beauty":
                if any(layer.channels() == other.channels() for other in product.layers):
                    product.warnings.append(f"{v}: channels {', '.join(layer.channels())} "
                                            "already written by another RenderVar; skipped")
                    continue
                product.layers.append(layer)
    if product is None:
        if skipped:
            return RenderProduct("", warnings=skipped)
        return None
    product.warnings[:0] = skipped
    return product
