"""Find cmlt's USD plugins and put them on the plugin path.

The plugins (today the codeless schema ``CmltRenderSettingsAPI``) live in
``plugins/usd`` at the repository root, and inside an installed wheel at
``cmlt/plugins/usd``. USD reads ``PXR_PLUGINPATH_NAME`` once, when its plugin
registry starts, and a schema registered after the schema registry has been
used is never seen (shared/NOTES.md, "Codeless schemas"). So
:func:`register` runs from ``cmlt/__init__.py`` before anything in cmlt
imports ``pxr``.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Optional

__all__ = ["plugin_path", "register", "PLUGIN_ENV"]

PLUGIN_ENV = "PXR_PLUGINPATH_NAME"
_PLUGINFO = "plugInfo.json"


def _candidates():
    here = Path(__file__).resolve().parent
    yield here / "plugins" / "usd"                   # installed wheel: cmlt/plugins/usd
    yield here.parent.parent / "plugins" / "usd"     # source tree: <repo>/src/cmlt -> <repo>/plugins/usd


def plugin_path() -> Optional[str]:
    """The directory holding cmlt's top-level USD ``plugInfo.json``.

    Checks the installed location (``cmlt/plugins/usd``) first, then the
    source tree (``<repo>/plugins/usd``, for editable installs and
    ``PYTHONPATH=src``). Returns ``None`` when neither exists.
    """
    for cand in _candidates():
        if (cand / _PLUGINFO).is_file():
            return str(cand)
    return None


def register() -> Optional[str]:
    """Prepend :func:`plugin_path` to ``$PXR_PLUGINPATH_NAME``; return it.

    Idempotent. If ``pxr`` was imported before cmlt, the environment variable
    may already have been read, so the plugins are also registered directly
    with ``Plug.Registry`` — which still works as long as the schema
    registry has not been used yet.
    """
    path = plugin_path()
    if path is None:
        return None
    entries = [p for p in os.environ.get(PLUGIN_ENV, "").split(os.pathsep) if p]
    if path not in entries:
        os.environ[PLUGIN_ENV] = os.pathsep.join([path] + entries)
    if "pxr.Plug" in sys.modules:
        from pxr import Plug
        Plug.Registry().RegisterPlugins(path)
    return path
