"""Scene-linear RGB OpenEXR frames through OpenImageIO.

* pixel type ``float`` (32-bit, default) or ``half`` (``--half``);
* compression ``zip`` (default, lossless), ``piz`` (lossless), ``dwaa``
  (lossy, small) or ``none``;
* the colour space goes into ``oiio:ColorSpace`` (OIIO stores ``ACEScg`` as
  ``lin_ap1_scene`` plus the EXR ``colorInteropID``);
* frame metadata goes into custom header attributes named ``cmlt:<key>``.

The image is checked for NaN/Inf before anything is written: the core
guarantees finite pixels, and a non-finite one is a bug to report, not to
paint over (no ``nan_to_num``). Files are written to a temporary sibling and
renamed into place (:mod:`cmlt.io.atomic`).
"""
from __future__ import annotations

from typing import Any, Dict, Mapping, Optional, Tuple

import numpy as np

from .atomic import atomic_path

__all__ = ["COMPRESSIONS", "ExrWriteError", "NonFiniteImageError", "write_exr", "read_exr"]

COMPRESSIONS = ("zip", "piz", "dwaa", "none")
#: prefix of cmlt's own header attributes
META_PREFIX = "cmlt:"


class ExrWriteError(RuntimeError):
    """OpenImageIO could not write the file (message names the path)."""


class NonFiniteImageError(ValueError):
    """The image holds NaN or Inf; nothing was written."""


def _check_image(image: np.ndarray, path: str) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.ndim != 3 or img.shape[2] not in (1, 3, 4) or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"{path}: image must be (H, W, 1|3|4), got shape {np.shape(image)}")
    img = np.ascontiguousarray(img, dtype=np.float32)
    bad = ~np.isfinite(img)
    if bad.any():
        y, x, c = (int(v) for v in np.argwhere(bad)[0])
        raise NonFiniteImageError(
            f"{path}: {int(bad.sum())} non-finite pixel values "
            f"(first at x={x}, y={y}, channel {c}: {img[y, x, c]}); not written")
    return img


def _set_attribute(spec, name: str, value: Any) -> None:
    import OpenImageIO as oiio

    if isinstance(value, bool):
        spec.attribute(name, int(value))
    elif isinstance(value, (int, np.integer)):
        spec.attribute(name, int(value))
    elif isinstance(value, (float, np.floating)):
        # float32: OIIO's Python binding silently drops double attributes
        # (checked with OIIO 3.2); exact values live in the JSON sidecar
        spec.attribute(name, float(value))
    elif isinstance(value, str):
        spec.attribute(name, value)
    elif value is None:
        return
    else:
        # lists, dicts: as text, since OIIO drops some tuple types silently
        import json
        spec.attribute(name, json.dumps(value, sort_keys=True, default=str))


def _set_raw_attribute(spec, name: str, value: Any) -> None:
    """A standard header attribute; a list of numbers becomes a float array
    (e.g. ``chromaticities``: 8 floats), since OIIO's Python binding drops
    some tuple types silently."""
    import OpenImageIO as oiio

    if isinstance(value, (list, tuple, np.ndarray)):
        arr = [float(v) for v in np.asarray(value, dtype=np.float64).ravel()]
        spec.attribute(name, oiio.TypeDesc(f"float[{len(arr)}]"), arr)
    else:
        _set_attribute(spec, name, value)


def write_exr(path: str, image: np.ndarray, *, half: bool = False,
              compression: str = "zip", colorspace: Optional[str] = "ACEScg",
              metadata: Optional[Mapping[str, Any]] = None,
              attributes: Optional[Mapping[str, Any]] = None) -> None:
    """Write ``image`` (H, W, 3) float, top row first, to ``path`` atomically.

    ``metadata`` keys are written as ``cmlt:<key>`` unless they already
    contain a ``:`` (then as given, e.g. ``oiio:Software``). ``attributes``
    are written under their own names, after ``colorspace`` (so
    :func:`cmlt.color.header_attributes` output can be passed straight in:
    ``oiio:ColorSpace`` and ``chromaticities``).
    """
    import OpenImageIO as oiio

    if compression not in COMPRESSIONS:
        raise ValueError(f"--compression {compression!r}: choose one of {', '.join(COMPRESSIONS)}")
    img = _check_image(image, path)
    h, w, nch = img.shape
    spec = oiio.ImageSpec(w, h, nch, oiio.HALF if half else oiio.FLOAT)
    spec.channelnames = {1: ("Y",), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}[nch]
    if nch == 4:
        spec.alpha_channel = 3
    spec.attribute("compression", compression)
    if colorspace:
        spec.attribute("oiio:ColorSpace", colorspace)
    for key, value in (metadata or {}).items():
        _set_attribute(spec, key if ":" in key else META_PREFIX + key, value)
    for key, value in (attributes or {}).items():
        _set_raw_attribute(spec, key, value)

    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(tmp)
        if out is None:
            raise ExrWriteError(f"{path}: no EXR writer: {oiio.geterror()}")
        try:
            if not out.open(tmp, spec):
                raise ExrWriteError(f"{path}: cannot open for writing: {out.geterror()}")
            if not out.write_image(img):
                raise ExrWriteError(f"{path}: write failed: {out.geterror()}")
        finally:
            ok = out.close()
        if not ok:
            raise ExrWriteError(f"{path}: close failed: {out.geterror()}")


def read_exr(path: str) -> Tuple[np.ndarray, Dict[str, Any]]:
    """Read an image as float32 (H, W, C) plus all header attributes."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(f"{path}: cannot read: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(oiio.FLOAT)
        if pixels is None:
            raise OSError(f"{path}: cannot read pixels: {inp.geterror()}")
        meta = {a.name: a.value for a in spec.extra_attribs}
        meta["channelnames"] = tuple(spec.channelnames)
        meta["format"] = str(spec.format)
    finally:
        inp.close()
    img = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    return img, meta
