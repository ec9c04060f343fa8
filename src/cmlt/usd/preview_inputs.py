"""The inputs of a UsdPreviewSurface that come from other shaders: UsdUVTexture
records (file, channel, wrap modes, scale / bias, fallback, colour space, the st
primvar and UsdTransform2d chain in front of it) and UsdPrimvarReader records (the
primvar a mesh must provide, with the reader's fallback), plus the surface's own
defaults. :func:`cmlt.usd.materials.read_material` assembles a material from them."""
from __future__ import annotations

from typing import List, Optional, Tuple

from pxr import Sdf, UsdShade

from .color import to_rendering_space
from .shading import (COLOR_INPUTS, PRIMVAR_INPUTS, PrimvarRequest, _input_value, _shader_id,
                      _transform2d_matrix, _value_source)

__all__ = ["PREVIEW_DEFAULTS", "PRIMVAR_READERS", "WRAP_MODES", "IDENTITY_ST",
           "texture_record", "fallback_constant", "primvar_record"]

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


def texture_record(tex: UsdShade.Shader, output: str,
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


def fallback_constant(name: str, record: dict):
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


def primvar_record(material: str, name: str, reader: UsdShade.Shader, sid: str,
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
