"""One time code of a stage -> :class:`cmlt.scene.FrameScene`.

Traversal rules
---------------
* Prims are visited with instance proxies, so every placement of an
  instanceable prototype is seen; its gprims are read once from the
  prototype (keyed by ``GetPrimInPrototype``) and shared between placements.
* ``visibility``: an invisible prim hides its subtree. ``purpose``: ``guide``
  is never rendered; ``proxy`` is rendered only where no sibling subtree of the
  proxy scope carries ``render`` purpose; default and ``render`` always are.
* ``UsdGeom.PointInstancer``: its children are not rendered in place; every
  instance renders its prototype subtree (nested instancers too) with
  ``world = instancer_world @ instance_xform (incl. prototype root xform) @
  relative_xform``. Masked (``invisibleIds``/``inactiveIds``) instances are
  skipped; visibility inside the prototype is respected.
* Each rendered gprim is one :class:`Instance` of one :class:`Mesh` (object
  space, scene units); ``Instance.transform`` is object -> world in metres.
"""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Tuple

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdLux, UsdRender

from ..scene import FrameScene, Instance, Mesh
from . import shapes
from .camera import framing_camera, gf_to_np, read_camera
from .errors import UsdLoadError
from .lights import default_dome, read_light
from .materials import MaterialTable, subset_bindings
from .mesh import MeshReader, SkipPrim, shape_primvars
from .skel import SkelBindings
from .stage import (INTRINSIC_TYPES, MESH_TYPES, SUPPORTED_LIGHT_TYPES, UNREGISTERED_REASON,
                    _stage_file, check_time_metadata, composition_warnings, ignored_reason,
                    settings_camera_problem, stage_state, unregistered_type)

DEFAULT_RESOLUTION = (640, 480)
_PROTO_PREDICATE = Usd.TraverseInstanceProxies(Usd.PrimIsActive & Usd.PrimIsLoaded)


def _time_code(stage, time) -> Usd.TimeCode:
    if isinstance(time, Usd.TimeCode):
        tc = time
    elif time is None:
        tc = Usd.TimeCode.Default()
    else:
        try:
            t = float(time)
        except (TypeError, ValueError):
            raise UsdLoadError(f"{_stage_file(stage)}: time {time!r} is not a number") from None
        if not math.isfinite(t):
            raise UsdLoadError(f"{_stage_file(stage)}: time {t} is not finite")
        tc = Usd.TimeCode(t)
    return tc


def _tstr(tc) -> str:
    return "default" if tc.IsDefault() else f"{tc.GetValue():g}"


