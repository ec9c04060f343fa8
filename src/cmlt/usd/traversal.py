"""The traversal of one time code of a stage: which prims render, and how.

Traversal rules
---------------
* Prims are visited with instance proxies, so every placement of an
  instanceable prototype is seen; its gprims are read once from the
  prototype (keyed by ``GetPrimInPrototype``) and shared between placements.
* ``visibility``: an invisible prim hides its subtree. ``purpose``: ``guide``
  is never rendered; ``proxy`` is rendered only where no sibling subtree of the
  proxy scope carries ``render`` purpose; default and ``render`` always are.
  ``--purpose LIST`` (``purposes``) replaces that rule: ``default`` and exactly
  the purposes listed render (husk's ``--purpose``).
* ``UsdGeom.PointInstancer``: see :mod:`cmlt.usd.instancing`.
* Each rendered gprim is one :class:`Instance` of one :class:`Mesh` (object
  space, scene units); ``Instance.transform`` is object -> world in metres.
"""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Tuple

import numpy as np
from pxr import Usd, UsdGeom, UsdLux

from ..scene import Instance, Mesh
from . import shapes
from .camera import condition_instance_transform, gf_to_np
from .errors import UsdLoadError
from .instancing import point_instancer
from .lights import read_light
from .materials import MaterialTable, subset_bindings
from .mesh import MeshReader, SkipPrim
from .mesh_primvars import shape_primvars
from .skel import SkelBindings
from .stage import (INTRINSIC_TYPES, MESH_TYPES, SUPPORTED_LIGHT_TYPES, UNREGISTERED_REASON,
                    ignored_reason, stage_file, stage_state, tstr, unregistered_type)

__all__ = ["FrameReader"]

_PROTO_PREDICATE = Usd.TraverseInstanceProxies(Usd.PrimIsActive & Usd.PrimIsLoaded)


