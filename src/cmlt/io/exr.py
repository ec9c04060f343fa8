"""Scene-linear RGB OpenEXR frames through OpenImageIO.

* pixel type ``float`` (32-bit, default) or ``half`` (``--half``); half holds
  magnitudes up to :data:`HALF_MAX` (65504), beyond which it has only Inf: a
  value above it (a bright light seen directly) is clamped to it, and
  :func:`write_exr` returns how many were, so the caller can warn;
* compression ``zip`` (default, lossless), ``piz`` (lossless), ``dwaa``
  (lossy, small) or ``none``;
* the colour space goes into ``oiio:ColorSpace`` (OIIO stores ``ACEScg`` as
  ``lin_ap1_scene`` plus the EXR ``colorInteropID``);
* frame metadata goes into custom header attributes named ``cmlt:<key>``;
* AOVs are extra channels of the same part with the standard names Nuke and
  OpenImageIO tools know (``albedo.R/G/B``, ``N.X/Y/Z``, ``Z``,
  ``variance.R/G/B``); with ``half`` every channel is half except ``Z``,
  which stays float (depth needs the precision);
* ``crop`` (x0, y0, x1, y1), half-open (x0 <= x < x1): only that window's
  pixels are stored; the data window is the crop, the display window the
  full frame, as compositors expect of a region render.

The image is checked for NaN/Inf before anything is written: the core
guarantees finite pixels, and a non-finite one is a bug to report, not to
paint over (no ``nan_to_num``). Files are written to a temporary sibling and
renamed into place (:mod:`cmlt.io.atomic`).
"""
from __future__ import annotations

from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

import numpy as np

from .image import write_image

__all__ = ["COMPRESSIONS", "HALF_MAX", "AOV_CHANNELS", "ExrWriteError", "NonFiniteImageError", "write_exr",
           "read_exr", "check_crop", "read_header", "format_header"]

COMPRESSIONS = ("zip", "piz", "dwaa", "none")
#: the largest finite half-float
HALF_MAX = 65504.0
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
        # OIIO's int attribute is 32 bits; a larger count or seed goes in as its
        # decimal text (the binding raises on it otherwise)
        v = int(value)
        spec.attribute(name, v if -2 ** 31 <= v < 2 ** 31 else str(v))
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


#: AOV name -> (layer prefix, channel suffixes); ``None``: a single channel named prefix
AOV_CHANNELS = {
    "albedo": ("albedo", ("R", "G", "B")),
    "normal": ("N", ("X", "Y", "Z")),
    "depth": ("Z", None),
    "variance": ("variance", ("R", "G", "B")),
    "error": ("relMSE", None),          # per-pixel relMSE estimate (cmlt.metrics.error_estimate)
}
#: channels written as float even with ``half``
FLOAT_ONLY_CHANNELS = ("Z",)


