"""The stage's ``UsdRender.Settings`` prim: which one, its resolution and camera.

One rule for the stage reader (:func:`cmlt.usd.load_frame`) and the settings
(:func:`cmlt.settings.resolve_settings`): an explicit prim path must name a
RenderSettings prim; otherwise the stage's ``renderSettingsPrimPath`` metadata,
which must name one too; otherwise the first RenderSettings prim in traversal
order; otherwise none.
"""
from __future__ import annotations

from typing import Optional, Tuple

from pxr import Sdf, Usd, UsdGeom, UsdRender

from .errors import UsdLoadError
from .stage import prim_at, stage_file

__all__ = ["find_settings_prim", "settings_resolution", "settings_camera",
           "settings_camera_problem", "default_resolution"]


def default_resolution() -> Tuple[int, int]:
    """The resolution of a stage without a settings prim: the core's default
    (the settings table's width and height)."""
    from .. import _core
    st = _core.RenderSettings()
    return (int(st.width), int(st.height))


def find_settings_prim(stage, settings_prim_path: Optional[str] = None) -> Optional[Usd.Prim]:
    """The ``UsdRender.Settings`` prim to read, or ``None`` (module rule).
    Raises :class:`UsdLoadError` naming the stage and the path when the
    explicit path or the metadata names no RenderSettings prim."""
    if stage is None:
        if settings_prim_path:
            raise UsdLoadError(f"render settings {settings_prim_path}: no stage")
        return None
    path = str(settings_prim_path) if settings_prim_path else ""
    if not path and stage.HasAuthoredMetadata("renderSettingsPrimPath"):
        path = str(stage.GetMetadata("renderSettingsPrimPath") or "")
    if not path:
        for prim in stage.Traverse():
            if prim.IsA(UsdRender.Settings):
                return prim
        return None
    prim = prim_at(stage, path)
    if prim is None:
        raise UsdLoadError(f"{stage_file(stage)}: render settings {path} does not exist")
    if not prim.IsA(UsdRender.Settings):
        raise UsdLoadError(f"{stage_file(stage)}: render settings {path} is a "
                           f"{prim.GetTypeName() or 'typeless'} prim, not RenderSettings")
    return prim


def settings_resolution(prim, time) -> Tuple[Optional[Tuple[int, int]], bool]:
    """``((width, height), authored)`` of a settings prim at ``time``: the
    authored value, else the UsdRender fallback (2048x1080); ``(None, False)``
    when it has no value at all."""
    attr = UsdRender.Settings(prim).GetResolutionAttr()
    value = attr.Get(time)
    if value is None:
        return None, False
    return (int(value[0]), int(value[1])), bool(attr.HasAuthoredValue())


def settings_camera(prim) -> Optional[Sdf.Path]:
    """The first target of the settings prim's ``camera`` relationship."""
    targets = UsdRender.Settings(prim).GetCameraRel().GetForwardedTargets()
    return targets[0] if targets else None


def settings_camera_problem(stage, prim) -> str:
    """Why the ``camera`` relationship of a settings prim cannot be used
    ('' when it can, or when it is not authored): its target does not exist,
    or is not a Camera. One line naming the settings prim and the target; the
    frame loop then renders from another camera."""
    if prim is None:
        return ""
    if isinstance(prim, UsdRender.Settings):
        prim = prim.GetPrim()
    path = settings_camera(prim)
    if path is None:
        return ""
    target = stage.GetPrimAtPath(path)
    if not target:
        why = "does not exist"
    elif not target.IsA(UsdGeom.Camera):
        why = f"is a {target.GetTypeName() or 'typeless prim'}, not a Camera"
    else:
        return ""
    return f"{prim.GetPath()}: camera {path} {why}; rendering from another camera"
