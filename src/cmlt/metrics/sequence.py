"""Load image sequences for the flicker metrics.

A sequence is named by

* a frame pattern (``shot.####.exr``, ``shot.$F4.exr``, ``shot.%04d.exr``;
  the tokens of :mod:`cmlt.io.frame_pattern`): every file on disk that the
  pattern names, matched exactly (``shot.####.exr`` finds ``shot.0007.exr``,
  not ``shot.7.exr``);
* a glob (``renders/shot.*.exr``): the frame number of each file is the last
  number in its name;
* an explicit list of paths (frame numbers as for a glob; files without a
  number are numbered by position, from 1).

Frames are sorted by number. Integral frames must form a complete range with
one stride (``1..24``, or ``1, 3, ..., 23``): a gap is a missing frame and an
error that names the missing files. Images are float64 ``(H, W, 3)``: the
colour of the file by the rule of :mod:`cmlt.io.image`.
"""
from __future__ import annotations

import glob
import math
import os
from typing import Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..io.frame_pattern import (expand_pattern, format_frame, frame_of, has_frame_token, is_glob,
                                match_pattern, number_paths)
from ..io.image import ImageReadError, read_rgb

__all__ = ["MetricsError", "load_image", "load_sequence", "find_frames", "frame_of"]


class MetricsError(ValueError):
    """Bad input to the metrics: a missing frame, a size mismatch, an unreadable
    file. The message is one line and names the files."""


def _check_complete(frames: List[float], describe) -> None:
    """Integral frames must be a full range with a single stride."""
    if len(frames) < 3 or any(abs(f - round(f)) > 1e-6 for f in frames):
        return
    ints = [int(round(f)) for f in frames]
    stride = 0
    for a, b in zip(ints, ints[1:]):
        stride = math.gcd(stride, b - a)
    if stride <= 0:
        return
    have = set(ints)
    missing = [f for f in range(ints[0], ints[-1] + 1, stride) if f not in have]
    if missing:
        shown = ", ".join(describe(float(f)) for f in missing[:5])
        more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        raise MetricsError(f"missing frame(s) {', '.join(map(str, missing[:5]))}{more}: "
                           f"no {shown}{more}")


def find_frames(pattern: str) -> List[Tuple[float, str]]:
    """``(frame, path)`` of every file a pattern or glob names, sorted by frame."""
    if has_frame_token(pattern):
        found = match_pattern(pattern)
        if not found:
            raise MetricsError(f"{pattern}: no files match the frame pattern")
        items = sorted(found.items())
        _check_complete([f for f, _ in items], lambda f: expand_pattern(pattern, f))
        return items
    if is_glob(pattern):
        paths = glob.glob(pattern)
        if not paths:
            raise MetricsError(f"{pattern}: no files match")
        return _number_paths(paths, pattern)
    if not os.path.exists(pattern):
        raise MetricsError(f"{pattern}: no such file")
    f = frame_of(pattern)
    return [(f if f is not None else 1.0, pattern)]


def _number_paths(paths: Sequence[str], what: str) -> List[Tuple[float, str]]:
    items = number_paths(paths)
    seen = {}
    for f, p in items:
        if f in seen:
            raise MetricsError(f"{what}: {seen[f]} and {p} both have frame number "
                               f"{format_frame(f)}")
        seen[f] = p
    _check_complete([f for f, _ in items],
                    lambda f: f"frame {format_frame(f)} between "
                              f"{os.path.basename(items[0][1])} and "
                              f"{os.path.basename(items[-1][1])}")
    return items


def load_image(path: str) -> np.ndarray:
    """The colour of an image file (:mod:`cmlt.io.image`) as float64 ``(H, W, 3)``;
    a non-finite value is a :class:`MetricsError` naming the first pixel."""
    try:
        rgb, _ = read_rgb(path, dtype=np.float64)
    except ImageReadError as exc:
        raise MetricsError(str(exc)) from None
    bad = ~np.isfinite(rgb)
    if bad.any():
        y, x, c = (int(v) for v in np.argwhere(bad)[0])
        raise MetricsError(f"{path}: {int(bad.sum())} non-finite pixel values "
                           f"(first at x={x}, y={y}, channel {'RGB'[c]})")
    return rgb


PathsOrPattern = Union[str, os.PathLike, Iterable[Union[str, os.PathLike]]]


def load_sequence(pattern_or_paths: PathsOrPattern,
                  frames: Optional[Sequence[float]] = None
                  ) -> Tuple[List[float], List[np.ndarray]]:
    """Load a sequence: ``(frames, images)``, sorted by frame number.

    ``pattern_or_paths`` is a frame pattern, a glob, one file or a list of
    files. With ``frames``, exactly those frames are loaded from a pattern
    (a missing one is an error naming its file). All images must have the
    same size.
    """
    if isinstance(pattern_or_paths, (str, os.PathLike)):
        pattern = os.fspath(pattern_or_paths)
        if frames is not None and has_frame_token(pattern):
            items = [(float(f), expand_pattern(pattern, float(f))) for f in frames]
            missing = [p for _, p in items if not os.path.exists(p)]
            if missing:
                more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
                raise MetricsError(f"{pattern}: missing {len(missing)} frame(s): "
                                   f"{', '.join(missing[:3])}{more}")
        else:
            items = find_frames(pattern)
    else:
        paths = [os.fspath(p) for p in pattern_or_paths]
        if not paths:
            raise MetricsError("no image files given")
        missing = [p for p in paths if not os.path.exists(p)]
        if missing:
            raise MetricsError(f"missing file(s): {', '.join(missing[:3])}"
                               + (f" and {len(missing) - 3} more" if len(missing) > 3 else ""))
        items = _number_paths(paths, "files")
    images = []
    first = None
    for _, path in items:
        img = load_image(path)
        if first is None:
            first = (path, img.shape)
        elif img.shape != first[1]:
            raise MetricsError(f"{path} is {img.shape[1]}x{img.shape[0]} but {first[0]} is "
                               f"{first[1][1]}x{first[1][0]}: all frames must have one size")
        images.append(img)
    return [f for f, _ in items], images
