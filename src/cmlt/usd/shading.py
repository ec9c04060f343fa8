"""Shading-network helpers shared by the UsdPreviewSurface reader
(:mod:`cmlt.usd.materials`) and the MaterialX reader (:mod:`cmlt.usd.materialx`):
shader ids, value sources through connections, UsdTransform2d, primvar requests."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Tuple

from pxr import Sdf, UsdShade

COLOR_INPUTS = ("diffuseColor", "emissiveColor", "specularColor")

#: UsdPreviewSurface inputs the core reads per hit from primvars (colour: 3 columns)
PRIMVAR_INPUTS = {"diffuseColor": 3, "specularColor": 3, "metallic": 1, "roughness": 1,
                  "clearcoat": 1, "clearcoatRoughness": 1, "opacity": 1}


@dataclass(frozen=True)
class PrimvarRequest:
    """A per-vertex value a material input reads through a UsdPrimvarReader:
    the mesh reader interpolates primvar ``varname`` to ``width`` columns
    (1 for scalar inputs, 3 for colours; a narrower primvar is repeated
    (scalar) or padded with 0, a wider one cut), converting colours to the
    rendering space; where a gprim lacks the primvar, ``fallback`` (already
    in rendering-space units) fills it, with a warning naming ``reader``.
    Equal requests share their columns (``cmlt.shot.material_table``)."""

    varname: str
    width: int
    colour: bool
    fallback: Tuple[float, ...]
    reader: str = field(default="", compare=False)


def _shader_id(shader: UsdShade.Shader) -> str:
    try:
        sid = shader.GetShaderId()
    except Exception:                                    # pragma: no cover
        sid = None
    return str(sid or "")


def _plain(value):
    """USD value -> plain Python (tuples of floats, str, float, int, bool)."""
    if value is None:
        return None
    if isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else 0.0
    if isinstance(value, Sdf.AssetPath):
        return value.resolvedPath or value.path
    try:
        seq = tuple(float(x) for x in value)
        return tuple(x if math.isfinite(x) else 0.0 for x in seq)
    except TypeError:
        return str(value)


def _value_source(inp: UsdShade.Input):
    """(value, shader, output name) for an input: follows connections through
    node graph / material interface inputs."""
    try:
        attrs = inp.GetValueProducingAttributes()
    except Exception:                                    # pragma: no cover
        attrs = []
    for attr in attrs:
        if UsdShade.Output.IsOutput(attr):
            shader = UsdShade.Shader(attr.GetPrim())
            if shader:
                return None, shader, UsdShade.Output(attr).GetBaseName()
        else:
            return attr.Get(), None, None
    return inp.Get(), None, None


def _input_value(shader: UsdShade.Shader, name: str, default):
    inp = shader.GetInput(name)
    if not inp:
        return default
    v, _, _ = _value_source(inp)
    return default if v is None else _plain(v)


def _transform2d_matrix(node: UsdShade.Shader) -> Tuple[float, ...]:
    """A UsdTransform2d as a 2x3 matrix: ``result = in * scale * rotate +
    translation`` (scale about the origin, then a counter-clockwise rotation
    in degrees, then the translation; the UsdPreviewSurface spec)."""
    sx, sy = (tuple(_input_value(node, "scale", (1.0, 1.0))) + (1.0, 1.0))[:2]
    rot = _input_value(node, "rotation", 0.0)
    rot = float(rot[0] if isinstance(rot, tuple) else rot)
    tx, ty = (tuple(_input_value(node, "translation", (0.0, 0.0))) + (0.0, 0.0))[:2]
    c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
    return (c * sx, -s * sy, float(tx), s * sx, c * sy, float(ty))


def _primvar_request_record(name: str, varname: str, fallback, reader: str, sid: str) -> dict:
    """The inputs record of ``name`` read per vertex from primvar ``varname``
    (``fallback`` in rendering-space units), as _primvar_record makes it."""
    fb = tuple(float(x) for x in fallback)
    return {"shader": reader, "id": sid, "primvar": varname, "fallback": fb,
            "primvar_request": PrimvarRequest(varname, PRIMVAR_INPUTS[name],
                                              name in COLOR_INPUTS, fb, reader)}
