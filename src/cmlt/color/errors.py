"""The colour package's error (its own module, so every part can raise it)."""
from __future__ import annotations

__all__ = ["ColorError"]


class ColorError(ValueError):
    """A colour-management failure: bad config, unknown colour space,
    display or view. The message names the offending value and where it
    came from."""
