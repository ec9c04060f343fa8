"""Transform motion blur over the camera shutter."""
from __future__ import annotations

from typing import List, Tuple

import numpy as np
from pxr import Gf, Usd, UsdGeom

from .camera import condition_instance_transform, gf_to_np

__all__ = ["shutter_motion", "MAX_MOTION_STEPS"]


#: most time steps of a motion-blurred transform (Embree allows 129)
MAX_MOTION_STEPS = 17


def shutter_motion(fr, cam, tc) -> Tuple[bool, str, List[float]]:
    """Transform motion blur over the camera shutter.

    On only when the shutter is open (``shutter:close > shutter:open``, time
    codes relative to the frame) and an animated instance's world transform
    differs between the time steps. The steps are evenly spaced over
    [frame + open, frame + close] (Embree's time steps are uniform): 2, plus
    one per authored xformOp time sample strictly inside the interval (so a
    sampled curve inside the shutter is followed), at most MAX_MOTION_STEPS.
    Sets ``Instance.motion_transforms`` of the moving instances; returns
    (on, reason, step time codes). Limits: instances placed by point
    instancers and the camera itself are not blurred; deforming points are
    not blurred (they use the frame's points)."""
    if cam is None or tc.IsDefault():
        return False, "off: no frame time code", []
    o, c = float(cam.shutter_open), float(cam.shutter_close)
    if not (c > o):
        return False, f"off: shutter closed (shutter:open {o:g}, shutter:close {c:g})", []
    kept = {id(i) for i in fr.instances}
    src = [(inst, prim) for inst, prim in fr.motion_src if id(inst) in kept]
    if not src:
        return False, f"off: shutter open [{o:g}, {c:g}] but nothing is animated", []
    t = float(tc.GetValue())
    t0, t1 = t + o, t + c
    interval = Gf.Interval(t0, t1)
    inner = set()
    seen = set()
    for _, prim in src:
        p = prim
        while p and not p.IsPseudoRoot() and p.GetPath() not in seen:
            seen.add(p.GetPath())
            x = UsdGeom.Xformable(p)
            if x:
                for s in x.GetTimeSamplesInInterval(interval):
                    if t0 < s < t1:
                        inner.add(round(s, 9))
                if x.GetResetXformStack():
                    break
            p = p.GetParent()
    n = min(2 + len(inner), MAX_MOTION_STEPS)
    times = [t0 + (t1 - t0) * k / (n - 1) for k in range(n)]
    caches = [UsdGeom.XformCache(Usd.TimeCode(tk)) for tk in times]
    moving = 0
    for inst, prim in src:
        steps = [condition_instance_transform(fr.S @ gf_to_np(xc.GetLocalToWorldTransform(prim)))[0]
                 for xc in caches]
        if any(m is None for m in steps):       # the frame's own transform is warned about
            continue
        if any(not np.array_equal(steps[0], m) for m in steps[1:]):
            inst.motion_transforms = steps
            moving += 1
    if not moving:
        return False, f"off: shutter open [{o:g}, {c:g}] but nothing moves within it", []
    return True, (f"on: shutter open [{o:g}, {c:g}], {moving} instance(s) move within it; "
                  f"{n} time steps"), times
