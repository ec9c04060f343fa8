"""Errors of the frame loop, sorted by who has to fix them.

``UsageError``      a flag value is wrong (the CLI exits 2)
``RenderError``     the shot or the render failed (the CLI exits 1)
``RenderCancelled`` the user pressed Ctrl-C (the CLI exits 130)

Messages are one line and name the flag, file or prim at fault.
"""
from __future__ import annotations

from typing import List, Sequence

__all__ = ["UsageError", "RenderError", "RenderCancelled"]


class UsageError(ValueError):
    """A command-line value (flag, path) is wrong."""


class RenderError(RuntimeError):
    """The shot could not be loaded or rendered."""


class RenderCancelled(Exception):
    """Rendering stopped on request; finished frames are on disk."""

    def __init__(self, frame: float, finished: Sequence[str], remaining: int):
        self.frame = frame
        self.finished: List[str] = list(finished)
        self.remaining = remaining
        super().__init__(
            f"interrupted at frame {frame:g}: {len(self.finished)} frame(s) written, "
            f"{remaining} left (the partial frame was not written)")
