"""What the stage says about its colour management: its OpenColorIO config
(``colorConfiguration``) and the metadata cmlt cannot honour."""
from __future__ import annotations

import os
from typing import Optional

__all__ = ["OCIO_CMS_NAMES", "stage_color_warnings", "stage_config_path"]

#: ``colorManagementSystem`` values meaning OpenColorIO (compared case-insensitively)
OCIO_CMS_NAMES = ("ocio", "opencolorio")


def _stage_cms(stage) -> str:
    try:
        return str(stage.GetColorManagementSystem() or "").strip()
    except Exception:                                   # pragma: no cover (old USD)
        return ""


def stage_color_warnings(stage) -> list:
    """Warnings about the stage's colour-management metadata cmlt cannot
    honour: a ``colorManagementSystem`` other than OpenColorIO (cmlt manages
    colour only with OCIO, so the stage's ``colorConfiguration`` is not used).
    One line each, naming the stage."""
    if stage is None:
        return []
    cms = _stage_cms(stage)
    if not cms or cms.lower() in OCIO_CMS_NAMES:
        return []
    layer = stage.GetRootLayer()
    where = layer.realPath or layer.identifier
    asset = stage.GetColorConfiguration()
    cfg = (asset.path if asset else "") or ""
    ignored = f"; its colorConfiguration {cfg} is not used" if cfg else ""
    return [f"{where}: colorManagementSystem is '{cms}', not OpenColorIO{ignored}; cmlt "
            f"manages colour with OpenColorIO ($OCIO or the built-in config; see "
            f"`cmlt inspect`)"]


def stage_config_path(stage) -> Optional[str]:
    """The stage's ``colorConfiguration`` as a file path or URI, when the
    stage says it is managed by OCIO (or does not say); otherwise None, and
    :func:`stage_color_warnings` says so."""
    if stage is None:
        return None
    cms = _stage_cms(stage)
    if cms and cms.lower() not in OCIO_CMS_NAMES:
        return None
    asset = stage.GetColorConfiguration()
    path = (asset.resolvedPath or asset.path) if asset else ""
    if not path:
        return None
    if "://" not in path and not os.path.isabs(path):
        layer = stage.GetRootLayer()
        base = os.path.dirname(layer.realPath) if layer.realPath else os.getcwd()
        path = os.path.join(base, path)
    return path
