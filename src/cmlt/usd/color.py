"""Colour entry point of the stage reader.

Every colour the reader takes from a stage (material inputs, light colours,
displayColor, texture fallbacks) goes through :func:`to_rendering_space`, and
every texture's texels through :func:`load_texture`, so colour management has
exactly one place to hook in. Both convert from the authored colour space to
the rendering space, ACEScg, with the process-wide OpenColorIO config
(:func:`cmlt.color.get_config`; the CLI installs ``--ocio-config`` / ``$OCIO``
/ the stage's ``colorConfiguration`` before loading). Conversion happens once,
when a frame is loaded, never per sample.

Which colour space a value is in (``cmlt.color.authored_colorspace``): the
attribute's own ``colorSpace`` metadata, else the nearest ``ColorSpaceAPI``
up namespace, else linear Rec.709 (USD's rule for untagged colours). A
texture's is its ``inputs:sourceColorSpace`` (``raw``, ``sRGB`` or ``auto``:
sRGB for 8-bit files, linear Rec.709 for half/float ones).
"""
from __future__ import annotations

from typing import Any, Optional, Sequence, Tuple

import numpy as np

__all__ = ["to_rendering_space", "source_colorspace", "load_texture"]


def source_colorspace(attr: Any, cache: Any = None) -> str:
    """The colour space ``attr`` (a ``Usd.Attribute``, a ``UsdShade.Input`` or
    a prim) was authored in; see :func:`cmlt.color.authored_colorspace`."""
    from ..color import authored_colorspace

    return authored_colorspace(attr, cache)


def to_rendering_space(rgb: Sequence[float], source_colorspace: Any = None, *,
                       prim: Any = None) -> Tuple[float, float, float]:
    """Convert an authored RGB triple to the rendering space (ACEScg).

    ``source_colorspace``: a colour-space name or USD token (``lin_rec709``,
    ``sRGB``, ``raw``, an OCIO name or interop ID), or the ``Usd.Attribute``
    / ``UsdShade.Input`` the value came from (its authored colour space is
    looked up), or ``None`` (untagged: linear Rec.709). Returns three finite
    Python floats; non-finite input components become 0 so that no NaN
    reaches the scene arrays. An unknown colour-space name raises
    :class:`cmlt.color.ColorError` naming it (and ``prim`` when given).
    """
    from ..color import to_rendering_space as _convert

    a = np.asarray(rgb, dtype=np.float64).reshape(-1)
    if a.size == 1:
        a = np.repeat(a, 3)
    a = a[:3] if a.size >= 3 else np.pad(a, (0, 3 - a.size))
    a = np.where(np.isfinite(a), a, 0.0)
    name = source_colorspace
    if name is not None and not isinstance(name, str):
        if prim is None and hasattr(name, "GetPrim"):
            prim = name.GetPrim()
        name = _source_of(name)
    out = _convert(tuple(float(v) for v in a), name, prim=prim)
    return tuple(float(v) if np.isfinite(v) else 0.0 for v in out)   # type: ignore[return-value]


def _source_of(obj: Any) -> str:
    return source_colorspace(obj)


def load_texture(path: str, source_colorspace: Optional[str] = "auto", *,
                 prim: Any = None) -> np.ndarray:
    """Read a texture file with OpenImageIO and convert its colour channels to
    the rendering space: float32 (H, W, C), row 0 at the top; alpha (a 4th
    channel) and single-channel (scalar) textures are not converted.

    ``source_colorspace`` is ``UsdUVTexture.inputs:sourceColorSpace`` (or a
    colour-space name): ``auto`` resolves by the file's bit depth (8 bits or
    fewer: sRGB; more: linear Rec.709), ``raw`` leaves the values alone.
    """
    import OpenImageIO as oiio
    from ..color import get_config

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(f"texture {path}: cannot read: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(oiio.FLOAT)
        if pixels is None:
            raise OSError(f"texture {path}: cannot read pixels: {inp.geterror()}")
        bits = str(spec.format)          # "uint8", "uint16", "half", "float"
    finally:
        inp.close()
    img = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    if spec.nchannels < 3:
        return np.ascontiguousarray(img)
    cfg = get_config()
    src = cfg.resolve(source_colorspace, bit_depth=bits, prim=prim if prim is not None else path)
    rgb = np.ascontiguousarray(img[..., :3])
    rgb = np.asarray(cfg.convert(rgb, src, cfg.rendering_space if src is not None else None),
                     dtype=np.float32)
    out = img.copy()
    out[..., :3] = rgb
    return out
