"""Checks of a sequence's outputs before the first frame renders.

* :func:`check_output_paths`: every ``--out`` name is an OpenEXR file cmlt can
  create: ``.exr`` (the beauty is scene-linear; a PNG or JPEG of it would be
  8-bit, clipped and not display-transformed: ``--preview`` writes one through
  the OCIO display/view), not an existing directory, below a directory (or a
  path that can become one) that is writable. A UsageError names the flag.
* :func:`finished_frame_problem`: whether an existing frame is really done
  (``--resume``): the EXR opens, reads to its last pixel, is finite, has the
  channels and size this render would write, and its sidecar is a cmlt sidecar
  of that image and frame.
* :func:`remove_stale_temporaries`: the hidden temporaries
  (:mod:`cmlt.io.atomic`) a killed render left in the directories this one
  writes to.
* :func:`chain_memory_problem`: whether the Markov chains a pssmlt/cmlt frame
  starts fit in memory, checked before anything is allocated (``--chains
  100000000`` is refused with the flag's name instead of running out of memory).
"""
from __future__ import annotations

import math
import os
from typing import Iterable, List, Optional, Sequence, Tuple

from .errors import UsageError

__all__ = ["IMAGE_EXTENSIONS", "check_output_paths", "check_state_dir",
           "finished_frame_problem", "remove_stale_temporaries", "available_memory",
           "chain_memory_problem", "CHAIN_BYTES"]

#: the beauty's file extensions
IMAGE_EXTENSIONS = (".exr",)
#: extensions of display-referred formats, pointed to --preview
_DISPLAY_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".gif", ".webp")


def _first_existing(path: str) -> str:
    """``path`` or its nearest ancestor that exists ('.' for a relative path
    none of whose components exists)."""
    p = os.path.abspath(path)
    while not os.path.lexists(p):
        parent = os.path.dirname(p)
        if parent == p:
            break
        p = parent
    return p


def _check_one(pattern: str, path: str) -> None:
    flag = f"--out {pattern}"
    if path.endswith(os.sep) or (os.altsep and path.endswith(os.altsep)):
        raise UsageError(f"{flag}: names a directory; give an image name pattern, e.g. "
                         f"{os.path.join(pattern, 'shot.####.exr')}")
    if os.path.isdir(path):
        raise UsageError(f"{flag}: {path} is a directory; give an image name pattern, e.g. "
                         f"{os.path.join(pattern, 'shot.####.exr')}")
    ext = os.path.splitext(path)[1].lower()
    if ext not in IMAGE_EXTENSIONS:
        if ext in _DISPLAY_EXTENSIONS:
            raise UsageError(
                f"{flag}: the beauty is written as scene-linear OpenEXR only (a {ext} would "
                f"be 8-bit, clipped and without the display transform); name it .exr and add "
                f"--preview (--preview-format png|jpg) for a display-referred image beside "
                f"each frame")
        what = f"unknown extension {ext!r}" if ext else "no file extension"
        raise UsageError(f"{flag}: {what}; the beauty is written as OpenEXR: name it .exr")
    anchor = _first_existing(os.path.dirname(os.path.abspath(path)))
    if not os.path.isdir(anchor):
        raise UsageError(f"{flag}: cannot write into {anchor}: not a directory")
    if not os.access(anchor, os.W_OK | os.X_OK):
        raise UsageError(f"{flag}: cannot write into {anchor} (permission denied)")


def check_output_paths(pattern: str, paths: Sequence[str], preview_paths: Sequence[str] = ()
                       ) -> None:
    """UsageError naming ``--out`` unless every path can be written as an EXR
    (module doc); ``preview_paths`` (``--preview``) must not be directories."""
    for path in dict.fromkeys(paths):
        _check_one(pattern, path)
        if os.path.isdir(path + ".json"):
            raise UsageError(f"--out {pattern}: the sidecar {path}.json is a directory")
    for pv in dict.fromkeys(preview_paths):
        if os.path.isdir(pv):
            raise UsageError(f"--preview: {pv} (the preview of an --out image) is a directory")


def check_state_dir(state_dir: Optional[str]) -> None:
    """UsageError naming ``--state-dir`` if it exists and is not a directory,
    or cannot be created / written."""
    if not state_dir:
        return
    if os.path.lexists(state_dir) and not os.path.isdir(state_dir):
        raise UsageError(f"--state-dir {state_dir}: exists and is not a directory")
    anchor = _first_existing(state_dir)
    if not os.path.isdir(anchor):
        raise UsageError(f"--state-dir {state_dir}: {anchor} is not a directory")
    if not os.access(anchor, os.W_OK | os.X_OK):
        raise UsageError(f"--state-dir {state_dir}: cannot write into {anchor} "
                         "(permission denied)")