class FrameReader:
    """The traversal of one :func:`cmlt.usd.load_frame` call and what it found:
    meshes, instances, lights, materials, warnings."""

    def __init__(self, stage, tc, warnings, purposes=None):
        self.stage = stage
        #: None: the default purpose rules (module docstring); else the purposes
        #: rendered besides ``default`` (``--purpose``), exactly
        self.purposes = None if purposes is None else frozenset(purposes)
        self.tc = tc
        self.warnings = warnings
        self.state = stage_state(stage)
        self.xc = UsdGeom.XformCache(tc)
        mpu = UsdGeom.GetStageMetersPerUnit(stage)
        if not (math.isfinite(mpu) and mpu > 0):
            warnings.append(f"{stage_file(stage)}: metersPerUnit is {mpu:g}; using 0.01")
            mpu = 0.01
        self.mpu = mpu
        self.S = np.diag([mpu, mpu, mpu, 1.0])
        self.materials = MaterialTable(tc, warnings)
        self.meshes: List[Mesh] = []
        self.instances = []
        self.lights = []
        self._mesh_index: Dict[object, int] = {}
        self._render_scope_cache: Dict[str, bool] = {}
        self._warned: set = set()
        self._skin_xforms: Dict[object, object] = {}
        # (Instance, prim whose world transform places it): animated top-level
        # instances, the candidates for transform motion blur
        self.motion_src: List[Tuple[Instance, object]] = []
        # prims of types no loaded schema defines, by type name (warned once per type)
        self.unregistered: Dict[str, Dict[str, None]] = {}

    def warn(self, msg: str):
        if msg not in self._warned:
            self._warned.add(msg)
            self.warnings.append(msg)

    def warn_unregistered(self, shown: int = 8):
        """One warning per unregistered prim type, naming its prims."""
        for type_name, found in self.unregistered.items():
            paths = list(found)
            names = ", ".join(paths[:shown])
            more = f" and {len(paths) - shown} more" if len(paths) > shown else ""
            self.warn(f"{stage_file(self.stage)}: {len(paths)} prim(s) of type {type_name}: "
                      f"{names}{more}: " + UNREGISTERED_REASON.format(type=type_name))

    # ---------------------------------------------------------- visibility
    def _hidden(self, prim) -> bool:
        """Own visibility/purpose of ``prim`` hides its subtree."""
        vis = prim.GetAttribute("visibility")
        if vis and vis.HasAuthoredValue() and vis.Get(self.tc) == UsdGeom.Tokens.invisible:
            return True
        pur = prim.GetAttribute("purpose")
        if pur and pur.HasAuthoredValue():
            p = pur.Get()
            if self.purposes is not None:
                return p != UsdGeom.Tokens.default_ and str(p) not in self.purposes
            if p == UsdGeom.Tokens.guide:
                return True
            if p == UsdGeom.Tokens.proxy and self._has_render_sibling(prim):
                return True
        return False

    def _has_render_sibling(self, prim) -> bool:
        parent = prim.GetParent()
        key = str(parent.GetPath())
        hit = self._render_scope_cache.get(key)
        if hit is None:
            hit = False
            for p in Usd.PrimRange(parent, _PROTO_PREDICATE):
                a = p.GetAttribute("purpose")
                if a and a.HasAuthoredValue() and a.Get() == UsdGeom.Tokens.render:
                    hit = True
                    break
            self._render_scope_cache[key] = hit
        return hit

    # ---------------------------------------------------------- skinning
    def _skinning(self, prim):
        """(skeleton query, skinning query) when UsdSkel deforms ``prim``."""
        if self.state.skel is None:
            self.state.skel = SkelBindings()
        return self.state.skel.lookup(prim)

    def _skinned_points(self, prim, skin, tc):
        sq, target = skin
        if target.HasBlendShapes():
            self.warn(f"{prim.GetPath()}: UsdSkel blend shapes are not applied")
        key = (sq.GetPrim().GetPath(), tc.GetValue() if not tc.IsDefault() else None)
        xforms = self._skin_xforms.get(key)
        if xforms is None:
            xforms = sq.ComputeSkinningTransforms(tc)
            self._skin_xforms[key] = xforms
        pts = UsdGeom.Mesh(prim).GetPointsAttr().Get(tc)
        if pts is None or xforms is None:
            return None
        return SkelBindings.skinned_points(sq, target, pts, tc, xforms)

    # ---------------------------------------------------------- time variance
    def xform_animated(self, prim, stop=None) -> bool:
        """Whether the transform of ``prim`` might vary in time: an xformOp of
        ``prim`` or of an ancestor (up to and including ``stop``, or up to the
        pseudo-root; a ``!resetXformStack!`` ends the walk) has time samples.
        From USD's own ``TransformMightBeTimeVarying``; cached per stage."""
        key = (prim.GetPath(), None if stop is None else stop.GetPath())
        hit = self.state.xform_anim.get(key)
        if hit is None:
            hit = False
            p = prim
            while p and not p.IsPseudoRoot():
                x = UsdGeom.Xformable(p)
                if x:
                    if x.TransformMightBeTimeVarying():
                        hit = True
                        break
                    if x.GetResetXformStack():
                        break
                if stop is not None and p == stop:
                    break
                p = p.GetParent()
            self.state.xform_anim[key] = hit
        return hit

    # ---------------------------------------------------------- traversal
    def traverse(self, root, outer: Optional[np.ndarray], depth: int = 0,
                 outer_animated: bool = False):
        """Visit ``root``'s subtree. ``outer`` None: top level (world
        transforms from the XformCache); else a PointInstancer prototype
        placed by the column matrix ``outer`` (scene units), which varies in
        time when ``outer_animated``."""
        if depth > 8:
            self.warn(f"{root.GetPath()}: point instancers nested deeper than 8; not rendered")
            return
        if outer is None:
            rng = Usd.PrimRange(root, Usd.TraverseInstanceProxies())
        else:
            rng = Usd.PrimRange(root, _PROTO_PREDICATE)
        it = iter(rng)
        for prim in it:
            if prim.IsPseudoRoot():
                continue
            try:
                if self._hidden(prim):
                    it.PruneChildren()
                    continue
                t = str(prim.GetTypeName())
                if prim.IsA(UsdGeom.PointInstancer):
                    it.PruneChildren()
                    point_instancer(self, prim, root, outer, depth, outer_animated)
                    continue
                if t in MESH_TYPES or t in INTRINSIC_TYPES:
                    if prim.HasAPI(UsdLux.LightAPI) or prim.HasAPI(UsdLux.MeshLightAPI):
                        self.warn(f"{prim.GetPath()}: mesh lights (LightAPI on a gprim) are not "
                                  f"supported; rendered as plain geometry, not emitting")
                    self._gprim(prim, t, root, outer, outer_animated)
                    continue
                if t in SUPPORTED_LIGHT_TYPES:
                    if outer is None:
                        self._light(prim)
                    else:
                        self.warn(f"{prim.GetPath()}: lights inside point-instancer prototypes "
                                  f"are not supported and are not rendered")
                    continue
                if unregistered_type(prim):
                    # one warning per type after the traversal (there may be many)
                    self.unregistered.setdefault(t, {})[str(prim.GetPath())] = None
                    continue
                reason = ignored_reason(prim)
                if reason:
                    self.warn(f"{prim.GetPath()}: {reason}")
                    if prim.IsA(UsdGeom.Gprim):
                        it.PruneChildren()
            except SkipPrim as exc:
                self.warn(str(exc))
            except UsdLoadError:
                raise
            except Exception as exc:                      # USD/Tf errors on odd data
                msg = " ".join(str(exc).split())
                self.warn(f"{prim.GetPath()}: cannot be read (time {tstr(self.tc)}): {msg}; "
                          f"not rendered")

    def _world(self, prim, root, outer) -> np.ndarray:
        """Object -> world (scene units, column convention)."""
        if outer is None:
            return gf_to_np(self.xc.GetLocalToWorldTransform(prim))
        if prim == root:
            return outer
        rel, _ = self.xc.ComputeRelativeTransform(prim, root)
        return outer @ gf_to_np(rel)

    # ---------------------------------------------------------- gprims
    def _gprim(self, prim, type_name, root, outer, outer_animated=False):
        path = prim.GetPath()
        src = prim.GetPrimInPrototype() if prim.IsInstanceProxy() else prim
        key = str(src.GetPath())
        skin = None
        if type_name == "Mesh":
            reader = self.state.mesh_cache.get(key)
            if reader is None or not isinstance(reader, MeshReader):
                uv_name, uv_fallback, uv_reader = self.materials.uv_primvar(prim)
                reader = MeshReader(src, uv_name, uv_fallback=uv_fallback, uv_reader=uv_reader,
                                    primvar_requests=self.materials.primvar_requests(prim))
                self.state.mesh_cache[key] = reader
            skin = self._skinning(prim) if outer is None else None
            posed = self._skinned_points(prim, skin, self.tc) if skin is not None else None
            if skin is not None and posed is None:
                self.warn(f"{path}: UsdSkel cannot skin it (time {tstr(self.tc)}); "
                          f"rendered in its authored points")
                skin = None
            geom = reader.read(src, self.tc, skinned_points=posed)
        else:
            skey, varying = shapes.shape_key(src, self.tc)
            geom = self.state.shape_cache.get(skey)
            if geom is None:
                geom = shapes.tessellate(src, self.tc)
                geom.deforming = bool(varying)
                if not varying:
                    self.state.shape_cache[skey] = geom
        for w in geom.warnings:
            self.warn(w if not prim.IsInstanceProxy() else w.replace(key, str(path), 1))

        # materials: per prim, or per face through GeomSubsets
        base = self.materials.for_prim(prim)
        subsets = subset_bindings(prim, self.tc) if type_name == "Mesh" else []
        if subsets and geom.tri_face is not None:
            n_faces = len(UsdGeom.Mesh(src).GetFaceVertexCountsAttr().Get(self.tc) or [])
            face_mat = np.full(n_faces, base, dtype=np.uint32)
            sig = [base]
            for idx, mat in subsets:
                mi = self.materials.material(mat)
                idx = np.asarray(idx, dtype=np.int64)
                bad = (idx < 0) | (idx >= n_faces)
                if bad.any():
                    self.warn(f"{path}: GeomSubset of {mat.GetPath()} refers to face "
                              f"{int(idx[bad][0])} but the mesh has {n_faces} faces "
                              f"(time {tstr(self.tc)}); ignored")
                face_mat[idx[~bad]] = mi
                sig.append((mi, idx.tobytes()))
            msig = hash(tuple(sig))
            mkey = (key, id(geom), msig)
        else:
            msig = base
            mkey = (key, id(geom), base)
        mi = self._mesh_index.get(mkey)
        if mi is None:
            # one material-id array per (gprim, binding, triangulation): a
            # static mesh hands the bridge the same array object every frame
            ckey = (key, msig)
            cached = self.state.material_ids_cache.get(ckey)
            tri_face = geom.tri_face if geom.tri_face is not None else geom.indices
            if cached is not None and cached[0] is tri_face:
                mat_ids = cached[1]
            else:
                if subsets and geom.tri_face is not None:
                    mat_ids = face_mat[geom.tri_face]
                else:
                    mat_ids = np.full(len(geom.indices), base, dtype=np.uint32)
                mat_ids = np.ascontiguousarray(mat_ids, dtype=np.uint32)
                self.state.material_ids_cache[ckey] = (tri_face, mat_ids)
            mi = len(self.meshes)
            pvs = geom.primvars if type_name == "Mesh" else shape_primvars(
                src, self.materials.primvar_requests(prim), len(geom.points), self.tc, self.warn)
            self.meshes.append(Mesh(name=str(path), points=geom.points, indices=geom.indices,
                                    normals=geom.normals, uvs=geom.uvs,
                                    material_ids=mat_ids,
                                    deforming=geom.deforming, primvars=pvs))
            self._mesh_index[mkey] = mi
        if skin is not None:
            # skinned points are in skeleton space: placed by the Skeleton prim
            skel_prim = skin[0].GetPrim()
            world = gf_to_np(self.xc.GetLocalToWorldTransform(skel_prim))
            animated = self.xform_animated(skel_prim)
            place = skel_prim
        else:
            world = self._world(prim, root, outer)
            animated = outer_animated or self.xform_animated(prim, None if outer is None else root)
            place = prim
        n_before = len(self.instances)
        self._add_instance(str(path), mi, world, animated)
        if animated and outer is None and len(self.instances) > n_before:
            self.motion_src.append((self.instances[-1], place))

    def _add_instance(self, name, mesh_index, world, animated=True):
        m, note = condition_instance_transform(self.S @ world)
        if m is None:
            self.warn(f"{name}: transform {note} (time {tstr(self.tc)}); not rendered")
            return
        if note:
            self.warn(f"{name}: transform {note} (time {tstr(self.tc)})")
        self.instances.append(Instance(name=name, mesh=mesh_index, transform=m,
                                       animated=bool(animated)))


    # ---------------------------------------------------------- lights
    def _light(self, prim):
        world = self.S @ gf_to_np(self.xc.GetLocalToWorldTransform(prim))
        light = read_light(prim, self.tc, world, self.warnings)
        if light is not None:
            self.lights.append(light)
