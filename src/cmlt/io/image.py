"""Reading and writing images through OpenImageIO: pixels and header, their RGB,
and the atomic write every image file of cmlt goes through.

One rule picks the colour of an image, for the metrics and the contact sheet
alike: the channels named ``R``, ``G``, ``B``; else a luminance channel ``Y``
or a single channel, repeated into grey; else the first three channels when
they carry no names (``channel0``...); else the image has no colour and is an
:class:`ImageReadError` naming its channels. Other channels (alpha, AOVs,
layers of a multi-channel EXR) are ignored.
"""
from __future__ import annotations

import os
from typing import Any, Dict, List, Tuple

import numpy as np

from .atomic import atomic_path

__all__ = ["ImageReadError", "read_error_reason", "read_image", "read_rgb", "rgb_channels", "header", "write_image"]


class ImageReadError(OSError):
    """An image that cannot be read, or has no colour channels; names the file."""


def read_error_reason(path: str, raw: str) -> str:
    """One short line from OpenImageIO's error text for ``path``. OpenEXR's
    reader reports a truncated file as several lines (``EXR Error (path):
    EXR_ERR_READ_IO End of file attempting to read header``, then the same
    again and ``... Unable to extract header byte``): keep the first, without
    the repeated path and the error code, and say what it means."""
    import re

    try:
        empty = os.path.getsize(path) == 0
    except OSError:
        empty = False
    if empty:
        return "the file is empty"
    lines = [ln.strip() for ln in str(raw or "").splitlines() if ln.strip()]
    if not lines:
        return "OpenImageIO gave no reason"
    first = re.sub(r"^EXR Error \(.*?\):\s*", "", lines[0])
    code = re.match(r"^(EXR_ERR_\w+)\s*(.*)$", first)
    if code:
        first = code.group(2) or code.group(1)
        if code.group(1) in ("EXR_ERR_READ_IO", "EXR_ERR_FILE_BAD_HEADER",
                             "EXR_ERR_CORRUPT_CHUNK", "EXR_ERR_BAD_CHUNK_LEADER"):
            first = f"truncated or corrupt OpenEXR file ({first[:1].lower() + first[1:]})"
    return first


def read_image(path: str) -> Tuple[np.ndarray, Any]:
    """``(pixels, spec)``: every channel as float32 ``(H, W, C)``, top row
    first, and the OpenImageIO ImageSpec (channel names, header attributes)."""
    import OpenImageIO as oiio

    if not os.path.exists(path):
        raise ImageReadError(f"{path}: no such file")
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise ImageReadError(f"{path}: cannot read: {read_error_reason(path, oiio.geterror())}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if pixels is None:
            raise ImageReadError(f"{path}: cannot read pixels: "
                                 f"{read_error_reason(path, inp.geterror())}")
    finally:
        inp.close()
    img = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    return img, spec


def rgb_channels(names: List[str]) -> List[int]:
    """Indices of the channels that make the colour (module rule), three of
    them (a grey channel repeated); ValueError if there are none."""
    if all(c in names for c in ("R", "G", "B")):
        return [names.index("R"), names.index("G"), names.index("B")]
    if "Y" in names:
        return [names.index("Y")] * 3
    if len(names) == 1:
        return [0, 0, 0]
    if len(names) >= 3 and all(n in ("", None) or n.startswith("channel") for n in names[:3]):
        return [0, 1, 2]
    raise ValueError(f"no R, G, B channels (channels: {', '.join(names)})")


def read_rgb(path: str, dtype=np.float32) -> Tuple[np.ndarray, Any]:
    """``(rgb, spec)``: the colour of an image (module rule) as ``(H, W, 3)``
    of ``dtype``, and its ImageSpec. Values are as stored (non-finite ones
    included: the caller decides)."""
    img, spec = read_image(path)
    try:
        idx = rgb_channels(list(spec.channelnames))
    except ValueError as exc:
        raise ImageReadError(f"{path}: {exc}") from None
    return np.ascontiguousarray(img[:, :, idx], dtype=dtype), spec


def header(spec) -> Dict[str, Any]:
    """The header attributes of an ImageSpec by name."""
    return {a.name: a.value for a in spec.extra_attribs}


def write_image(path: str, spec, pixels: np.ndarray, what: str, error=OSError) -> None:
    """Write ``pixels`` with ``spec`` to ``path`` atomically (a temporary name, then
    renamed: a half-written file never replaces a good one). Failures raise
    ``error`` with ``what`` (e.g. the path) at the start of the message."""
    import OpenImageIO as oiio

    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(tmp)
        if out is None:
            raise error(f"{what}: OpenImageIO has no writer: {oiio.geterror()}")
        try:
            if not out.open(tmp, spec):
                raise error(f"{what}: cannot open for writing: {out.geterror()}")
            if not out.write_image(pixels):
                raise error(f"{what}: write failed: {out.geterror()}")
        finally:
            ok = out.close()
        if not ok:
            raise error(f"{what}: close failed: {out.geterror()}")
