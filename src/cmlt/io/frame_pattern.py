"""Frame patterns: the frame number in a file name, both ways.

One set of tokens for every command that names or finds frames (``render
--out``, ``flicker``, ``compare``, ``contact-sheet``):

==============  ==============================================
``####``        zero-padded to the number of ``#`` (``0007``)
``####.###``    fractional frames with fixed decimals (``0001.500``)
``$F4``, ``$F`` Houdini: padded to 4 / unpadded
``%04d``, ``%d``  printf style
==============  ==============================================

A fractional frame with a token that has no explicit decimals is written
with three decimals (``cornell.0001.500.exr``); integral frames keep the
plain form (``cornell.0001.exr``): a frame's name depends only on the frame.
Frames are never negative (``--frames`` refuses them).

Finding frames: :func:`match_pattern` lists the files a pattern names
exactly (``shot.####.exr`` finds ``shot.0007.exr``, not ``shot.7.exr`` nor a
half-written ``.shot.0007.tmp-…``); the frame number of any other file name
is its last number (:func:`frame_of`).
"""
from __future__ import annotations

import glob
import os
import re
from typing import Dict, List, Optional, Sequence, Tuple

__all__ = ["TOKEN", "DEFAULT_DECIMALS", "format_frame", "has_frame_token", "expand_pattern",
           "is_glob", "frame_of", "match_pattern", "number_paths"]

#: decimals used for fractional frames when the pattern does not say
DEFAULT_DECIMALS = 3
#: a frame within this distance of an integer counts as that integer
_INTEGRAL_EPS = 1e-6

#: every frame token; alternatives are tried left to right
TOKEN = re.compile(
    r"(?P<hash>#+)(?:\.(?P<hdec>#+))?"     # #### or ####.###
    r"|\$F(?P<fw>\d*)"                      # $F4, $F
    r"|%(?P<pw>0?\d*)d"                     # %04d, %d
)
_GLOB_CHARS = re.compile(r"[*?\[]")
_NUMBER = re.compile(r"\d+(?:\.\d+)?")
_IMAGE_EXTENSIONS = (".exr", ".png", ".tif", ".tiff", ".hdr", ".jpg", ".jpeg")


def _is_integral(frame: float) -> bool:
    return abs(frame - round(frame)) < _INTEGRAL_EPS


def format_frame(frame: float, width: int = 0, decimals: Optional[int] = None) -> str:
    """One frame number: zero-padded integer part, then decimals.
    ``decimals=None``: none for integral frames, three otherwise. ValueError
    for a negative frame."""
    if frame < 0:
        raise ValueError(f"negative frame {frame:g} cannot be named")
    if decimals is None:
        decimals = 0 if _is_integral(frame) else DEFAULT_DECIMALS
    if decimals == 0:
        return f"{int(round(frame)):0{width}d}"
    text = f"{frame:.{decimals}f}"
    whole, frac = text.split(".")
    return f"{int(whole):0{width}d}.{frac}"


def has_frame_token(pattern: str) -> bool:
    return TOKEN.search(pattern) is not None


def is_glob(pattern: str) -> bool:
    """Whether ``pattern`` has glob characters (``*``, ``?``, ``[``)."""
    return _GLOB_CHARS.search(pattern) is not None


def expand_pattern(pattern: str, frame: float) -> str:
    """Substitute ``frame`` for every frame token in ``pattern``."""
    def repl(m: "re.Match[str]") -> str:
        if m.group("hash") is not None:
            width = len(m.group("hash"))
            dec = len(m.group("hdec")) if m.group("hdec") else None
            return format_frame(frame, width, dec)
        if m.group("fw") is not None:
            return format_frame(frame, int(m.group("fw") or 0))
        return format_frame(frame, int(m.group("pw") or 0))
    return TOKEN.sub(repl, pattern)


def frame_of(path: str) -> Optional[float]:
    """The frame number of a file name: its last number, decimals included
    (``shot.0012.exr`` -> 12, ``shot.0001.500.exr`` -> 1.5), or ``None``."""
    stem = os.path.basename(path)
    for ext in _IMAGE_EXTENSIONS:
        if stem.lower().endswith(ext):
            stem = stem[: -len(ext)]
            break
    nums = _NUMBER.findall(stem)
    return float(nums[-1]) if nums else None


def _pattern_regex(pattern: str) -> "re.Pattern[str]":
    out, pos = [], 0
    for m in TOKEN.finditer(pattern):
        out.append(re.escape(pattern[pos:m.start()]))
        out.append(r"(\d+(?:\.\d+)?)")
        pos = m.end()
    out.append(re.escape(pattern[pos:]))
    return re.compile("".join(out) + r"\Z")


def match_pattern(pattern: str) -> Dict[float, str]:
    """``{frame: path}`` of every file on disk that a frame pattern names
    exactly: the pattern gives that very name back for that frame."""
    rx = _pattern_regex(pattern)
    # glob.escape only touches * ? [, never a token; the candidates are then
    # matched against the pattern itself
    found: Dict[float, str] = {}
    for path in glob.glob(TOKEN.sub("*", glob.escape(pattern))):
        m = rx.match(path)
        if not m:
            continue
        frame = float(m.group(1))
        if expand_pattern(pattern, frame) == path:
            found[frame] = path
    return found


def number_paths(paths: Sequence[str]) -> List[Tuple[float, str]]:
    """``(frame, path)`` sorted by frame, the frame being each name's last
    number; if some name has none, every path is numbered by position from 1."""
    numbered = [(frame_of(p), p) for p in paths]
    if any(f is None for f, _ in numbered):
        return [(float(i + 1), p) for i, p in enumerate(paths)]
    return sorted(numbered)
