"""Screen motion of a shot's frames and the temporal flicker measured along it.

Under a moving camera the same pixel shows a different surface in each frame, so the
plain temporal flicker TF (:mod:`.flicker`) also counts noise that moves with the
surfaces; the motion-compensated TF compares each frame's error with the next frame's
error where the surface point went. The motion comes from the core's screen anchors
(the first hit of each pixel centre's camera ray, kept in its instance's object space
and projected with the next frame's geometry and camera).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["screen_flow", "motion_compensated_tf"]


def screen_flow(shot: str, frames: str, res):
    """Where each pixel centre's first hit is in the next frame: a list over frame pairs
    of (H, W, 2) raster positions (NaN: nothing hit, or behind the camera), from the
    core's screen anchors (the geometry and camera of each frame)."""
    import cmlt._core as core

    from ..shot.bridge import SceneBridge
    from ..shot.frames import parse_frames
    from ..usd import load_frame, open_stage, stage_info
    stage = open_stage(shot)
    info = stage_info(stage)
    times = parse_frames(frames, info.start, info.end, info.has_authored_time_range)
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


def motion_compensated_tf(images, refs, flow) -> float:
    """TF with the error of frame f compared to frame f+1's error where that surface
    point went (nearest pixel): mean |E_{f+1}(p') − E_f(p)| / mean R over the pixels
    whose point stays in the image. On a static shot it is TF."""
    E = np.asarray(images, np.float64) - np.asarray(refs, np.float64)
    norm = float(np.asarray(refs, np.float64).mean())
    H, W = E.shape[1:3]
    terms = []
    for k, fl in enumerate(flow):
        x = np.floor(fl[..., 0])
        y = np.floor(fl[..., 1])
        ok = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x < W) & (y >= 0) & (y < H)
        yy, xx = np.nonzero(ok)
        d = np.abs(E[k + 1][y[ok].astype(int), x[ok].astype(int)] - E[k][yy, xx])
        terms.append(float(d.mean()) / norm if d.size else 0.0)
    return float(np.mean(terms)) if terms else math.nan