class _Frame:
    """State of one load_frame call."""

    def __init__(self, stage, tc, warnings):
        self.stage = stage
        self.tc = tc
        self.warnings = warnings
        self.state = stage_state(stage)
        self.xc = UsdGeom.XformCache(tc)
        mpu = UsdGeom.GetStageMetersPerUnit(stage)
        if not (math.isfinite(mpu) and mpu > 0):
            warnings.append(f"{_stage_file(stage)}: metersPerUnit is {mpu:g}; using 0.01")
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
            self.warn(f"{_stage_file(self.stage)}: {len(paths)} prim(s) of type {type_name}: "
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
                    self._point_instancer(prim, root, outer, depth, outer_animated)
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
                self.warn(f"{prim.GetPath()}: cannot be read (time {_tstr(self.tc)}): {msg}; "
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
                self.warn(f"{path}: UsdSkel cannot skin it (time {_tstr(self.tc)}); "
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
                              f"(time {_tstr(self.tc)}); ignored")
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
        m = self.S @ world
        if not np.isfinite(m).all():
            self.warn(f"{name}: transform is not finite (time {_tstr(self.tc)}); not rendered")
            return
        self.instances.append(Instance(name=name, mesh=mesh_index, transform=m,
                                       animated=bool(animated)))

    # ---------------------------------------------------------- instancers
    _PI_ATTRS = ("positions", "orientations", "orientationsf", "scales", "protoIndices",
                 "ids", "invisibleIds", "velocities", "angularVelocities", "accelerations")

    def _point_instancer(self, prim, root, outer, depth, outer_animated=False):
        path = prim.GetPath()
        pi = UsdGeom.PointInstancer(prim)
        tc = self.tc
        animated = outer_animated or \
            self.xform_animated(prim, None if outer is None else root) or \
            any(prim.GetAttribute(a).ValueMightBeTimeVarying()
                for a in self._PI_ATTRS if prim.GetAttribute(a))
        protos = pi.GetPrototypesRel().GetForwardedTargets()
        proto_prims = []
        for p in protos:
            pp = self.stage.GetPrimAtPath(p)
            if not pp:
                self.warn(f"{path}: prototype {p} does not exist; its instances are not rendered")
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
            self.warn(f"{path}: protoIndices refers to prototype {int(indices[bad][0])} but "
                      f"prototypes has {len(proto_prims)} targets (time {_tstr(tc)}); "
                      f"those instances are not rendered")
        if bad.all():
            return
        if bad.any():
            mats = self._manual_instance_xforms(pi, indices, bad, proto_prims)
        else:
            try:
                xforms = pi.ComputeInstanceTransformsAtTime(
                    tc, tc, UsdGeom.PointInstancer.IncludeProtoXform,
                    UsdGeom.PointInstancer.IgnoreMask)
            except Exception as exc:
                self.warn(f"{path}: instance transforms cannot be computed (time {_tstr(tc)}): "
                          f"{' '.join(str(exc).split())}; not rendered")
                return
            if xforms is None or len(xforms) != len(indices):
                self.warn(f"{path}: positions/orientations/scales do not match protoIndices "
                          f"({len(indices)} instances, time {_tstr(tc)}); not rendered")
                return
            mats = np.asarray(xforms, dtype=np.float64).reshape(-1, 4, 4)
            mats = np.transpose(mats, (0, 2, 1))
        if mats is None:
            return
        W = self._world(prim, root, outer)
        for i in np.nonzero(mask & ~bad)[0]:
            pp = proto_prims[indices[i]]
            if pp is None:
                continue
            n_before = len(self.instances)
            self.traverse(pp, W @ mats[i], depth + 1, animated)
            for inst in self.instances[n_before:]:
                inst.name = f"{path}[{i}]:{inst.name}"

    def _manual_instance_xforms(self, pi, indices, bad, proto_prims):
        """Instance transforms (column convention, prototype root xform
        included) from positions/orientations/scales, for when USD refuses
        to compute them (bad protoIndices). Velocities are not applied."""
        tc, n = self.tc, len(indices)
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
            self.warn(f"{path}: {exc} does not match protoIndices ({n} instances, "
                      f"time {_tstr(tc)}); not rendered")
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
            local = gf_to_np(self.xc.GetLocalTransformation(pp)[0])
            sel = (indices == k) & ~bad
            mats[sel] = mats[sel] @ local
        return mats

    # ---------------------------------------------------------- lights
    def _light(self, prim):
        world = self.S @ gf_to_np(self.xc.GetLocalToWorldTransform(prim))
        light = read_light(prim, self.tc, world, self.warnings)
        if light is not None:
            self.lights.append(light)


def _collect_prototype_roots(stage) -> List[Sdf.Path]:
    """Prototype roots of every PointInstancer (they never render in place)."""
    roots = []
    for prim in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()):
        if prim.IsA(UsdGeom.PointInstancer):
            roots.extend(UsdGeom.PointInstancer(prim).GetPrototypesRel().GetForwardedTargets())
    return roots


def _find_cameras(stage) -> List:
    return [p for p in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies())
            if p.IsA(UsdGeom.Camera)]


