"""The OpenColorIO config cmlt renders with, and every conversion through it.

cmlt renders in **ACEScg** (AP1 primaries, linear). Colours enter through
:meth:`ColorConfig.to_rendering_space` (authored colour space -> ACEScg),
frames leave through :meth:`ColorConfig.from_rendering_space` (ACEScg ->
``--output-colorspace``, default ACEScg: no conversion), and previews go
through :meth:`ColorConfig.display_transform` (an OCIO display/view).

Which config (first match wins; ``ColorConfig.source`` says which one):

1. an explicit path (``--ocio-config``),
2. ``$OCIO``,
3. the stage's ``colorConfiguration`` metadata (when its
   ``colorManagementSystem`` is empty, ``OCIO`` or ``OpenColorIO``; another
   system is reported by :func:`stage_color_warnings`),
4. the ACES studio config built into OpenColorIO, ``ocio://studio-config-latest``
   (with OCIO 2.6.0 that resolves to
   ``studio-config-v5.0.0_aces-v2.1_ocio-v2.6``).

All colour maths runs in PyOpenColorIO with this config: OpenImageIO's own
``colorconvert`` would use its bundled OCIO and default config
(shared/NOTES.md).
"""
from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
import PyOpenColorIO as ocio

from .spaces import (USD_TOKEN_ALIASES, Chromaticities,
                     chromaticities_for_interop_id)
from .errors import ColorError
from .rendering_space import choose_rendering_space, luminance_weights
from .stage_config import stage_color_warnings, stage_config_path

__all__ = [
    "ColorError", "ColorConfig", "load_config", "get_config", "set_config",
    "BUILTIN_CONFIG", "RENDERING_SPACE", "DEFAULT_USD_COLORSPACE", "DEFAULT_DISPLAY",
    "OCIO_ENV", "stage_color_warnings",
]

#: the built-in config used when nothing else names one
BUILTIN_CONFIG = "ocio://studio-config-latest"
#: environment variable OpenColorIO itself reads
OCIO_ENV = "OCIO"
#: cmlt's rendering space (the core's colours are in it)
RENDERING_SPACE = "ACEScg"
#: USD's default for colours with no authored colour space (USD 25.05+ names)
DEFAULT_USD_COLORSPACE = "lin_rec709_scene"
#: preferred preview display; else the config's default display
DEFAULT_DISPLAY = "sRGB - Display"

# Tokens meaning "do not convert" (data textures such as normal maps).
_RAW_TOKENS = {"raw", "data", "identity", "none", "utility - raw"}
# Tokens meaning "whatever USD assumes for untagged colours".
_DEFAULT_TOKENS = {"", "unknown"}

Triple = Tuple[float, float, float]


def _bits(bit_depth: Any) -> Optional[int]:
    """Bits per channel from an int, a numpy dtype (or dtype-like) or an
    OIIO TypeDesc/format string; ``None`` means float data."""
    if bit_depth is None:
        return None
    if isinstance(bit_depth, (int, np.integer)) and not isinstance(bit_depth, bool):
        return int(bit_depth)
    text = str(bit_depth).lower()
    for key, bits in (("uint8", 8), ("int8", 8), ("uint16", 16), ("int16", 16),
                      ("uint32", 32), ("int32", 32)):
        if key in text:
            return bits
    try:
        dt = np.dtype(bit_depth)
    except TypeError:
        return None
    if dt.kind in "ui":
        return dt.itemsize * 8
    return None


