"""Display-referred previews of scene-linear frames (PNG / JPEG).

A frame is ACEScg; a preview is that frame through an OpenColorIO
display/view (default "sRGB - Display" and the config's default view, an ACES
output transform), quantised to 8 bits and written with OpenImageIO to a
temporary name that is then renamed into place.
"""
from __future__ import annotations

import os
from typing import Any, Dict, Optional

import numpy as np
import OpenImageIO as oiio

from ..color import ColorConfig, get_config
from .image import write_image

__all__ = ["write_preview", "write_display_image", "display_attributes", "display_colorspace",
           "display_colorspace_tag", "PREVIEW_EXTENSIONS"]

PREVIEW_EXTENSIONS = (".png", ".jpg", ".jpeg")


def _as_rgb(image) -> np.ndarray:
    """(H, W), (H, W, 1), (H, W, 3) or (H, W, 4) -> float32 (H, W, 3|4)."""
    arr = np.asarray(image, dtype=np.float32)
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4) or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"preview: expected an image of shape (H, W[, 1|3|4]), got {arr.shape}")
    if arr.shape[2] == 1:
        arr = np.repeat(arr, 3, axis=2)
    return arr


def _check_extension(path: str) -> str:
    ext = os.path.splitext(path)[1].lower()
    if ext not in PREVIEW_EXTENSIONS:
        raise ValueError(f"preview '{path}': the extension must be one of "
                         f"{', '.join(PREVIEW_EXTENSIONS)}")
    return ext


def write_display_image(pixels: np.ndarray, path: str,
                        attributes: Optional[Dict[str, Any]] = None,
                        jpeg_quality: int = 92) -> str:
    """Write display-referred uint8 pixels (H, W, 3|4) as PNG or JPEG,
    atomically (temporary name + ``os.replace``). Returns ``path``."""
    ext = _check_extension(path)
    pix = np.ascontiguousarray(pixels, dtype=np.uint8)
    if ext in (".jpg", ".jpeg") and pix.shape[2] == 4:
        pix = np.ascontiguousarray(pix[..., :3])          # JPEG has no alpha
    h, w, c = pix.shape
    spec = oiio.ImageSpec(w, h, c, oiio.UINT8)
    if c == 4:
        spec.alpha_channel = 3
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)
    if ext in (".jpg", ".jpeg"):
        spec.attribute("Compression", f"jpeg:{int(jpeg_quality)}")
    write_image(path, spec, pix, f"preview '{path}'")
    return path


#: OCIO's placeholder in a (shared) view: the view's colour space is the one named
#: like the display
USE_DISPLAY_NAME = "<USE_DISPLAY_NAME>"


def display_colorspace(config: ColorConfig, display: str, view: str):
    """The OCIO colour space a display/view writes (the display's colour
    space, e.g. ``sRGB - Display``), or ``None`` if the config does not
    name one. ACES configs define their views once, shared by every
    display, with the colour space ``<USE_DISPLAY_NAME>``: that is the
    colour space named like the display."""
    name = config.ocio.getDisplayViewColorSpaceName(display, view) or ""
    if name == USE_DISPLAY_NAME:
        name = display
    return config.ocio.getColorSpace(name) if name else None


def display_colorspace_tag(config: ColorConfig, display: str, view: str) -> str:
    """``oiio:ColorSpace`` of a preview: the Color Interop ID of the display's
    colour space (``srgb_rec709_display`` for ``sRGB - Display``), else one of
    its aliases that is an interop ID (``*_display``), else its OCIO name;
    '' if the display has no colour space."""
    cs = display_colorspace(config, display, view)
    if cs is None:
        return ""
    interop = cs.getInteropID() if hasattr(cs, "getInteropID") else ""
    if interop:
        return interop
    for alias in cs.getAliases():
        if alias.lower().endswith("_display"):
            return alias
    return cs.getName()


def display_attributes(config: ColorConfig, display: str, view: str) -> Dict[str, Any]:
    """Header attributes saying how a preview was made, and that it is
    display-referred: ``oiio:ColorSpace`` is the display's colour space
    (:func:`display_colorspace_tag`). OpenImageIO 3 stores it in the file as
    PNG ``sRGB``/``gAMA``/``cICP`` chunks or the JPEG Exif colour space, and
    reads it back as the same encoding and primaries (it names sRGB-encoded
    files ``srgb_rec709_scene`` on input: its own convention for 8-bit
    sRGB, whatever the file says)."""
    attrs: Dict[str, Any] = {
        "ImageDescription": f"cmlt preview: OCIO display '{display}', view '{view}', "
                            f"config '{config.name}'",
        "Software": "cmlt",
    }
    tag = display_colorspace_tag(config, display, view)
    if tag:
        attrs["oiio:ColorSpace"] = tag
    return attrs


def write_preview(image_acescg, path: str, display: Optional[str] = None,
                  view: Optional[str] = None, *, config: Optional[ColorConfig] = None,
                  jpeg_quality: int = 92) -> str:
    """Write an ACEScg image as a display-referred PNG or JPEG (by extension).

    ``display``/``view`` default to "sRGB - Display" (else the config's
    default display) and that display's default view. Alpha (RGBA input) is
    kept in PNGs and dropped from JPEGs. Returns ``path``.
    """
    _check_extension(path)
    cfg = config or get_config()
    display, view = cfg.check_display_view(display, view)
    rgb = _as_rgb(image_acescg)
    pixels = cfg.display_transform(rgb, display, view, dtype=np.uint8)
    return write_display_image(pixels, path, display_attributes(cfg, display, view),
                               jpeg_quality=jpeg_quality)
