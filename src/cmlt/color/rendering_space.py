"""Which colour space of an OpenColorIO config cmlt renders in.

The rendering space is the space the core's colours are in: every authored
colour and texel is converted into it when a frame is loaded, frames leave
it through the output transform. Chosen, first match wins:

1. a name asked for (``--rendering-space NAME``): any colour space, alias,
   role or Color Interop ID of the config; it must be scene-referred and not
   data, else :class:`~cmlt.color.ColorError` lists the choices;
2. the config's ``scene_linear`` role (ACEScg in the ACES configs, so the
   default stays ACEScg with the built-in config);
3. ACEScg under one of its names or its interop ID ``lin_ap1_scene``.

:func:`luminance_weights` gives the Y row of the chosen space (the AP1 row for
ACEScg, exactly; otherwise derived through OpenColorIO's conversion to ACEScg).
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np
import PyOpenColorIO as ocio

from .errors import ColorError
from .spaces import ACESCG_LUMINANCE

__all__ = ["choose_rendering_space", "rendering_space_choices", "is_acescg", "luminance_weights"]

_ACESCG_NAMES = ("ACEScg", "lin_ap1_scene", "lin_ap1")


def is_acescg(cs) -> bool:
    names = {cs.getName().lower()} | {a.lower() for a in cs.getAliases()}
    interop = cs.getInteropID() if hasattr(cs, "getInteropID") else ""
    return "acescg" in names or "lin_ap1_scene" in names or interop == "lin_ap1_scene"


def _by_interop_id(cfg, interop_id: str):
    if not hasattr(ocio.ColorSpace, "getInteropID"):
        return None
    for cs in cfg.getColorSpaces():
        if cs.getInteropID() == interop_id:
            return cs
    return None


def rendering_space_choices(cfg) -> Tuple[str, ...]:
    """The colour spaces a render can use: scene-referred, not data, linear
    (OCIO's ``isLinear`` where it can tell, else by the ``lin``/``linear``
    in the name or encoding)."""
    out = []
    for cs in cfg.getColorSpaces(ocio.SEARCH_REFERENCE_SPACE_SCENE, ocio.COLORSPACE_ACTIVE):
        if cs.isData():
            continue
        enc = (cs.getEncoding() or "").lower() if hasattr(cs, "getEncoding") else ""
        text = (cs.getName() + " " + " ".join(cs.getAliases())).lower()
        linear = enc == "scene-linear" or "lin" in text or "acescg" in text
        if linear:
            out.append(cs.getName())
    return tuple(out)


def choose_rendering_space(cfg, lookup, requested: Optional[str], where: str) -> str:
    """The OCIO name of the rendering space (module rules). ``lookup(name)``
    resolves a name, alias, role or interop ID to a colour space or None;
    ``where`` names the config in messages."""
    if requested:
        cs = lookup(requested)
        ref = cs.getReferenceSpaceType() if cs is not None else None
        if cs is None or cs.isData() or ref != ocio.REFERENCE_SPACE_SCENE:
            why = ("is not a colour space, alias, role or interop ID of" if cs is None else
                   "is a data space of" if cs.isData() else "is display-referred in")
            raise ColorError(f"rendering space '{requested}' {why} OpenColorIO config "
                             f"{where}; choose one of: "
                             f"{', '.join(rendering_space_choices(cfg))}")
        return cs.getName()
    scene_linear = cfg.getColorSpace("scene_linear")        # roles resolve too
    if scene_linear is not None and not scene_linear.isData():
        return scene_linear.getName()
    for name in _ACESCG_NAMES:
        cs = cfg.getColorSpace(name)
        if cs is not None:
            return cs.getName()
    cs = _by_interop_id(cfg, "lin_ap1_scene")
    if cs is not None:
        return cs.getName()
    raise ColorError(
        f"OpenColorIO config {where} has no scene_linear role and no ACEScg colour space "
        f"(looked for {', '.join(repr(n) for n in _ACESCG_NAMES)}); name one with "
        f"--rendering-space (choices: {', '.join(rendering_space_choices(cfg))})")


def luminance_weights(cfg, rendering_space: str, convert,
                      chromaticities=None) -> Tuple[float, float, float]:
    """Y of a rendering-space colour as weights of its R, G, B: the AP1 row for
    ACEScg; else the Y row of the RGB -> XYZ matrix of the space's primaries
    and white (``chromaticities``: 8 floats, OpenEXR order) when known (Rec.709:
    0.2126, 0.7152, 0.0722); else the AP1 row through OpenColorIO's conversion
    of the space to ACEScg (``convert(values, src, dst)``)."""
    cs = cfg.getColorSpace(rendering_space)
    if cs is not None and is_acescg(cs):
        return ACESCG_LUMINANCE
    if chromaticities is not None:
        c = np.asarray(chromaticities, dtype=np.float64).reshape(4, 2)

        def xyz(x, y):
            return np.array([x / y, 1.0, (1.0 - x - y) / y])
        prim = np.stack([xyz(*c[i]) for i in range(3)], axis=1)    # columns: R, G, B
        scale = np.linalg.solve(prim, xyz(*c[3]))                  # white = prim @ scale
        return tuple(float(v) for v in scale)                      # the Y row (prim[1] = 1)
    acescg = next((cfg.getColorSpace(n).getName() for n in _ACESCG_NAMES
                   if cfg.getColorSpace(n) is not None), None)
    if acescg is None:
        found = _by_interop_id(cfg, "lin_ap1_scene")
        acescg = found.getName() if found is not None else None
    if acescg is None:
        return ACESCG_LUMINANCE          # no AP1 to measure against: AP1's row
    cols = np.asarray(convert(np.eye(3, dtype=np.float32), rendering_space, acescg),
                      dtype=np.float64)  # row i: primary i in ACEScg
    return tuple(float(v) for v in cols @ np.asarray(ACESCG_LUMINANCE))