def remove_stale_temporaries(directories: Iterable[str]) -> List[str]:
    """:func:`cmlt.io.atomic.remove_stale_temps` in each existing directory
    (each once); returns the paths removed."""
    from ..io.atomic import remove_stale_temps

    removed: List[str] = []
    for d in dict.fromkeys(os.path.abspath(d or ".") for d in directories):
        if os.path.isdir(d):
            removed += remove_stale_temps(d)
    return removed


def finished_frame_problem(path: str, frame: float, *,
                           size: Optional[Tuple[int, int]] = None,
                           channels: Sequence[str] = ("R", "G", "B"),
                           crop: Optional[Sequence[int]] = None) -> Optional[str]:
    """Why the frame at ``path`` is not a finished frame of this render
    (``None``: it is). ``size``: the full frame (display window) expected,
    ``None`` not to check it; ``channels``: names the image must have;
    ``crop``: the data window expected (x0, y0, x1, y1), else the full frame."""
    from ..io.image import ImageReadError, read_image
    from ..io.sidecar import SIDECAR_FORMAT, read_sidecar, sidecar_path

    if not os.path.isfile(path):
        return "no such file"
    if os.path.getsize(path) == 0:
        return "the file is empty"
    try:
        img, spec = read_image(path)
    except ImageReadError as exc:
        why = str(exc)
        return why[len(path) + 2:] if why.startswith(path + ": ") else why
    import numpy as np
    if not np.isfinite(img).all():
        return "it holds non-finite pixel values"
    have = list(spec.channelnames)
    missing = [c for c in channels if c not in have]
    if missing:
        return f"it lacks the channel(s) {', '.join(missing)}"
    full = (spec.full_width, spec.full_height)
    if size is not None and tuple(int(v) for v in size) != full:
        return f"it is {full[0]}x{full[1]}, this render is {size[0]}x{size[1]}"
    window = (spec.x, spec.y, spec.x + spec.width, spec.y + spec.height)
    want = tuple(int(v) for v in crop) if crop is not None else \
        (spec.full_x, spec.full_y, spec.full_x + spec.full_width, spec.full_y + spec.full_height)
    if window != want:
        return (f"its data window is {window}, this render writes {want}")
    side = sidecar_path(path)
    if not os.path.isfile(side):
        return f"its sidecar {os.path.basename(side)} is missing"
    try:
        doc = read_sidecar(path)
    except (OSError, ValueError) as exc:
        return f"its sidecar {os.path.basename(side)} cannot be read ({exc})"
    if not isinstance(doc, dict) or doc.get("format") != SIDECAR_FORMAT:
        return f"its sidecar {os.path.basename(side)} is not a cmlt frame sidecar"
    if doc.get("image") != os.path.basename(path):
        return f"its sidecar {os.path.basename(side)} describes {doc.get('image')!r}"
    try:
        same_frame = math.isclose(float(doc.get("frame")), float(frame), abs_tol=1e-6)
    except (TypeError, ValueError):
        same_frame = False
    if not same_frame:
        return f"its sidecar {os.path.basename(side)} is of frame {doc.get('frame')!r}"
    return None


#: memory a chain costs, at least (bytes): its state in the integrator (primary
#: samples with their backups, per stream) and its copy as a carried start (temporal
#: driver). Measured (peak RSS, 1,000 against 400,000 chains asked, 128x96, spp 64,
#: max_depth 6): 5.3 KiB per chain with pssmlt, 5.8 KiB with cmlt; deeper paths cost more
CHAIN_BYTES = 4096
#: the share of the machine's available memory the chains may take
CHAIN_MEMORY_SHARE = 0.5


def available_memory() -> Optional[int]:
    """Bytes of memory available to a new allocation (``MemAvailable`` of
    /proc/meminfo, else free physical pages), None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return None


def chain_memory_problem(n_chains: int, where: str,
                         available: Optional[int] = None) -> Optional[str]:
    """Why ``n_chains`` chains cannot be allocated (None: they can): more than
    :data:`CHAIN_MEMORY_SHARE` of the available memory at :data:`CHAIN_BYTES`
    each. ``where`` names the setting (``--chains 100000000``)."""
    avail = available_memory() if available is None else int(available)
    if avail is None or n_chains <= 0:
        return None
    need = int(n_chains) * CHAIN_BYTES
    if need <= CHAIN_MEMORY_SHARE * avail:
        return None
    gib = 1024.0 ** 3
    fit = int(CHAIN_MEMORY_SHARE * avail // CHAIN_BYTES)
    return (f"{where}: {n_chains} chains need at least {need / gib:.1f} GiB, more than "
            f"{CHAIN_MEMORY_SHARE:.0%} of the {avail / gib:.1f} GiB available; use at most "
            f"{fit} chains (the default is 1000)")
