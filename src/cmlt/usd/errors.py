"""Errors raised by the stage reader."""
from __future__ import annotations


class UsdLoadError(Exception):
    """A fatal problem with a stage: the message is one line and names the
    file, prim, attribute and/or time code it is about."""
