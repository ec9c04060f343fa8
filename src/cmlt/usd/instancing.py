"""UsdGeom.PointInstancer: every instance renders its prototype subtree.

Its children are not rendered in place; every instance renders its prototype
subtree (nested instancers too) with ``world = instancer_world @ instance_xform
(incl. prototype root xform) @ relative_xform``. Masked (``invisibleIds`` /
``inactiveIds``) instances are skipped; visibility inside the prototype is
respected. Prototypes that live outside their instancer are removed from the
top-level traversal's result (:func:`drop_prototype_placements`).
"""
from __future__ import annotations

from typing import List

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from .camera import gf_to_np
from .stage import tstr

__all__ = ["point_instancer", "prototype_roots", "drop_prototype_placements"]


#: PointInstancer attributes whose time samples animate the instances
_PI_ATTRS = ("positions", "orientations", "orientationsf", "scales", "protoIndices",
             "ids", "invisibleIds", "velocities", "angularVelocities", "accelerations")

def point_instancer(fr, prim, root, outer, depth, outer_animated=False):
    """Render every instance of the PointInstancer ``prim`` (reached from ``root``
    under ``outer``, see :meth:`FrameReader.traverse`): its prototype subtree
    placed by the instance transform."""
    path = prim.GetPath()
    pi = UsdGeom.PointInstancer(prim)
    tc = fr.tc
    animated = outer_animated or \
        fr.xform_animated(prim, None if outer is None else root) or \
        any(prim.GetAttribute(a).ValueMightBeTimeVarying()
            for a in _PI_ATTRS if prim.GetAttribute(a))
    protos = pi.GetPrototypesRel().GetForwardedTargets()
    proto_prims = []
    for p in protos:
        pp = fr.stage.GetPrimAtPath(p)
        if not pp:
            fr.warn(f"{path}: prototype {p} does not exist; its instances are not rendered")
        proto_prims.append(pp if pp else None)
    indices = pi.GetProtoIndicesAttr().Get(tc)
    if indices is None or len(indices) == 0:
        return
    indices = np.asarray(indices, dtype=np.int64)
    mask = pi.ComputeMaskAtTime(tc)
    mask = np.ones(len(indices), bool) if mask is None or len(mask) != len(indices) \
        else np.asarray(mask, dtype=bool)
    bad = (indices < 0) | (indices >= len(proto_prims))
    if bad.any():
        fr.warn(f"{path}: protoIndices refers to prototype {int(indices[bad][0])} but "
                  f"prototypes has {len(proto_prims)} targets (time {tstr(tc)}); "
                  f"those instances are not rendered")
    if bad.all():
        return
    if bad.any():
        mats = _manual_instance_xforms(fr, pi, indices, bad, proto_prims)
    else:
        try:
            xforms = pi.ComputeInstanceTransformsAtTime(
                tc, tc, UsdGeom.PointInstancer.IncludeProtoXform,
                UsdGeom.PointInstancer.IgnoreMask)
        except Exception as exc:
            fr.warn(f"{path}: instance transforms cannot be computed (time {tstr(tc)}): "
                      f"{' '.join(str(exc).split())}; not rendered")
            return
        if xforms is None or len(xforms) != len(indices):
            fr.warn(f"{path}: positions/orientations/scales do not match protoIndices "
                      f"({len(indices)} instances, time {tstr(tc)}); not rendered")
            return
        mats = np.asarray(xforms, dtype=np.float64).reshape(-1, 4, 4)
        mats = np.transpose(mats, (0, 2, 1))
    if mats is None:
        return
    W = fr._world(prim, root, outer)
    for i in np.nonzero(mask & ~bad)[0]:
        pp = proto_prims[indices[i]]
        if pp is None:
            continue
        n_before = len(fr.instances)
        fr.traverse(pp, W @ mats[i], depth + 1, animated)
        for inst in fr.instances[n_before:]:
            inst.name = f"{path}[{i}]:{inst.name}"

def _manual_instance_xforms(fr, pi, indices, bad, proto_prims):
    """Instance transforms (column convention, prototype root xform
    included) from positions/orientations/scales, for when USD refuses
    to compute them (bad protoIndices). Velocities are not applied."""
    tc, n = fr.tc, len(indices)
    path = pi.GetPath()

    def arr(attr, width, default):
        v = attr.Get(tc) if attr else None
        if v is None or len(v) == 0:
            return np.tile(default, (n, 1))
        a = np.asarray(v, dtype=np.float64).reshape(-1, width)
        if len(a) != n:
            raise ValueError(attr.GetName())
        return a

    try:
        pos = arr(pi.GetPositionsAttr(), 3, [0.0, 0.0, 0.0])
        scl = arr(pi.GetScalesAttr(), 3, [1.0, 1.0, 1.0])
        ov = pi.GetOrientationsAttr().Get(tc)
        if ov is not None and len(ov):
            if len(ov) != n:
                raise ValueError("orientations")
            q = np.array([[o.GetReal(), *o.GetImaginary()] for o in ov], dtype=np.float64)
        else:
            q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    except ValueError as exc:
        fr.warn(f"{path}: {exc} does not match protoIndices ({n} instances, "
                  f"time {tstr(tc)}); not rendered")
        return None
    q /= np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-30)
    w, x, y, z = q.T
    R = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], 1)
    mats = np.zeros((n, 4, 4))
    mats[:, :3, :3] = R * scl[:, None, :]
    mats[:, :3, 3] = pos
    mats[:, 3, 3] = 1.0
    for k in range(len(proto_prims)):
        pp = proto_prims[k]
        if pp is None:
            continue
        local = gf_to_np(fr.xc.GetLocalTransformation(pp)[0])
        sel = (indices == k) & ~bad
        mats[sel] = mats[sel] @ local
    return mats


def prototype_roots(stage) -> List[Sdf.Path]:
    """Prototype roots of every PointInstancer (they never render in place)."""
    roots = []
    for prim in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()):
        if prim.IsA(UsdGeom.PointInstancer):
            roots.extend(UsdGeom.PointInstancer(prim).GetPrototypesRel().GetForwardedTargets())
    return roots


def drop_prototype_placements(fr, roots: List[Sdf.Path]):
    """Remove the in-place renders of PointInstancer prototypes found by the
    top-level traversal (prototypes that live outside their instancer)."""
    keep = []
    for inst in fr.instances:
        if "[" in inst.name:                         # placed by an instancer
            keep.append(inst)
            continue
        p = Sdf.Path(inst.name)
        if any(p.HasPrefix(r) for r in roots):
            continue
        keep.append(inst)
    fr.instances = keep
    used = {i.mesh for i in fr.instances}
    if len(used) < len(fr.meshes):
        remap, meshes = {}, []
        for i, m in enumerate(fr.meshes):
            if i in used:
                remap[i] = len(meshes)
                meshes.append(m)
        for inst in fr.instances:
            inst.mesh = remap[inst.mesh]
        fr.meshes = meshes
