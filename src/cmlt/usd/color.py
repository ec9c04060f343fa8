"""Colour entry point of the stage reader.

Every colour the reader takes from a stage (material inputs, light colours,
displayColor, texture fallbacks) goes through :func:`to_rendering_space`, so
colour management has exactly one place to hook in.
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np

# Names (lower case) of colour spaces that are already the rendering space.
_IDENTITY_SPACES = {"", "auto", "raw", "lin_rec709", "lin_srgb", "linear rec.709 (srgb)",
                    "linear", "lin_rec709_scene"}


def to_rendering_space(rgb: Sequence[float],
                       source_colorspace: Optional[str] = None) -> Tuple[float, float, float]:
    """Convert an authored linear RGB triple to the rendering space.

    PLACEHOLDER for the colour-management engineer: today this is the
    identity (the rendering space is taken to be linear Rec.709, which is
    what USD assumes for unmarked colours). ``source_colorspace`` is the
    authored ``colorSpace`` metadata / ``sourceColorSpace`` token when there
    is one, else ``None`` (unknown, treated as linear Rec.709). The function
    must return three finite Python floats; non-finite input components are
    replaced by 0 so that no NaN reaches the scene arrays.
    """
    a = np.asarray(rgb, dtype=np.float64).reshape(-1)
    if a.size == 1:
        a = np.repeat(a, 3)
    a = a[:3] if a.size >= 3 else np.pad(a, (0, 3 - a.size))
    a = np.where(np.isfinite(a), a, 0.0)
    # Unknown/linear spaces: identity. Other spaces: identity as well until
    # OCIO is wired in (see cmlt.color); the name is kept for that hook.
    _ = (source_colorspace or "").strip().lower() in _IDENTITY_SPACES
    return (float(a[0]), float(a[1]), float(a[2]))
