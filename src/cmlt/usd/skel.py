"""UsdSkel: skinned meshes posed per frame with usd-core's own UsdSkel API.

For every ``SkelRoot`` a ``UsdSkel.Cache`` is populated once per stage
(``Populate(skelRoot, Usd.TraverseInstanceProxies())``) and its skinning
bindings are computed (``ComputeSkelBindings``): skeleton -> skinning
queries of the meshes it deforms. Per frame, for a bound mesh,

* ``SkeletonQuery.ComputeSkinningTransforms(time)`` gives the joints'
  skinning transforms (inverse bind * animated skel-space transform);
* ``SkinningQuery.ComputeSkinnedPoints(xforms, points, time)`` poses the
  authored points (geomBindTransform, joint indices/weights, the skinning
  method — linear blend or dual quaternion — all applied by USD).

The posed points are in *skeleton space*, so the mesh is placed by the
Skeleton prim's local-to-world transform (its own xformOps are ignored, as
UsdSkel specifies). Skinned meshes are ``deforming``. Authored normals are not
skinned (usd-core's Python API has no ComputeSkinnedNormals): a skinned mesh
with authored normals is shaded with smooth normals of its posed points.
Blend shapes are not applied (a warning says so). Meshes inside
PointInstancer prototypes are not skinned.
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

from pxr import Usd, UsdSkel

__all__ = ["SkelBindings"]


class SkelBindings:
    """Per stage: mesh prim path -> (SkeletonQuery, SkinningQuery)."""

    def __init__(self):
        self.cache = UsdSkel.Cache()
        self._roots: Dict[object, bool] = {}            # SkelRoot paths populated
        self._targets: Dict[object, Tuple] = {}
        self._root_of: Dict[object, object] = {}        # prim path -> SkelRoot path or None

    def _skel_root(self, prim):
        path = prim.GetPath()
        if path in self._root_of:
            r = self._root_of[path]
            return None if r is None else prim.GetStage().GetPrimAtPath(r)
        root = UsdSkel.Root.Find(prim)
        rp = root.GetPrim() if root else None
        self._root_of[path] = rp.GetPath() if rp else None
        return rp

    def lookup(self, prim) -> Optional[Tuple]:
        """(skeleton query, skinning query) of a skinned mesh, else None."""
        root = self._skel_root(prim)
        if root is None:
            return None
        rpath = root.GetPath()
        if rpath not in self._roots:
            skel_root = UsdSkel.Root(root)
            self.cache.Populate(skel_root, Usd.TraverseInstanceProxies())
            for b in self.cache.ComputeSkelBindings(skel_root, Usd.TraverseInstanceProxies()):
                sq = self.cache.GetSkelQuery(b.GetSkeleton())
                if not sq:
                    continue
                for target in b.GetSkinningTargets():
                    if target and target.HasJointInfluences():
                        self._targets[target.GetPrim().GetPath()] = (sq, target)
            self._roots[rpath] = True
        return self._targets.get(prim.GetPath())

    @staticmethod
    def skinned_points(sq, target, points, time, xforms=None):
        """Pose ``points`` (a Vt.Vec3fArray, modified in place) at ``time``;
        returns it, or None if USD cannot skin it."""
        if xforms is None:
            xforms = sq.ComputeSkinningTransforms(time)
        if xforms is None:
            return None
        if not target.ComputeSkinnedPoints(xforms, points, time):
            return None
        return points
