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

__all__ = ["to_rendering_space", "source_colorspace", "load_texture", "texture_wrap_metadata",
           "WRAP_TOKENS"]


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
    the rendering space: float32 (H, W, C), row 0 at the top; alpha (the 4th
    channel of RGBA, the 2nd of luminance + alpha) is never converted.

    ``source_colorspace`` is ``UsdUVTexture.inputs:sourceColorSpace`` (or a
    colour-space name); ``raw`` leaves the values alone. ``auto`` follows the
    UsdPreviewSurface spec: sRGB for 8-bit (or fewer) files with 3 or 4
    channels, otherwise the values as read (so an 8-bit 1-channel roughness
    map stays linear; a 16-bit/half/float RGB file is linear Rec.709).

    1- and 2-channel (luminance) textures with a colour space (``sRGB`` or
    any named one) are converted too: the luminance L stands for the grey
    (L, L, L) (UsdUVTexture repeats it into r, g, b), which is converted to
    ACEScg and stored back as one channel, its ACEScg luminance (a grey stays
    grey under the conversion, so nothing is lost; the sRGB curve is
    undone).

    ``path`` may lie inside a ``.usdz`` package (``pkg.usdz[tex.png]``): it is
    read through USD's asset resolver (:func:`cmlt.usd.assets.local_path`).
    """
    import OpenImageIO as oiio
    from ..color import get_config
    from .assets import local_path

    inp = oiio.ImageInput.open(local_path(path))
    if inp is None:
        from ..io.image import read_error_reason
        raise OSError(f"texture {path}: cannot read: {read_error_reason(path, oiio.geterror())}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(oiio.FLOAT)
        if pixels is None:
            from ..io.image import read_error_reason
            raise OSError(f"texture {path}: cannot read pixels: "
                          f"{read_error_reason(path, inp.geterror())}")
        bits = str(spec.format)          # "uint8", "uint16", "half", "float"
    finally:
        inp.close()
    img = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    token = (source_colorspace or "auto").strip() if isinstance(source_colorspace, str) \
        else source_colorspace
    if spec.nchannels < 3 and str(token or "auto").lower() == "auto":
        return np.ascontiguousarray(img)           # spec: auto is sRGB only for 3/4 channels
    cfg = get_config()
    src = cfg.resolve(source_colorspace, bit_depth=bits, prim=prim if prim is not None else path)
    if src is None:
        return np.ascontiguousarray(img)           # raw / data
    dst = cfg.rendering_space
    out = img.copy()
    if spec.nchannels < 3:
        grey = np.repeat(np.ascontiguousarray(img[..., :1]), 3, axis=2)
        acescg = np.asarray(cfg.convert(grey, src, dst), dtype=np.float32)
        out[..., 0] = (acescg.astype(np.float64) @ np.asarray(cfg.luminance_weights)) \
            .astype(np.float32)
        return out
    rgb = np.ascontiguousarray(img[..., :3])
    out[..., :3] = np.asarray(cfg.convert(rgb, src, dst), dtype=np.float32)
    return out


#: OpenImageIO's ``wrapmodes`` names -> UsdUVTexture wrap tokens
_OIIO_WRAP = {"black": "black", "clamp": "clamp", "periodic": "repeat", "repeat": "repeat",
              "mirror": "mirror"}
WRAP_TOKENS = ("black", "clamp", "repeat", "mirror")


def texture_wrap_metadata(path: str) -> Tuple[Optional[str], Optional[str]]:
    """The wrap modes a texture file declares, as UsdUVTexture tokens
    (``black``, ``clamp``, ``repeat``, ``mirror``), for ``wrapS``/``wrapT``
    = ``useMetadata``: string attributes ``wrapS`` / ``wrapT`` (the
    UsdPreviewSurface spec's names), else OpenImageIO's ``wrapmodes``
    (``"periodic,clamp"``: TIFF/.tx and OpenEXR files made by maketx or
    txmake). (None, None) when the file says nothing or cannot be read; a
    value that is not a wrap mode is None too. A path inside a ``.usdz``
    package is read through the asset resolver."""
    import OpenImageIO as oiio
    from .assets import AssetError, local_path

    try:
        path = local_path(path)
    except AssetError:
        return None, None
    inp = oiio.ImageInput.open(path)
    if inp is None:
        oiio.geterror()
        return None, None
    try:
        spec = inp.spec()
    finally:
        inp.close()

    def token(value) -> Optional[str]:
        return _OIIO_WRAP.get(str(value).strip().lower()) if value else None

    s = token(spec.getattribute("wrapS") or spec.getattribute("oiio:wrapS"))
    t = token(spec.getattribute("wrapT") or spec.getattribute("oiio:wrapT"))
    modes = spec.getattribute("wrapmodes")
    if modes and (s is None or t is None):
        parts = [p for p in str(modes).split(",") if p.strip()]
        if parts:
            s = s or token(parts[0])
            t = t or token(parts[1] if len(parts) > 1 else parts[0])
    return s, t
