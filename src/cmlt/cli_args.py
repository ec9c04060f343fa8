"""The ``cmlt`` command line's exit codes, its parser class (errors are one line) and
the value types of its flags (``--res``, ``--aov``, ``--variant``, ``--purpose``,
``--crop``)."""

from __future__ import annotations

import argparse
import sys


EXIT_OK, EXIT_RENDER, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class _Parser(argparse.ArgumentParser):
    """argparse, but errors are one line: ``cmlt: error: ...``, exit 2."""

    def error(self, message):                      # noqa: D401 - argparse API
        sys.stderr.write(f"cmlt: error: {message} (see `{self.prog} --help`)\n")
        raise SystemExit(EXIT_USAGE)


def parse_resolution(text: str):
    """``640x480`` -> (640, 480); argparse turns ValueError into a usage error."""
    parts = text.lower().replace("*", "x").split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        w, h = int(parts[0]), int(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT, e.g. 640x480") from None
    from .settings.table import RESOLUTION_RANGE
    lo, hi = RESOLUTION_RANGE
    if w < lo or h < lo or w > hi or h > hi:
        raise argparse.ArgumentTypeError(f"{text!r}: width and height must be {lo}..{hi}")
    return (w, h)


def _int_at_least(lo: int):
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{text!r}: must be at least {lo}")
        return v
    return parse


def parse_aovs(text: str):
    """``albedo,normal`` -> ("albedo", "normal"); an unknown name is a usage
    error naming ``--aov`` (argparse prefixes "argument --aov:")."""
    from .io.exr import AOV_CHANNELS

    names = [t.strip().lower() for t in text.split(",") if t.strip()]
    if not names:
        raise argparse.ArgumentTypeError(f"{text!r}: give one or more of "
                                         f"{', '.join(AOV_CHANNELS)}")
    for n in names:
        if n not in AOV_CHANNELS:
            raise argparse.ArgumentTypeError(f"unknown AOV {n!r}; choose from "
                                             f"{', '.join(AOV_CHANNELS)} (comma-separated)")
    return tuple(dict.fromkeys(names))


def parse_variant_flag(text: str) -> str:
    """``--variant`` text checked for its form (:func:`cmlt.usd.variants.parse_variant`);
    whether the stage has that set is checked once it is open."""
    from .usd.variants import parse_variant
    try:
        parse_variant(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text.strip()


def parse_purposes(text: str):
    """``render,proxy`` -> ("render", "proxy"); ``geometry`` (husk's name for
    the default purpose) is accepted and means ``default``."""
    names = [t.strip().lower() for t in text.split(",") if t.strip()]
    names = ["default" if n == "geometry" else n for n in names]
    allowed = ("default", "render", "proxy", "guide")
    for n in names:
        if n not in allowed:
            raise argparse.ArgumentTypeError(f"unknown purpose {n!r}; choose from "
                                             "render, proxy, guide (comma-separated)")
    if not names:
        raise argparse.ArgumentTypeError(f"{text!r}: give one or more of render, proxy, guide")
    return tuple(dict.fromkeys(names))


def parse_crop(text: str):
    """``x0,y0,x1,y1`` (pixels, x1/y1 exclusive) -> a tuple of 4 ints."""
    parts = text.replace(" ", "").split(",")
    try:
        if len(parts) != 4:
            raise ValueError
        x0, y0, x1, y1 = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not X0,Y0,X1,Y1, e.g. 0,0,320,240") \
            from None
    if x0 < 0 or y0 < 0 or x1 <= x0 or y1 <= y0:
        raise argparse.ArgumentTypeError(f"{text!r}: need 0 <= X0 < X1 and 0 <= Y0 < Y1 "
                                         "(X1, Y1 exclusive)")
    return (x0, y0, x1, y1)


def _error(message: str, code: int) -> int:
    sys.stderr.write(f"cmlt: error: {message}\n")
    return code
