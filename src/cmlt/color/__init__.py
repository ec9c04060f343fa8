"""Colour management for cmlt with OpenColorIO.

cmlt renders in ACEScg. The module-level functions below use the
process-wide config (:func:`get_config`; the CLI installs the one named by
``--ocio-config``/``$OCIO`` with :func:`set_config`); each also takes
``config=`` to use another.

    to_rendering_space(rgb_or_array, source_colorspace)   authored -> ACEScg
    from_rendering_space(image, output_colorspace)        ACEScg -> output
    header_attributes(colorspace)                         EXR oiio:ColorSpace + chromaticities
    display_transform(image, display, view)               ACEScg -> display (previews)
    authored_colorspace(attr_or_prim)                     the colour space USD says
"""
from __future__ import annotations

from typing import Any, Dict, Optional

import numpy as np

from .config import (BUILTIN_CONFIG, DEFAULT_DISPLAY, DEFAULT_USD_COLORSPACE, OCIO_ENV,
                     RENDERING_SPACE, ColorConfig, ColorError, get_config, load_config,
                     set_config)
from .spaces import ACESCG_LUMINANCE, GAMUT_CHROMATICITIES
from .usd import authored_colorspace, texture_colorspace

__all__ = [
    "ColorConfig", "ColorError", "load_config", "get_config", "set_config",
    "to_rendering_space", "from_rendering_space", "header_attributes",
    "display_transform", "authored_colorspace", "texture_colorspace", "resolve",
    "BUILTIN_CONFIG", "DEFAULT_DISPLAY", "DEFAULT_USD_COLORSPACE", "OCIO_ENV",
    "RENDERING_SPACE", "ACESCG_LUMINANCE", "GAMUT_CHROMATICITIES",
]


def _cfg(config: Optional[ColorConfig]) -> ColorConfig:
    return config if config is not None else get_config()


def resolve(name: Optional[str], *, bit_depth: Any = None, prim: Any = None,
            config: Optional[ColorConfig] = None) -> Optional[str]:
    """See :meth:`ColorConfig.resolve`."""
    return _cfg(config).resolve(name, bit_depth=bit_depth, prim=prim)


def to_rendering_space(values, source_colorspace: Optional[str] = None, *,
                       bit_depth: Any = None, prim: Any = None,
                       config: Optional[ColorConfig] = None):
    """See :meth:`ColorConfig.to_rendering_space`."""
    return _cfg(config).to_rendering_space(values, source_colorspace,
                                           bit_depth=bit_depth, prim=prim)


def from_rendering_space(image, output_colorspace: Optional[str] = None, *,
                         config: Optional[ColorConfig] = None):
    """See :meth:`ColorConfig.from_rendering_space`."""
    return _cfg(config).from_rendering_space(image, output_colorspace)


def header_attributes(colorspace: Optional[str] = None, *,
                      config: Optional[ColorConfig] = None) -> Dict[str, Any]:
    """See :meth:`ColorConfig.header_attributes`."""
    return _cfg(config).header_attributes(colorspace)


def display_transform(image, display: Optional[str] = None, view: Optional[str] = None, *,
                      dtype=np.float32, source: Optional[str] = None,
                      config: Optional[ColorConfig] = None):
    """See :meth:`ColorConfig.display_transform`."""
    return _cfg(config).display_transform(image, display, view, dtype=dtype, source=source)
