"""Frame specs (``--frames``) and output patterns (``--out``).

Frame specs follow usdrecord's ``--frames`` syntax:

==============  ==============================================
``7``           one frame (time code 7)
``1.5``         one fractional frame (time code 1.5)
``1:24``        24 frames, both ends included
``1-24``        the same (husk's spelling; frames are never negative)
``1:24x2``      every second frame: 1, 3, ..., 23
``1:2x0.25``    sub-frames: 1, 1.25, 1.5, 1.75, 2
``1,5,9``       a comma list; each item may itself be a range
``all``         the stage's ``startTimeCode:endTimeCode`` (step 1)
==============  ==============================================

Frames are time codes. Negative frames are rejected: an output name cannot
carry a sign in a way that sorts or pads sensibly, and husk/usdrecord users
render negative pre-roll through an offset layer instead. A frame listed twice
is rendered once (first occurrence wins; order is otherwise kept).

Frames outside the stage's authored time range render the stage as USD holds
it there (every animated value at its first or last time sample):
:func:`check_stage_range` warns about them, naming the range, and refuses a
spec that lies far beyond it (:func:`far_outside_limit`) unless forced
(``--force-frames``): ``1:1000000`` on a one-frame stage is a typo, not a
million identical frames.

Output patterns (``--out``) substitute the frame number for a token of
:mod:`cmlt.io.frame_pattern` (``####``, ``####.###``, ``$F4``, ``%04d``). So a
frame's name depends only on the frame, never on the rest of the spec, and
``--resume`` works across specs. Two frames that would get the same name
(``1.0001`` and ``1.0002`` at three decimals) are an error, as is a pattern
without a token when more than one frame is rendered.
"""
from __future__ import annotations

import math
import re
from typing import List, Optional, Sequence

from ..io import frame_pattern as _pattern
from ..io.frame_pattern import has_frame_token
from .errors import UsageError

__all__ = [
    "FrameSpecError",
    "OutputPatternError",
    "parse_frames",
    "default_frames",
    "format_frame",
    "expand_pattern",
    "expand_outputs",
    "check_stage_range",
    "far_outside_limit",
]

#: a frame within this distance of an integer counts as that integer
_INTEGRAL_EPS = 1e-6
#: upper bound on frames from one spec (a typo like 1:1e9 must not hang)
MAX_FRAMES = 1_000_000
#: "far outside" the stage's time range (check_stage_range): more frames outside it
#: than FAR_FACTOR times the stage's frame count, at least FAR_MIN, at most FAR_MAX
FAR_FACTOR, FAR_MIN, FAR_MAX = 10, 100, 10_000
#: husk's START-END range spelling (no sign: frames are never negative), with an
#: optional stride as in START:ENDxSTRIDE
_DASH_RANGE = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*-\s*(\d+(?:\.\d*)?)\s*(?=[xX]|$)")


class FrameSpecError(UsageError):
    """A ``--frames`` spec that cannot be parsed or makes no sense."""


class OutputPatternError(UsageError):
    """An ``--out`` pattern that cannot name the frames being rendered."""


