"""The stage reader: USD (usd-core) -> :class:`cmlt.scene.FrameScene` per time code.

Public API::

    stage = open_stage(path)          # Usd.Stage, or UsdLoadError
    info = stage_info(stage)          # StageInfo; info.format() for `cmlt inspect`
    scene = load_frame(stage, time, camera=None, resolution=None, render_settings=None)

Modules, each importing only those before it: ``stage`` (opening, the
per-stage caches), ``render_settings`` (the UsdRender.Settings prim),
``camera``, ``instancing``, ``traversal``, ``motion``, ``frame``
(:func:`load_frame`), ``info`` (:func:`stage_info`).

Fatal problems raise :class:`UsdLoadError` (one line naming file/prim/attribute/time);
non-fatal ones are strings in ``FrameScene.warnings`` / ``StageInfo.warnings``.
"""
from .color import to_rendering_space
from .errors import UsdLoadError
from .frame import load_frame
from .info import StageInfo, stage_info
from .stage import open_stage

__all__ = ["open_stage", "load_frame", "stage_info", "StageInfo", "UsdLoadError",
           "to_rendering_space"]
