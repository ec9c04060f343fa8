"""Colour-space facts that do not need a config: primaries and white points,
USD's colour-space tokens, and the AP1 luminance weights.

Chromaticities are CIE 1931 xy, in the order of the OpenEXR
``chromaticities`` attribute: red x, y, green x, y, blue x, y, white x, y.
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

__all__ = [
    "Chromaticities", "GAMUT_CHROMATICITIES", "INTEROP_GAMUT",
    "gamut_of_interop_id", "chromaticities_for_interop_id",
    "USD_TOKEN_ALIASES", "ACESCG_LUMINANCE", "D65", "ACES_WHITE",
]

Chromaticities = Tuple[float, float, float, float, float, float, float, float]

D65 = (0.3127, 0.3290)
ACES_WHITE = (0.32168, 0.33767)     # the ACES white, "about D60" (SMPTE ST 2065-1)

#: Primaries + white of the gamuts cmlt writes, keyed by the gamut token of
#: the Color Interop Forum IDs (``lin_<gamut>_scene``, ``srgb_<gamut>_scene``).
#: Sources: SMPTE ST 2065-1 (AP0), S-2014-004 (AP1), ITU-R BT.709 and BT.2020,
#: SMPTE EG 432-1 (P3-D65), Adobe RGB (1998). tests/python/color/test_color.py
#: checks each against the matrices OpenColorIO computes.
GAMUT_CHROMATICITIES: Dict[str, Chromaticities] = {
    "ap1": (0.713, 0.293, 0.165, 0.830, 0.128, 0.044) + ACES_WHITE,
    "ap0": (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.0770) + ACES_WHITE,
    "rec709": (0.64, 0.33, 0.30, 0.60, 0.15, 0.06) + D65,
    "rec2020": (0.708, 0.292, 0.170, 0.797, 0.131, 0.046) + D65,
    "p3d65": (0.680, 0.320, 0.265, 0.690, 0.150, 0.060) + D65,
    "adobergb": (0.64, 0.33, 0.21, 0.71, 0.15, 0.06) + D65,
}

#: Spellings of a gamut inside interop IDs that differ from the table keys.
INTEROP_GAMUT = {"displayp3": "p3d65"}

#: Y row of the ACEScg (AP1) RGB -> XYZ matrix: luminance of a rendering-space
#: colour (S-2014-004).
ACESCG_LUMINANCE = (0.2722287168, 0.6740817658, 0.0536895174)

#: USD colour-space tokens that are not OCIO names or aliases, mapped to the
#: Color Interop Forum ID cmlt resolves them by. The token comparison is case
#: insensitive. ``raw``/``data``/``identity`` (no conversion) and ``auto``
#: (depends on the texture's bit depth) are handled by the resolver itself.
USD_TOKEN_ALIASES: Dict[str, str] = {
    "srgb": "srgb_rec709_scene",        # UsdUVTexture inputs:sourceColorSpace = "sRGB"
    "srgb_rec709": "srgb_rec709_scene",
    "lin_rec709": "lin_rec709_scene",
    "linear": "lin_rec709_scene",
    "lin_srgb": "lin_rec709_scene",
    "lin_ap1": "lin_ap1_scene",
    "lin_ap0": "lin_ap0_scene",
    "acescg": "lin_ap1_scene",
    "aces2065-1": "lin_ap0_scene",
    "lin_rec2020": "lin_rec2020_scene",
    "lin_p3d65": "lin_p3d65_scene",
    "lin_displayp3": "lin_p3d65_scene",
    "lin_adobergb": "lin_adobergb_scene",
    "g22_rec709": "g22_rec709_scene",
    "g18_rec709": "g18_rec709_scene",
    "g24_rec709": "g24_rec709_scene",
    "srgb_ap1": "srgb_ap1_scene",
    "g22_ap1": "g22_ap1_scene",
    "srgb_p3d65": "srgb_p3d65_scene",
    "srgb_displayp3": "srgb_p3d65_scene",
    "g22_adobergb": "g22_adobergb_scene",
}


def gamut_of_interop_id(interop_id: str) -> Optional[str]:
    """``"lin_ap1_scene"`` -> ``"ap1"``; ``None`` when it names no known gamut."""
    name = (interop_id or "").split(":")[-1].lower()
    parts = name.split("_")
    if len(parts) < 2:
        return None
    for token in parts[1:]:
        token = INTEROP_GAMUT.get(token, token)
        if token in GAMUT_CHROMATICITIES:
            return token
    return None


def chromaticities_for_interop_id(interop_id: str) -> Optional[Chromaticities]:
    """The primaries + white of the gamut an interop ID names, or ``None``."""
    gamut = gamut_of_interop_id(interop_id)
    return GAMUT_CHROMATICITIES[gamut] if gamut else None
