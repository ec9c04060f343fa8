"""Which colour space a USD colour was authored in.

USD (25.05 and later) records it as ``colorSpace`` metadata on an attribute,
or as ``colorSpace:name`` on a prim with ``ColorSpaceAPI`` applied, inherited
down namespace; untagged colours are linear Rec.709. UsdUVTexture shaders say
it with ``inputs:sourceColorSpace`` (``raw`` | ``sRGB`` | ``auto``).
"""
from __future__ import annotations

from typing import Any

from .config import DEFAULT_USD_COLORSPACE

__all__ = ["authored_colorspace", "texture_colorspace"]


def authored_colorspace(obj: Any, cache: Any = None,
                        default: str = DEFAULT_USD_COLORSPACE) -> str:
    """The colour-space name authored for an attribute, shader input or prim.

    ``obj``: a ``Usd.Attribute``, a ``UsdShade.Input``/``Output`` (anything
    with ``GetAttr``) or a ``Usd.Prim``. An attribute's own ``colorSpace``
    metadata wins, else the nearest ``ColorSpaceAPI`` up namespace, else
    ``default`` (linear Rec.709, USD's rule for untagged colours). ``cache``:
    a ``Usd.ColorSpaceCache`` to share between many calls on one stage.
    Returns the name as authored; resolve it with
    :meth:`cmlt.color.ColorConfig.resolve`.
    """
    from pxr import Usd

    if hasattr(obj, "GetAttr") and not isinstance(obj, (Usd.Attribute, Usd.Prim)):
        obj = obj.GetAttr()
    if isinstance(obj, Usd.Attribute) and obj.HasColorSpace():
        name = obj.GetColorSpace()
        if name:
            return str(name)
    if cache is None:
        cache = Usd.ColorSpaceCache()
    try:
        name = Usd.ColorSpaceAPI.ComputeColorSpaceName(obj, cache)
    except Exception:   # very old usd-core, or an invalid object
        name = ""
    return str(name) if name else default


def texture_colorspace(shader: Any, cache: Any = None) -> str:
    """The colour space of a UsdUVTexture's texels, as a token for
    :meth:`~cmlt.color.ColorConfig.resolve` (which needs the bit depth for
    ``auto``).

    An authored ``inputs:sourceColorSpace`` other than ``auto`` wins, then
    ``colorSpace`` metadata on ``inputs:file``, then ``auto``.
    """
    prim = shader.GetPrim() if hasattr(shader, "GetPrim") else shader
    src = prim.GetAttribute("inputs:sourceColorSpace")
    if src and src.HasAuthoredValue():
        token = str(src.Get() or "auto")
        if token.lower() != "auto":
            return token
    file_attr = prim.GetAttribute("inputs:file")
    if file_attr and file_attr.HasColorSpace() and file_attr.GetColorSpace():
        return str(file_attr.GetColorSpace())
    return "auto"