def _render_settings(stage, render_settings) -> Optional[UsdRender.Settings]:
    if render_settings is not None:
        path = str(render_settings)
        prim = stage.GetPrimAtPath(path) if Sdf.Path.IsValidPathString(path) else None
        if not prim or not prim.IsA(UsdRender.Settings):
            raise UsdLoadError(f"{_stage_file(stage)}: render settings {path} "
                               f"{'is not a RenderSettings prim' if prim else 'does not exist'}")
        return UsdRender.Settings(prim)
    try:
        s = UsdRender.Settings.GetStageRenderSettings(stage)
    except Exception:                                   # pragma: no cover
        s = None
    if s and s.GetPrim().IsValid():
        return s
    for prim in stage.Traverse():
        if prim.IsA(UsdRender.Settings):
            return UsdRender.Settings(prim)
    return None


def _bounds(fr: _Frame) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    by_mesh: Dict[int, List[np.ndarray]] = {}
    for inst in fr.instances:
        by_mesh.setdefault(inst.mesh, []).append(inst.transform)
    for mi, xs in by_mesh.items():
        p = fr.meshes[mi].points
        used = np.zeros(len(p), dtype=bool)
        used[fr.meshes[mi].indices.reshape(-1)] = True
        p = p[used] if not used.all() else p
        plo, phi = p.min(axis=0).astype(np.float64), p.max(axis=0).astype(np.float64)
        corners = np.array([[x, y, z, 1.0] for x in (plo[0], phi[0])
                            for y in (plo[1], phi[1]) for z in (plo[2], phi[2])])
        X = np.asarray(xs)                                  # (k, 4, 4)
        w = np.einsum("kij,cj->kci", X, corners)[..., :3].reshape(-1, 3)
        lo, hi = np.minimum(lo, w.min(axis=0)), np.maximum(hi, w.max(axis=0))
    if not np.isfinite(lo).all():
        return None
    return lo, hi


def load_frame(stage, time, camera=None, resolution=None, render_settings=None) -> FrameScene:
    try:
        return _load_frame(stage, time, camera, resolution, render_settings)
    except Tf.ErrorException as exc:          # USD refused the data outside any one prim
        msg = " ".join(str(exc).split())
        raise UsdLoadError(f"{_stage_file(stage)}: time {time}: {msg}") from None