def check_crop(crop, width: int, height: int, flag: str = "--crop") -> Tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` -> ints, checked against the frame (half-open
    window, 0 <= x0 < x1 <= width, 0 <= y0 < y1 <= height); ValueError names
    ``flag``."""
    try:
        x0, y0, x1, y1 = (int(v) for v in crop)
    except (TypeError, ValueError):
        raise ValueError(f"{flag} {crop!r}: expected x0,y0,x1,y1") from None
    if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
        raise ValueError(f"{flag} {x0},{y0},{x1},{y1}: the window must satisfy 0 <= x0 < x1 <= "
                         f"{width} and 0 <= y0 < y1 <= {height} (the {width}x{height} frame; "
                         f"x1 and y1 are exclusive)")
    return x0, y0, x1, y1


def write_exr(path: str, image: np.ndarray, *, half: bool = False,
              compression: str = "zip", colorspace: Optional[str] = "ACEScg",
              metadata: Optional[Mapping[str, Any]] = None,
              attributes: Optional[Mapping[str, Any]] = None,
              aovs: Optional[Mapping[str, np.ndarray]] = None,
              crop: Optional[Sequence[int]] = None,
              layers: Optional[Mapping[str, Tuple[str, Optional[Sequence[str]]]]] = None,
              half_channels: Sequence[str] = ()) -> Tuple[int, float]:
    """Write ``image`` (H, W, 3) float, top row first, to ``path`` atomically.
    Returns ``(clamped, peak)``: with ``half``, how many stored values exceeded
    :data:`HALF_MAX` in magnitude and were clamped to it, and the largest
    magnitude among them (``(0, 0.0)`` otherwise).

    ``metadata`` keys are written as ``cmlt:<key>`` unless they already
    contain a ``:`` (then as given, e.g. ``oiio:Software``). ``attributes``
    are written under their own names, after ``colorspace`` (so
    :func:`cmlt.color.header_attributes` output can be passed straight in:
    ``oiio:ColorSpace`` and ``chromaticities``). ``aovs`` maps names of
    :data:`AOV_CHANNELS` to (H, W, 3) or (H, W) arrays the size of
    ``image``, written as extra channels. ``crop`` keeps only that window of
    every channel (data window) inside the full frame (display window).
    ``layers`` names the channels of ``aovs`` keys that are no AOV name
    (``key -> (prefix, suffixes)``, as in :data:`AOV_CHANNELS`: a render
    product's layers); ``half_channels`` are stored as half even without
    ``half``.
    """
    import OpenImageIO as oiio

    if compression not in COMPRESSIONS:
        raise ValueError(f"--compression {compression!r}: choose one of {', '.join(COMPRESSIONS)}")
    img = _check_image(image, path)
    h, w, nch = img.shape
    names = list({1: ("Y",), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}[nch])
    planes = [img]
    for name, data in (aovs or {}).items():
        layout = (layers or {}).get(name) or AOV_CHANNELS.get(name)
        if layout is None:
            raise ValueError(f"{path}: unknown AOV {name!r}; known: {', '.join(AOV_CHANNELS)}")
        prefix, suffixes = layout
        arr = _check_image(data, f"{path} (AOV {name})")
        want = 1 if suffixes is None else len(suffixes)
        if arr.shape != (h, w, want):
            raise ValueError(f"{path}: AOV {name} has shape {np.shape(data)}, expected "
                             f"({h}, {w}{'' if want == 1 else f', {want}'})")
        planes.append(arr)
        names += [prefix] if suffixes is None else [f"{prefix}.{c}" for c in suffixes]
    pixels = np.ascontiguousarray(np.concatenate(planes, axis=2)) if len(planes) > 1 else img
    x0, y0 = 0, 0
    if crop is not None:
        x0, y0, x1, y1 = check_crop(crop, w, h)
        pixels = np.ascontiguousarray(pixels[y0:y1, x0:x1])
    ph, pw, ptot = pixels.shape
    clamped, peak = 0, 0.0
    as_half = [(half and n not in FLOAT_ONLY_CHANNELS) or n in half_channels for n in names]
    if any(as_half):
        # half has no finite value above HALF_MAX: clamp rather than store Inf
        chans = [i for i, h16 in enumerate(as_half) if h16]
        over = np.abs(pixels[:, :, chans]) > HALF_MAX
        if over.any():
            clamped = int(over.sum())
            peak = float(np.abs(pixels[:, :, chans])[over].max())
            pixels = pixels.copy()             # never the caller's array
            pixels[:, :, chans] = np.clip(pixels[:, :, chans], -HALF_MAX, HALF_MAX)

    spec = oiio.ImageSpec(pw, ph, ptot, oiio.HALF if half or all(as_half) else oiio.FLOAT)
    spec.x, spec.y = x0, y0
    spec.full_x, spec.full_y, spec.full_width, spec.full_height = 0, 0, w, h
    spec.channelnames = tuple(names)
    if len(set(as_half)) > 1:
        spec.channelformats = tuple(oiio.TypeDesc(oiio.HALF if h16 else oiio.FLOAT)
                                    for h16 in as_half)
    if nch == 4:
        spec.alpha_channel = 3
    if "Z" in names:
        spec.z_channel = names.index("Z")
    spec.attribute("compression", compression)
    if colorspace:
        spec.attribute("oiio:ColorSpace", colorspace)
    for key, value in (metadata or {}).items():
        _set_attribute(spec, key if ":" in key else META_PREFIX + key, value)
    for key, value in (attributes or {}).items():
        _set_raw_attribute(spec, key, value)

    write_image(path, spec, pixels, path, error=ExrWriteError)
    return clamped, peak


def read_exr(path: str) -> Tuple[np.ndarray, Dict[str, Any]]:
    """Read an image as float32 (H, W, C) plus all header attributes
    (:func:`cmlt.io.image.read_image`), ``channelnames`` and ``format``."""
    from .image import header, read_image

    img, spec = read_image(path)
    meta = header(spec)
    meta["channelnames"] = tuple(spec.channelnames)
    meta["format"] = str(spec.format)
    return img, meta


def read_header(path: str) -> Dict[str, Any]:
    """The header of an image (no pixels): ``channels`` [(name, type)],
    ``data_window`` / ``display_window`` as (x0, y0, x1, y1) half-open,
    ``compression``, ``colorspace`` (``oiio:ColorSpace``), ``chromaticities``,
    ``cmlt`` (the ``cmlt:*`` attributes without prefix) and ``attributes``
    (every other one). Raises OSError naming the path."""
    import OpenImageIO as oiio

    from .image import read_error_reason

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(f"{path}: cannot read: {read_error_reason(path, oiio.geterror())}")
    try:
        spec = inp.spec()
        nparts = 1
        while inp.seek_subimage(nparts, 0):
            nparts += 1
    finally:
        inp.close()
    formats = list(spec.channelformats) or [spec.format] * spec.nchannels
    attrs = {a.name: a.value for a in spec.extra_attribs}
    cmlt_meta = {k[len(META_PREFIX):]: v for k, v in attrs.items() if k.startswith(META_PREFIX)}
    other = {k: v for k, v in attrs.items() if not k.startswith(META_PREFIX)}
    return {
        "path": path,
        "parts": nparts,
        "channels": [(n, str(f)) for n, f in zip(spec.channelnames, formats)],
        "data_window": (spec.x, spec.y, spec.x + spec.width, spec.y + spec.height),
        "display_window": (spec.full_x, spec.full_y, spec.full_x + spec.full_width,
                           spec.full_y + spec.full_height),
        "compression": str(other.get("compression", "")),
        "colorspace": str(other.get("oiio:ColorSpace", "")),
        "chromaticities": (tuple(float(c) for c in other["chromaticities"])
                           if "chromaticities" in other else None),
        "cmlt": cmlt_meta,
        "attributes": other,
    }


def _show(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(_show(v) for v in value) + ")"
    return str(value)


def format_header(header: Mapping[str, Any]) -> str:
    """Text for ``cmlt inspect --image``: channels, windows, colour space,
    compression, cmlt metadata, then the remaining attributes."""
    def window(w):
        x0, y0, x1, y1 = w
        return f"({x0}, {y0}) - ({x1 - 1}, {y1 - 1})  [{x1 - x0} x {y1 - y0}]"

    chans = header["channels"]
    lines = [f"image: {header['path']}",
             f"channels ({len(chans)}): " + ", ".join(f"{n} ({t})" for n, t in chans),
             f"data window:    {window(header['data_window'])}",
             f"display window: {window(header['display_window'])}",
             f"colour space: {header['colorspace'] or '(not tagged)'}",
             "chromaticities: " + (_show(header["chromaticities"])
                                   if header["chromaticities"] else "(none)"),
             f"compression: {header['compression'] or '-'}"]
    if header["cmlt"]:
        lines.append("cmlt metadata:")
        width = max(len(k) for k in header["cmlt"])
        for k in sorted(header["cmlt"]):
            lines.append(f"  {k:<{width}}  {_show(header['cmlt'][k])}")
    skip = {"compression", "oiio:ColorSpace", "chromaticities"}
    rest = {k: v for k, v in header["attributes"].items() if k not in skip}
    if rest:
        lines.append("other attributes:")
        width = max(len(k) for k in rest)
        for k in sorted(rest):
            lines.append(f"  {k:<{width}}  {_show(rest[k])}")
    return "\n".join(lines) + "\n"