class ColorConfig:
    """An OpenColorIO config plus cmlt's choices in it (rendering space,
    default display) and a cache of CPU processors.

    Thread safe: the processor cache is guarded by a lock, and OCIO CPU
    processors may be applied from several threads at once.
    """

    def __init__(self, config: "ocio.Config", source: str, location: str,
                 rendering_space: Optional[str] = None):
        self.ocio = config
        #: where the config came from, e.g. ``"$OCIO"``, ``"built-in"``
        self.source = source
        #: the path or ``ocio://`` URI it was loaded from
        self.location = location
        self._lock = threading.Lock()
        self._processors: Dict[Tuple, Any] = {}
        #: the OCIO name of the rendering space (cmlt.color.rendering_space: the
        #: space asked for, else the scene_linear role, else ACEScg)
        self.requested_rendering_space = rendering_space or None
        self.rendering_space = choose_rendering_space(
            config, self._lookup, rendering_space,
            f"'{self.name}' ({source}: {location})")
        self._luminance: Optional[Tuple[float, float, float]] = None

    # -- description -------------------------------------------------------
    @property
    def name(self) -> str:
        """The config's own name, e.g. ``studio-config-v5.0.0_aces-v2.1_ocio-v2.6``."""
        return self.ocio.getName() or os.path.basename(self.location)

    def describe(self) -> str:
        """One line for logs and ``cmlt inspect``."""
        return (f"OpenColorIO {ocio.__version__} config '{self.name}' "
                f"({self.source}: {self.location}); rendering space "
                f"'{self.rendering_space}'")

    def __repr__(self) -> str:
        return f"ColorConfig({self.name!r}, source={self.source!r})"

    # -- colour spaces -----------------------------------------------------
    @property
    def luminance_weights(self) -> Tuple[float, float, float]:
        """Y row of the rendering space (ACEScg: the AP1 row, exactly)."""
        if self._luminance is None:
            self._luminance = luminance_weights(self.ocio, self.rendering_space, self.convert,
                                                self.chromaticities(None))
        return self._luminance

    def _by_interop_id(self, interop_id: str):
        if not hasattr(ocio.ColorSpace, "getInteropID"):
            return None
        for cs in self.ocio.getColorSpaces():
            if cs.getInteropID() == interop_id:
                return cs
        return None

    def _lookup(self, name: str):
        """A colour space by OCIO name, alias, role or interop ID (or its
        ``_scene`` form), else ``None``."""
        cfg = self.ocio
        candidates = [name]
        low = name.lower()
        if low in USD_TOKEN_ALIASES:
            candidates.append(USD_TOKEN_ALIASES[low])
        if not low.endswith("_scene") and "_" in low:
            candidates.append(name + "_scene")
        for cand in candidates:
            cs = cfg.getColorSpace(cand)
            if cs is not None:
                return cs
            cs = self._by_interop_id(cand)
            if cs is not None:
                return cs
        return None

    def resolve(self, name: Optional[str], *, bit_depth: Any = None,
                prim: Any = None) -> Optional[str]:
        """The OCIO colour-space name ``name`` stands for; ``None`` for raw
        data (no conversion).

        ``name`` may be an OCIO name, alias or role, a Color Interop ID
        (``lin_rec709_scene``), or a USD token: ``lin_rec709``,
        ``srgb_rec709``, ``sRGB`` (UsdUVTexture ``sourceColorSpace``),
        ``raw``/``data`` (no conversion), ``auto`` (sRGB-encoded for textures
        of 8 bits or fewer per channel, else linear Rec.709; ``bit_depth=None``
        means float data, so linear), ``lin_ap1``, ``ACES2065-1``. ``None``,
        ``""`` and ``unknown`` mean USD's default for untagged colours,
        linear Rec.709. ``prim`` (a path or prim) only goes into the error
        message.
        """
        token = (name or "").strip()
        low = token.lower()
        if low in _DEFAULT_TOKENS:
            token, low = DEFAULT_USD_COLORSPACE, DEFAULT_USD_COLORSPACE
        if low in _RAW_TOKENS:
            return None
        if low == "auto":
            bits = _bits(bit_depth)
            token = "srgb_rec709_scene" if bits is not None and bits <= 8 else DEFAULT_USD_COLORSPACE
        cs = self._lookup(token)
        if cs is None:
            where = f" on {_prim_text(prim)}" if prim is not None else ""
            raise ColorError(
                f"unknown colour space '{name}'{where}: not a colour space, alias, role "
                f"or interop ID of OpenColorIO config '{self.name}' ({self.source}), nor "
                f"a USD token (raw, auto, sRGB, lin_rec709, srgb_rec709, lin_ap1, ...)")
        if cs.isData():
            return None
        return cs.getName()

    # -- processors --------------------------------------------------------
    def _cpu(self, key: Tuple, build):
        with self._lock:
            cpu = self._processors.get(key)
        if cpu is None:
            try:
                cpu = build().getOptimizedCPUProcessor(ocio.BIT_DEPTH_F32, ocio.BIT_DEPTH_F32,
                                                       ocio.OPTIMIZATION_DEFAULT)
            except ocio.Exception as exc:
                raise ColorError(f"OpenColorIO cannot build {key[0]} {key[1:]} in config "
                                 f"'{self.name}': {exc}") from exc
            with self._lock:
                self._processors.setdefault(key, cpu)
        return cpu

    def processor(self, src: str, dst: str):
        """Cached CPU processor between two OCIO colour-space names."""
        return self._cpu(("conversion", src, dst), lambda: self.ocio.getProcessor(src, dst))

    def convert(self, values, src: Optional[str], dst: Optional[str]):
        """Convert ``values`` between two *resolved* names (``None`` = raw)."""
        if src is None or dst is None or src == dst:
            return _passthrough(values)
        return _apply(self.processor(src, dst), values)

    # -- the three directions ------------------------------------------------
    def to_rendering_space(self, values, source_colorspace: Optional[str] = None, *,
                           bit_depth: Any = None, prim: Any = None):
        """Authored colour(s) -> ACEScg.

        ``values``: one RGB triple (any sequence of 3 numbers; returns a tuple
        of 3 floats) or an array whose last axis is 3 (RGB) or 4 (RGBA, alpha
        untouched), returned as a new float32 array of the same shape.
        ``source_colorspace``: see :meth:`resolve`; ``raw`` returns the values
        unconverted.
        """
        src = self.resolve(source_colorspace, bit_depth=bit_depth, prim=prim)
        return self.convert(values, src, self.rendering_space if src is not None else None)

    def from_rendering_space(self, image, output_colorspace: Optional[str] = None):
        """ACEScg -> ``output_colorspace`` (``None`` or ACEScg: unchanged)."""
        if output_colorspace is None:
            return _passthrough(image)
        dst = self.resolve(output_colorspace)
        return self.convert(image, self.rendering_space, dst)

    def output_colorspace_name(self, output_colorspace: Optional[str] = None) -> Optional[str]:
        """The resolved OCIO name frames are written in (``None`` = raw)."""
        return self.rendering_space if output_colorspace is None else self.resolve(output_colorspace)

    # -- EXR header ----------------------------------------------------------
    def interop_id(self, colorspace: Optional[str]) -> Optional[str]:
        """The Color Interop ID of a colour space (``lin_ap1_scene`` for ACEScg),
        from the config, else from its aliases; ``None`` if it has none."""
        name = self.output_colorspace_name(colorspace)
        if name is None:
            return "data"
        cs = self.ocio.getColorSpace(name)
        interop = cs.getInteropID() if hasattr(cs, "getInteropID") else ""
        if interop:
            return interop
        for alias in [cs.getName()] + list(cs.getAliases()):
            if alias.lower().endswith("_scene") or alias.lower().endswith("_display"):
                return alias
        return None

    def chromaticities(self, colorspace: Optional[str] = None) -> Optional[Chromaticities]:
        """Primaries + white (8 floats, OpenEXR order) of a colour space, or
        ``None`` when cmlt's table does not know its gamut."""
        interop = self.interop_id(colorspace)
        return chromaticities_for_interop_id(interop) if interop else None

    def header_attributes(self, colorspace: Optional[str] = None) -> Dict[str, Any]:
        """Image attributes describing frames written in ``colorspace``
        (``None`` = ACEScg, the default ``--output-colorspace``).

        ``oiio:ColorSpace`` is the Color Interop ID where there is one
        (OpenImageIO stores it with the EXR ``colorInteropID``; it silently
        drops names it does not know) else the OCIO name; ``chromaticities``
        is a list of 8 floats (absent if the gamut is not in the table).
        """
        name = self.output_colorspace_name(colorspace)
        attrs: Dict[str, Any] = {"oiio:ColorSpace": self.interop_id(colorspace) or name}
        chroma = self.chromaticities(colorspace)
        if chroma is not None:
            attrs["chromaticities"] = [float(c) for c in chroma]
        return attrs

    def set_header_attributes(self, spec, colorspace: Optional[str] = None):
        """Put :meth:`header_attributes` on an OpenImageIO ``ImageSpec`` (the
        Python binding rejects a plain list, so ``chromaticities`` goes in
        as ``float[8]``). Returns ``spec``."""
        for key, value in self.header_attributes(colorspace).items():
            if isinstance(value, (list, tuple)):
                spec.attribute(key, f"float[{len(value)}]", [float(v) for v in value])
            else:
                spec.attribute(key, value)
        return spec

    def colorspace_of_header(self, attrs) -> Optional[str]:
        """The resolved colour space an image header declares (an
        ``ImageSpec`` or a dict), defaulting to the rendering space."""
        get = attrs.get if isinstance(attrs, dict) else (lambda k: attrs.getattribute(k))
        for key in ("colorInteropID", "oiio:ColorSpace"):
            value = get(key)
            if value:
                try:
                    return self.resolve(str(value))
                except ColorError:
                    continue
        return self.rendering_space

    # -- display ---------------------------------------------------------------
    def default_display(self) -> str:
        displays = list(self.ocio.getDisplays())
        return DEFAULT_DISPLAY if DEFAULT_DISPLAY in displays else self.ocio.getDefaultDisplay()

    def default_view(self, display: Optional[str] = None) -> str:
        return self.ocio.getDefaultView(display or self.default_display())

    def check_display_view(self, display: Optional[str], view: Optional[str]) -> Tuple[str, str]:
        """Fill in defaults and check both names exist; return them."""
        display = display or self.default_display()
        displays = list(self.ocio.getDisplays())
        if display not in displays:
            raise ColorError(f"unknown display '{display}' in OpenColorIO config "
                             f"'{self.name}'; displays: {', '.join(displays)}")
        view = view or self.default_view(display)
        views = list(self.ocio.getViews(display))
        if view not in views:
            raise ColorError(f"unknown view '{view}' for display '{display}' in OpenColorIO "
                             f"config '{self.name}'; views: {', '.join(views)}")
        return display, view

    def display_processor(self, display: Optional[str] = None, view: Optional[str] = None,
                          source: Optional[str] = None):
        display, view = self.check_display_view(display, view)
        src = self.rendering_space if source is None else self.resolve(source)

        def build():
            dvt = ocio.DisplayViewTransform(src=src, display=display, view=view)
            return self.ocio.getProcessor(dvt, ocio.TRANSFORM_DIR_FORWARD)
        return self._cpu(("display/view", src, display, view), build)

    def display_transform(self, image, display: Optional[str] = None,
                          view: Optional[str] = None, *, dtype=np.float32,
                          source: Optional[str] = None):
        """Scene-linear image (ACEScg unless ``source`` says otherwise) ->
        display-referred values through an OCIO display/view.

        ``display`` defaults to "sRGB - Display" when the config has it, else
        the config's default display; ``view`` to the display's default view.
        ``dtype=np.float32`` returns unclipped floats; ``np.uint8`` or
        ``np.uint16`` clip to [0, 1] and quantise with rounding.
        """
        out = _apply(self.display_processor(display, view, source), image)
        dt = np.dtype(dtype)
        if dt.kind == "f":
            return out
        if dt not in (np.dtype(np.uint8), np.dtype(np.uint16)):
            raise ColorError(f"display_transform: unsupported dtype {dt}")
        arr = np.asarray(out, dtype=np.float32)
        scale = float(np.iinfo(dt).max)
        arr = np.nan_to_num(arr, nan=0.0, posinf=1.0, neginf=0.0)
        return np.rint(np.clip(arr, 0.0, 1.0) * scale).astype(dt)

    def luminance(self, rgb) -> np.ndarray:
        """Luminance (Y) of rendering-space colours (last axis RGB)."""
        return np.asarray(rgb, dtype=np.float64)[..., :3] @ np.asarray(self.luminance_weights)


