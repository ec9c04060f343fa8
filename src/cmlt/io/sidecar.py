"""Per-frame statistics sidecars.

Beside every image ``cornell.0001.exr`` the frame loop writes
``cornell.0001.exr.json`` (image name + ``.json``: unambiguous for any
extension, and it sorts next to its image). The file is one JSON object:

``format``        ``"cmlt-frame-stats"``, ``version`` (int)
``image``         image file name (relative to the sidecar)
``shot``, ``frame``, ``time_code``, ``camera``, ``resolution``
``settings``      integrator, spp, max_depth, seed, threads, half, compression
``stats``         the core's ``RenderResult.stats`` passed through as is
                  (time_s, samples, rays, rays_per_s, ...; later acceptance
                  rates and normalisation), plus ``wall_time_s`` of the frame
``warnings``      loader warnings for this frame
``cmlt_version``
``core_isa``      the build of the core that rendered it (``cmlt._core.isa``: ``x86-64``,
                  the portable one, or an x86-64 level such as ``x86-64-v4``)

A number that does not exist for the frame (NaN, e.g. ``temporal.b_ratio``
of a frame without carried chain states) or is infinite is written as
``null``, never as a string.

Written atomically, like the image.
"""
from __future__ import annotations

import json
import math
from typing import Any, Dict, Mapping

import numpy as np

from .atomic import atomic_write_text

__all__ = ["SIDECAR_FORMAT", "SIDECAR_VERSION", "sidecar_path", "sidecar_text", "write_sidecar",
           "read_sidecar"]

SIDECAR_FORMAT = "cmlt-frame-stats"
SIDECAR_VERSION = 1


def sidecar_path(image_path: str) -> str:
    return image_path + ".json"


def _plain(value: Any) -> Any:
    """JSON-safe copy: numpy scalars/arrays to Python, non-finite floats
    (NaN: an estimate that does not exist for the frame, such as ``b_ratio``
    without carried states; ±Inf) to ``None``, i.e. JSON ``null``."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None         # strict JSON has no NaN/Infinity
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def sidecar_text(record: Mapping[str, Any]) -> str:
    """The sidecar file's text for ``record`` (format and version first)."""
    doc: Dict[str, Any] = {"format": SIDECAR_FORMAT, "version": SIDECAR_VERSION}
    doc.update(_plain(dict(record)))
    return json.dumps(doc, indent=2, sort_keys=False, allow_nan=False) + "\n"


def write_sidecar(image_path: str, record: Mapping[str, Any], *, to: str = None) -> str:
    """Write ``record`` as the sidecar of ``image_path`` (atomically); returns its
    path. ``to``: write it there instead (a temporary the caller renames)."""
    path = to or sidecar_path(image_path)
    atomic_write_text(path, sidecar_text(record))
    return path


def read_sidecar(image_path: str) -> Dict[str, Any]:
    with open(sidecar_path(image_path), encoding="utf-8") as fh:
        return json.load(fh)