def _load_frame(stage, time, camera=None, resolution=None, render_settings=None) -> FrameScene:
    """Read the render scene of ``stage`` at the time code ``time``.

    ``camera``: a camera prim path (UsdLoadError if it is not a Camera);
    default: the RenderSettings camera, else the first camera (warning if
    several), else a framing camera (warning). ``resolution``: (w, h),
    overriding the RenderSettings resolution (default 640x480).
    ``render_settings``: a RenderSettings prim path; default: the stage's
    ``renderSettingsPrimPath`` metadata, else the first RenderSettings prim.
    Non-fatal problems are listed in ``FrameScene.warnings``, each naming its
    prim; fatal ones raise :class:`UsdLoadError`.
    """
    if stage is None:
        raise UsdLoadError("load_frame: no stage")
    check_time_metadata(stage)
    tc = _time_code(stage, time)
    warnings: List[str] = []
    state = stage_state(stage)
    for w in state.open_warnings + composition_warnings(stage):
        if w not in warnings:
            warnings.append(w)
    fr = _Frame(stage, tc, warnings)
    up = str(UsdGeom.GetStageUpAxis(stage))

    # settings, camera path (validated before the expensive traversal)
    settings = _render_settings(stage, render_settings)
    res = None
    cam_path = None
    if settings is not None:
        r = settings.GetResolutionAttr().Get(tc)
        if r is not None:
            res = (int(r[0]), int(r[1]))
        targets = settings.GetCameraRel().GetForwardedTargets()
        if targets and camera is None:
            cam_path = targets[0]
    if resolution is not None:
        try:
            res = (int(resolution[0]), int(resolution[1]))
        except (TypeError, ValueError, IndexError):
            raise UsdLoadError(f"resolution {resolution!r} is not (width, height)") from None
    if res is None:
        res = DEFAULT_RESOLUTION
    if res[0] <= 0 or res[1] <= 0:
        raise UsdLoadError(f"{_stage_file(stage)}: resolution {res[0]}x{res[1]} must be positive")

    cam_prim = None
    if camera is not None:
        path = str(camera)
        prim = stage.GetPrimAtPath(path) if Sdf.Path.IsValidPathString(path) and \
            Sdf.Path(path).IsAbsolutePath() else None
        if not prim:
            raise UsdLoadError(f"{_stage_file(stage)}: camera {path} does not exist")
        if not prim.IsA(UsdGeom.Camera):
            raise UsdLoadError(f"{_stage_file(stage)}: camera {path} is a "
                               f"{prim.GetTypeName() or 'typeless prim'}, not a Camera")
        cam_prim = prim
    elif cam_path is not None:
        problem = settings_camera_problem(stage, settings)
        if problem:
            warnings.append(problem)            # does not exist / is not a Camera
        else:
            cam_prim = stage.GetPrimAtPath(cam_path)

    # geometry, lights, materials
    proto_roots = _collect_prototype_roots(stage)
    fr.traverse(stage.GetPseudoRoot(), None)
    fr.warn_unregistered()
    if proto_roots:
        _drop_prototype_placements(fr, proto_roots)

    if not fr.lights and not fr.materials.has_emission():
        fr.lights.append(default_dome())
        warnings.append(f"{_stage_file(stage)}: the stage has no lights and no emissive "
                        f"materials; adding a white dome light (radiance 1)")

    # camera
    if cam_prim is None:
        cams = _find_cameras(stage)
        if cams:
            cam_prim = cams[0]
            if len(cams) > 1:
                warnings.append(f"{_stage_file(stage)}: {len(cams)} cameras and none chosen; "
                                f"using the first, {cam_prim.GetPath()}")
    if cam_prim is not None:
        world = fr.S @ gf_to_np(fr.xc.GetLocalToWorldTransform(cam_prim))
        cam = read_camera(cam_prim, tc, fr.mpu, world, warnings)
    else:
        cam = framing_camera(_bounds(fr), up, res)
        warnings.append(f"{_stage_file(stage)}: no camera; using a framing camera "
                        f"({'+Y' if up == 'Z' else '-Z'} view of the stage bounds)")

    blur, blur_reason, blur_times = _shutter_motion(fr, cam, tc)
    ftime = float(stage.GetStartTimeCode()) if tc.IsDefault() else float(tc.GetValue())
    return FrameScene(time=ftime, motion_blur=blur, motion_blur_reason=blur_reason,
                      motion_times=blur_times,
                      meshes=fr.meshes, instances=fr.instances,
                      materials=fr.materials.materials or [],
                      lights=fr.lights, camera=cam, resolution=res,
                      meters_per_unit=fr.mpu, up_axis=up, warnings=warnings,
                      static_signature=static_signature(fr.meshes, fr.instances))


#: most time steps of a motion-blurred transform (Embree allows 129)
MAX_MOTION_STEPS = 17


def _shutter_motion(fr: _Frame, cam, tc) -> Tuple[bool, str, List[float]]:
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
        steps = [fr.S @ gf_to_np(xc.GetLocalToWorldTransform(prim)) for xc in caches]
        if not all(np.isfinite(m).all() for m in steps):
            continue
        if any(not np.array_equal(steps[0], m) for m in steps[1:]):
            inst.motion_transforms = steps
            moving += 1
    if not moving:
        return False, f"off: shutter open [{o:g}, {c:g}] but nothing moves within it", []
    return True, (f"on: shutter open [{o:g}, {c:g}], {moving} instance(s) move within it; "
                  f"{n} time steps"), times


def static_signature(meshes, instances) -> Tuple:
    """The structure of a frame (see ``FrameScene.static_signature``)."""
    return (tuple((m.name, len(m.points), len(m.indices), m.normals is None, m.uvs is None,
                   bool(m.deforming)) for m in meshes),
            tuple((i.name, int(i.mesh), bool(i.animated)) for i in instances))


def _drop_prototype_placements(fr: _Frame, roots: List[Sdf.Path]):
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


load_frame.__doc__ = _load_frame.__doc__