# -- array plumbing -------------------------------------------------------------

def _is_triple(values) -> bool:
    return not isinstance(values, np.ndarray) and np.shape(values) == (3,)


def _passthrough(values):
    if _is_triple(values):
        return tuple(float(v) for v in values)
    return np.array(values, dtype=np.float32, copy=True)


def _apply(cpu, values):
    """Apply a CPU processor to a triple or an (..., 3|4) array (a copy)."""
    triple = _is_triple(values)
    arr = np.array(values, dtype=np.float32, copy=True, order="C")
    if arr.ndim == 0 or arr.shape[-1] not in (3, 4):
        raise ColorError(f"colour data must have 3 (RGB) or 4 (RGBA) channels on its last "
                         f"axis, got shape {arr.shape}")
    flat = arr.reshape(-1, arr.shape[-1])
    if flat.shape[0]:
        if flat.shape[1] == 3:
            cpu.applyRGB(flat)
        else:
            cpu.applyRGBA(flat)
    if triple:
        return tuple(float(v) for v in flat[0])
    return arr


def _prim_text(prim) -> str:
    if prim is None:
        return ""
    path = getattr(prim, "GetPath", None)
    return str(path()) if callable(path) else str(prim)


# -- loading ----------------------------------------------------------------------

def load_config(path: Optional[Union[str, os.PathLike]] = None, *, stage=None,
                rendering_space: Optional[str] = None) -> ColorConfig:
    """Load the OpenColorIO config cmlt renders with.

    ``path`` (``--ocio-config``) wins, then ``$OCIO``, then the stage's
    ``colorConfiguration``, then the built-in ``ocio://studio-config-latest``.
    A config that does not load raises :class:`ColorError` naming the path
    and where it came from. ``rendering_space`` (``--rendering-space``):
    see :mod:`cmlt.color.rendering_space`.
    """
    if path is not None and str(path):
        location, source = str(path), "--ocio-config"
    elif os.environ.get(OCIO_ENV):
        location, source = os.environ[OCIO_ENV], f"${OCIO_ENV}"
    elif stage_config_path(stage):
        location, source = stage_config_path(stage), "stage colorConfiguration"
    else:
        location, source = BUILTIN_CONFIG, "built-in"
    if "://" not in location and not Path(location).is_file():
        raise ColorError(f"OpenColorIO config '{location}' (from {source}) does not exist")
    try:
        cfg = ocio.Config.CreateFromFile(location)
        cfg.validate()
    except ocio.Exception as exc:
        raise ColorError(f"cannot load OpenColorIO config '{location}' (from {source}): "
                         f"{exc}") from exc
    return ColorConfig(cfg, source, location, rendering_space)


_default: Optional[ColorConfig] = None
_default_lock = threading.Lock()


def get_config() -> ColorConfig:
    """The process-wide config (loaded on first use with :func:`load_config`)."""
    global _default
    with _default_lock:
        if _default is None:
            _default = load_config()
        return _default


def current_config() -> Optional[ColorConfig]:
    """The process-wide config if one is loaded or set, else None (loads nothing)."""
    with _default_lock:
        return _default


def set_config(config: Optional[ColorConfig]) -> None:
    """Make ``config`` the process-wide config (``None``: reload lazily);
    the CLI calls this once with ``load_config(args.ocio_config, stage=...)``."""
    global _default
    with _default_lock:
        _default = config