def _number(text: str, spec: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FrameSpecError(
            f"--frames {spec!r}: {text.strip()!r} is not a frame number") from None
    if not math.isfinite(value):
        raise FrameSpecError(f"--frames {spec!r}: {text.strip()!r} is not a finite frame number")
    if value < 0:
        raise FrameSpecError(
            f"--frames {spec!r}: negative frame {text.strip()} is not supported "
            "(output names cannot carry a sign)")
    return value


def _clean(value: float) -> float:
    """Round away float noise from stride arithmetic (1 + 3*0.1 -> 1.3)."""
    rounded = round(value, 9)
    return float(round(rounded)) if abs(rounded - round(rounded)) < _INTEGRAL_EPS else rounded


def _range(start: float, end: float, stride: float, spec: str) -> List[float]:
    if end < start:
        raise FrameSpecError(
            f"--frames {spec!r}: range ends ({end:g}) before it starts ({start:g})")
    count = int(math.floor((end - start) / stride + 1e-9)) + 1
    if count > MAX_FRAMES:
        raise FrameSpecError(f"--frames {spec!r}: {count} frames is more than the limit of {MAX_FRAMES}")
    return [_clean(start + i * stride) for i in range(count)]


def _item(item: str, spec: str, start: float, end: float, has_range: bool) -> List[float]:
    text = item.strip()
    if not text:
        raise FrameSpecError(f"--frames {spec!r}: empty item in the list")
    if text.lower() == "all":
        if not has_range:
            # No authored range: USD's start/end are both 0 (or only one
            # is authored); render the one start frame, as husk does.
            return [_clean(start)]
        return _range(start, end, 1.0, spec)
    text = _DASH_RANGE.sub(r"\1:\2", text, count=1)        # 1-24 -> 1:24
    stride = 1.0
    if "x" in text.lower():
        if ":" not in text:
            raise FrameSpecError(f"--frames {spec!r}: a stride (x) needs a range, as in 1:24x2")
        text, stride_text = re.split(r"[xX]", text, maxsplit=1)
        try:
            stride = float(stride_text)
        except ValueError:
            raise FrameSpecError(
                f"--frames {spec!r}: stride {stride_text.strip()!r} is not a number") from None
        if not math.isfinite(stride) or stride <= 0:
            raise FrameSpecError(f"--frames {spec!r}: stride must be positive, got {stride_text.strip()}")
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 2:
            raise FrameSpecError(f"--frames {spec!r}: a range is START:END or START:ENDxSTRIDE")
        return _range(_number(parts[0], spec), _number(parts[1], spec), stride, spec)
    return [_clean(_number(text, spec))]


def parse_frames(spec: str, start: float = 0.0, end: float = 0.0,
                 has_range: bool = True) -> List[float]:
    """Parse a ``--frames`` spec into a list of time codes.

    ``start``/``end``/``has_range`` describe the stage (``stage_info``) and
    are used only by ``all``.
    """
    if spec is None or not str(spec).strip():
        raise FrameSpecError("--frames: empty frame spec")
    spec = str(spec).strip()
    frames: List[float] = []
    seen = set()
    for item in spec.split(","):
        for f in _item(item, spec, float(start), float(end), has_range):
            if f not in seen:
                seen.add(f)
                frames.append(f)
    if len(frames) > MAX_FRAMES:
        raise FrameSpecError(f"--frames {spec!r}: more than {MAX_FRAMES} frames")
    return frames


def far_outside_limit(stage_frames: int) -> int:
    """How many frames outside the stage's time range a spec may list before
    it is refused as a typo: ``FAR_FACTOR`` times the stage's frame count,
    at least ``FAR_MIN`` (a static one-frame stage rendered 24 times for a
    flicker measurement is fine), at most ``FAR_MAX``."""
    return int(min(FAR_MAX, max(FAR_MIN, FAR_FACTOR * max(1, int(stage_frames)))))


def _list_frames(frames: Sequence[float], limit: int = 4) -> str:
    shown = ", ".join(f"{f:g}" for f in frames[:limit])
    return shown + (f", ... ({len(frames) - limit} more)" if len(frames) > limit else "")


def check_stage_range(frames: Sequence[float], start: float, end: float,
                      has_range: bool = True, *, spec: Optional[str] = None,
                      force: bool = False) -> Optional[str]:
    """Frames against the stage's time range ``start..end``.

    Returns a warning naming the range and the frames outside it (None if
    all are inside, or if the stage authors no range: a static stage looks
    the same at every frame). Raises :class:`FrameSpecError` if more frames
    than :func:`far_outside_limit` lie outside the range (without an
    authored range: other than ``start``, the one frame such a stage has),
    unless ``force``.
    """
    lo, hi = (float(start), float(end)) if has_range else (float(start), float(start))
    if hi < lo:
        lo, hi = hi, lo
    outside = [f for f in frames if f < lo - _INTEGRAL_EPS or f > hi + _INTEGRAL_EPS]
    if not outside:
        return None
    stage_frames = int(math.floor(hi - lo + 1e-9)) + 1
    what = f"--frames {spec!r}" if spec is not None else "frames"
    rng = (f"time range {lo:g}..{hi:g} ({stage_frames} frame{'s' if stage_frames != 1 else ''})"
           if has_range else f"time range (none authored: one frame, {lo:g})")
    limit = far_outside_limit(stage_frames)
    if len(outside) > limit and not force:
        raise FrameSpecError(
            f"{what}: {len(outside)} of {len(frames)} frames lie outside the stage's {rng}, "
            f"more than {limit}; give --force-frames to render them anyway")
    if not has_range:
        return None
    return (f"{what}: {len(outside)} of {len(frames)} frame(s) lie outside the stage's {rng}: "
            f"{_list_frames(outside)}; there every animated value holds its first or last "
            "time sample")


def default_frames(start: float) -> List[float]:
    """Without ``--frames``: the stage's start time code only (husk's rule)."""
    return [_clean(float(start))]


def format_frame(frame: float, width: int = 0, decimals: Optional[int] = None) -> str:
    """:func:`cmlt.io.frame_pattern.format_frame`; a negative frame is an
    :class:`OutputPatternError`."""
    try:
        return _pattern.format_frame(frame, width, decimals)
    except ValueError as exc:
        raise OutputPatternError(f"--out: {exc}") from None


def expand_pattern(pattern: str, frame: float) -> str:
    """:func:`cmlt.io.frame_pattern.expand_pattern`; a negative frame is an
    :class:`OutputPatternError`."""
    try:
        return _pattern.expand_pattern(pattern, frame)
    except ValueError as exc:
        raise OutputPatternError(f"--out: {exc}") from None


def expand_outputs(pattern: str, frames: Sequence[float]) -> List[str]:
    """Output path of every frame; checks that the names are distinct."""
    if not pattern:
        raise OutputPatternError("--out: empty output path")
    if not has_frame_token(pattern):
        if len(frames) > 1:
            raise OutputPatternError(
                f"--out {pattern!r}: {len(frames)} frames need a frame token "
                "in the name (####, $F4 or %04d)")
        return [pattern] * len(frames)
    paths = [expand_pattern(pattern, f) for f in frames]
    seen = {}
    for f, p in zip(frames, paths):
        if p in seen:
            raise OutputPatternError(
                f"--out {pattern!r}: frames {seen[p]:g} and {f:g} both map to {p!r}; "
                "add decimals to the token (####.####)")
        seen[p] = f
    return paths
