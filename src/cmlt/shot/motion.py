"""Screen motion of a shot's frames: where each pixel centre's first hit goes in the next
frame, from the core's screen anchors (the first hit of each pixel centre's camera ray,
kept in its instance's object space and projected with the next frame's geometry and
camera). ``cmlt.metrics.flicker.motion_compensated_tf`` measures temporal flicker along
it.
"""
from __future__ import annotations

import numpy as np

__all__ = ["screen_flow"]


def screen_flow(shot: str, frames, res):
    """Where each pixel centre's first hit is in the next frame: a list over frame pairs
    of (H, W, 2) raster positions (NaN: nothing hit, or behind the camera), from the
    core's screen anchors (the geometry and camera of each frame). ``frames``: a
    ``--frames`` spec or a list of time codes."""
    import cmlt._core as core

    from ..usd import load_frame, open_stage, stage_info
    from .bridge import SceneBridge
    from .frames import parse_frames
    stage = open_stage(shot)
    info = stage_info(stage)
    times = (parse_frames(frames, info.start, info.end, info.has_authored_time_range)
             if isinstance(frames, str) else [float(t) for t in frames])
    st = core.RenderSettings()
    st.width, st.height = int(res[0]), int(res[1])
    bridge = SceneBridge(core)
    out, prev = [], None
    for t in times:
        scene = bridge.update(load_frame(stage, t, resolution=tuple(res)))
        if prev is not None:
            p = np.asarray(core.temporal_project_anchors(scene, st, prev), dtype=np.float64)
            out.append(p.reshape(st.height, st.width, 2))
        prev = core.temporal_screen_anchors(scene, st, st.width, st.height)
    return out
