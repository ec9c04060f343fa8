"""FrameScene (:mod:`cmlt.scene`) -> ``cmlt._core.Scene``, frame after frame.

The first frame builds the core scene. Each following frame sends only what
can have changed, as the USD reader decided from the time samples
(``attr.ValueMightBeTimeVarying()``, ``TransformMightBeTimeVarying()`` on the
prim and its ancestors):

* a static instance (``Instance.animated`` False) or a static mesh
  (``Mesh.deforming`` False) is never looked at again after the first frame;
* an animated instance -> ``set_instance_transform`` (skipped when its 16
  numbers equal the last ones: a held key costs no top-level commit);
* a deforming mesh -> ``update_mesh_points`` (the core refits that mesh's BVH
  only; skipped when the points and normals equal the last ones);
* materials that differ -> ``set_materials``;
* lights and the camera are cheap and always re-set.

Motion blur: an instance with ``motion_transforms`` (the reader sets them
only when the shutter is open and the instance moves within it) gets its
time steps with ``set_instance_motion``; an instance that stops moving goes
back to one step. Nothing else changes, so a frame without motion costs
nothing extra (the core samples ray times only when some instance moves).

The scene is rebuilt from scratch when its structure changes. Counts and
names of meshes and instances are compared, then a cheap per-mesh check:
point/triangle counts, and indices, UVs and material ids by *identity* (the
reader hands a static mesh the very same arrays every frame) with an element
comparison only when the arrays are new objects (hand-built scenes, animated
topology); last the reader's ``FrameScene.static_signature`` (names, counts
and static/animated flags). Hand-built scenes without flags stay safe:
``Instance.animated`` defaults to True, so their transforms are compared.

:meth:`SceneBridge.last_update` says what the last :meth:`update` did, for
the sidecar and the tests.
"""
from __future__ import annotations

import contextlib

from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from ..scene import FrameScene, Mesh, padded_points
from .material_table import (IDENTITY_ST_TRANSFORM, BridgeError, material_params, primvar_array,
                             primvar_layout, resolve_wrap_modes, texture_channel)

__all__ = ["SceneBridge", "UpdateReport", "BridgeError"]


@contextlib.contextmanager
def _naming(core, prim: str, what: str):
    """A core refusal (SceneError, or a binding's ValueError/TypeError) inside the
    block becomes a BridgeError naming the prim: the core's messages name its call
    (``add_light: radiance must be finite and >= 0``), which means nothing to a user
    who authored ``/World/Lamp``."""
    errors = tuple(e for e in (getattr(core, "SceneError", None), ValueError, TypeError) if e)
    try:
        yield
    except BridgeError as exc:
        if str(exc).startswith(prim + ":"):
            raise
        raise BridgeError(f"{prim}: {what}: {exc}") from None
    except errors as exc:
        msg = str(exc)
        call, sep, rest = msg.partition(": ")
        if sep and call.replace("_", "").isalpha():
            msg = rest                          # the core call's name: said by `what`
        raise BridgeError(f"{prim}: {what}: {msg}") from None


def _material_error(core, materials, exc) -> "BridgeError":
    """set_materials' refusal naming the material (``emission[3] must be ...``:
    the 4th material of the frame)."""
    import re
    msg = str(exc)
    call, sep, rest = msg.partition(": ")
    if sep and call.replace("_", "").isalpha():
        msg = rest
    m = re.match(r"^(\w+)\[(\d+)\]\s*(.*)$", msg)
    if m and materials and int(m.group(2)) < len(materials):
        return BridgeError(f"{materials[int(m.group(2))].name}: material {m.group(1)} "
                           f"{m.group(3)}")
    return BridgeError(f"materials: {msg}")


@dataclass
class UpdateReport:
    rebuilt: bool = False
    reason: str = ""
    transforms_updated: int = 0        # set_instance_transform calls
    meshes_updated: int = 0            # update_mesh_points calls
    materials_updated: bool = False
    static_instances: int = 0          # skipped without a look (not animated)
    static_meshes: int = 0             # skipped without a look (not deforming)
    animated_instances: int = 0        # looked at (updated or equal to the last frame)
    deforming_meshes: int = 0          # looked at (updated or equal to the last frame)
    motion_blurred: int = 0            # instances with shutter time steps
    motion_blur: bool = False          # the core samples a ray time per camera sample
    lights_camera_changed: bool = True  # a light or the camera differs from the last frame's

    @property
    def unchanged(self) -> bool:
        """The core scene is the last frame's: nothing rebuilt or updated, no instance
        moving within the shutter, the same lights and camera."""
        return not (self.rebuilt or self.transforms_updated or self.meshes_updated
                    or self.materials_updated or self.motion_blurred
                    or self.lights_camera_changed)

    def as_dict(self) -> dict:
        return {
            "rebuilt": self.rebuilt, "reason": self.reason,
            "transforms_updated": self.transforms_updated,
            "meshes_updated": self.meshes_updated,
            "materials_updated": self.materials_updated,
            "static_instances": self.static_instances,
            "static_meshes": self.static_meshes,
            "animated_instances": self.animated_instances,
            "deforming_meshes": self.deforming_meshes,
            "motion_blurred": self.motion_blurred,
            "motion_blur": self.motion_blur,
            "lights_camera_changed": self.lights_camera_changed,
        }


def _optional_equal(a: Optional[np.ndarray], b: Optional[np.ndarray]) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and np.array_equal(a, b)


def _same(new, old_src, old) -> bool:
    """``new`` is the array last seen (identity: O(1)) or equal to it."""
    if new is old_src:
        return True
    return _optional_equal(None if new is None else np.asarray(new), old)


def _material_ids(ids) -> Optional[np.ndarray]:
    """The per-triangle material ids as the core takes them: uint32, and one entry for a
    mesh whose triangles all share a material (no 4 bytes per triangle then)."""
    if ids is None:
        return None
    ids = np.ascontiguousarray(np.asarray(ids, dtype=np.uint32).reshape(-1))
    if len(ids) > 1 and (ids == ids[0]).all():
        return ids[:1].copy()
    return ids


def _topology_key(mesh: Mesh) -> Tuple:
    return (
        mesh.name,
        int(np.asarray(mesh.points).reshape(-1, 3).shape[0]),
        mesh.normals is None,
        mesh.uvs is None,
    )


@dataclass
class _MeshState:
    key: Tuple
    points: np.ndarray
    normals: Optional[np.ndarray]
    indices: np.ndarray
    uvs: Optional[np.ndarray]
    material_ids: Optional[np.ndarray]
    # the FrameScene's own arrays last seen (identity checks)
    src: Tuple = (None, None, None)      # (indices, uvs, material_ids)
    primvars: Optional[np.ndarray] = None   # the (N, K) array handed to the core
    primvars_src: object = None             # the Mesh.primvars dict it came from


def _f32(a, cols: int) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float32).reshape(-1, cols))


def _mat(m) -> np.ndarray:
    t = np.ascontiguousarray(np.asarray(m, dtype=np.float64))
    if t.shape != (4, 4):
        raise BridgeError(f"transform must be 4x4, got shape {t.shape}")
    return t


class SceneBridge:
    """Keeps one ``core.Scene`` in step with a sequence of FrameScenes."""

    def __init__(self, core=None):
        if core is None:
            import cmlt._core as core          # noqa: F811 - imported lazily
        self._core = core
        self.scene = None
        self._meshes: List[_MeshState] = []
        self._mesh_ids: List[int] = []
        self._instances: List[Tuple[str, int]] = []
        self._instance_ids: List[int] = []
        self._transforms: List[np.ndarray] = []
        self._materials: Optional[Tuple[np.ndarray, np.ndarray]] = None
        self._textures: dict = {}               # texture key -> core id (None: unreadable)
        self._texture_arrays: list = []         # arrays shared with the core (zero copy)
        self._lights_camera: Optional[tuple] = None  # what the last frame's were given
        self._signature = None
        self._moving: List[bool] = []           # per instance: has shutter time steps
        self._layout: dict = {}                 # primvar_layout of the materials
        self.last_update = UpdateReport()

    # -- helpers ---------------------------------------------------------
    def _material_arrays(self, fs: FrameScene) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(diffuse, emission, params): every UsdPreviewSurface field of every
        material (the full model, also for a material with only a diffuse colour)."""
        mats = fs.materials
        if not mats:
            # The core wants at least one material; the USD reader always
            # provides a fallback, a hand-built scene may not.
            from ..scene import Material
            mats = [Material(name="<default>")]
        diffuse = np.array([m.diffuse for m in mats], dtype=np.float32).reshape(-1, 3)
        emission = np.array([m.emission for m in mats], dtype=np.float32).reshape(-1, 3)
        cols = {k: c for k, (c, _, _) in self._layout.items()} if self._layout else None
        params = np.stack([material_params(m, self._texture_ids(m), cols) for m in mats])
        return diffuse, emission, np.ascontiguousarray(params, dtype=np.float32)

    def _texture_ids(self, m) -> dict:
        """{input name: (core texture id, channel)} for the material's texture
        inputs; each (file, colour space, wrap, scale, bias, st transform) is
        loaded once per core scene. A file that cannot be read gives a warning naming the
        material and the file, and the input keeps its fallback constant."""
        out = {}
        for name, rec in (m.inputs or {}).items():
            if not (isinstance(rec, dict) and "texture" in rec):
                continue
            path = rec.get("texture")
            cs = "raw" if name == "normal" else (rec.get("sourceColorSpace") or "auto")
            key = (path, cs, str(rec.get("wrapS")), str(rec.get("wrapT")),
                   tuple(rec.get("scale") or (1, 1, 1, 1)), tuple(rec.get("bias") or (0, 0, 0, 0)),
                   tuple(rec.get("st_transform") or IDENTITY_ST_TRANSFORM))
            if key not in self._textures:
                self._textures[key] = self._load_texture(m.name, name, path, cs, rec)
            tid = self._textures[key]
            if tid is None:
                continue
            out[name] = (tid, texture_channel(rec.get("output")))
        return out

    def _light_texture(self, light) -> int:
        """Core texture id of a dome / rect light's ``inputs:texture:file`` (loaded
        once per core scene, colour space by bit depth), or -1. Dome: lat-long,
        wrapping around in s and clamped at the poles; rect: clamped. An
        unreadable file warns naming the light and keeps the untextured light."""
        path = getattr(light, "texture", None)
        if not path or light.kind not in ("dome", "rect"):
            return -1
        rec = {"wrapS": "repeat" if light.kind == "dome" else "clamp", "wrapT": "clamp"}
        if getattr(light, "texture_unresolved", False):
            rec["unresolved"] = str(path)       # the stage reader warned about it already
        key = (str(path), "auto", "light", rec["wrapS"], rec["wrapT"])
        if key not in self._textures:
            self._textures[key] = self._load_texture(light.name, "texture:file", path, "auto", rec)
        tid = self._textures[key]
        return -1 if tid is None else int(tid)

    def _load_texture(self, material: str, input_name: str, path, cs: str, rec: dict):
        import warnings
        from ..usd.color import load_texture
        try:
            if not path:
                raise OSError("no file")
            img = load_texture(str(path), cs)
        except Exception as exc:                       # missing / unreadable file
            if rec.get("unresolved"):
                return None             # the stage reader said so already (one cause, one warning)
            warnings.warn(f"{material}: texture file {rec.get('unresolved') or path!r} for "
                          f"{input_name} cannot be read ({exc}); using the fallback value")
            return None
        img = np.ascontiguousarray(img, dtype=np.float32)
        if img.ndim == 2:
            img = img[..., None]
        self._texture_arrays.append(img)
        wrap_s, wrap_t = resolve_wrap_modes(str(path), rec.get("wrapS"), rec.get("wrapT"))
        def four(v, d):
            v = tuple(float(x) for x in (v if v is not None else d))
            return (v + d[len(v):])[:4]
        kwargs = {}
        st_xf = rec.get("st_transform")
        if st_xf is not None and tuple(st_xf) != IDENTITY_ST_TRANSFORM:
            kwargs["st_transform"] = tuple(float(v) for v in st_xf)
        return self.scene.add_texture(img, wrap_s, wrap_t,
                                      four(rec.get("scale"), (1.0, 1.0, 1.0, 1.0)),
                                      four(rec.get("bias"), (0.0, 0.0, 0.0, 0.0)),
                                      name=f"{material}:{input_name}", **kwargs)

    def _structure_change(self, fs: FrameScene) -> str:
        """Why the scene must be rebuilt, or '' if updates suffice."""
        if self.scene is None:
            return "first frame"
        if len(fs.meshes) != len(self._meshes):
            return f"mesh count {len(self._meshes)} -> {len(fs.meshes)}"
        inst = [(i.name, int(i.mesh)) for i in fs.instances]
        if len(inst) != len(self._instances):
            return f"instance count {len(self._instances)} -> {len(inst)}"
        for mesh, old in zip(fs.meshes, self._meshes):
            if _topology_key(mesh) != old.key:
                return f"{mesh.name}: topology changed"
            if len(mesh.indices) != len(old.indices) or \
                    not _same(mesh.indices, old.src[0], old.indices):
                return f"{mesh.name}: indices changed"
            if not _same(mesh.uvs, old.src[1], old.uvs):
                return f"{mesh.name}: uvs changed"
            if mesh.material_ids is not old.src[2] and \
                    not _optional_equal(_material_ids(mesh.material_ids), old.material_ids):
                return f"{mesh.name}: material ids changed"
            old.src = (mesh.indices, mesh.uvs, mesh.material_ids)
        layout = primvar_layout(fs.materials or [])
        if layout != self._layout:
            return "primvar layout changed"
        for mesh, old in zip(fs.meshes, self._meshes):
            pvs = getattr(mesh, "primvars", None)
            if pvs is old.primvars_src:        # the reader's very dict: unchanged
                continue
            if not _optional_equal(primvar_array(mesh, layout), old.primvars):
                return f"{mesh.name}: primvars changed"
            old.primvars_src = pvs
        if inst != self._instances:
            return "instances changed"
        if fs.static_signature is not None and self._signature is not None and \
                fs.static_signature != self._signature:
            return "static/animated flags changed"
        return ""

    # -- building ---------------------------------------------------------
    def _build(self, fs: FrameScene) -> None:
        import warnings
        core = self._core
        scene = core.Scene()
        meshes, mesh_ids = [], []
        self._layout = primvar_layout(fs.materials or [], warn=warnings.warn)
        for mesh in fs.meshes:
            points = padded_points(mesh.points)
            indices = np.ascontiguousarray(np.asarray(mesh.indices, dtype=np.uint32).reshape(-1, 3))
            normals = None if mesh.normals is None else padded_points(mesh.normals)
            uvs = None if mesh.uvs is None else _f32(mesh.uvs, 2)
            mids = _material_ids(mesh.material_ids)
            pv = primvar_array(mesh, self._layout)
            kwargs = {} if pv is None else {"primvars": pv}
            with _naming(core, mesh.name, "mesh"):
                mesh_ids.append(scene.add_mesh(mesh.name, points, indices, normals=normals,
                                               uvs=uvs, material_ids=mids, **kwargs))
            # keep the very arrays handed over: the core may share their
            # buffers (zero-copy), so they must stay alive and unchanged
            meshes.append(_MeshState(_topology_key(mesh), points, normals, indices, uvs, mids,
                                     (mesh.indices, mesh.uvs, mesh.material_ids), pv,
                                     getattr(mesh, "primvars", None)))
        inst_ids, transforms = [], []
        for inst in fs.instances:
            if not 0 <= inst.mesh < len(mesh_ids):
                raise BridgeError(f"{inst.name}: instance refers to mesh {inst.mesh}, "
                                  f"but the frame has {len(mesh_ids)} meshes")
            with _naming(core, inst.name, "instance"):
                t = _mat(inst.transform)
                inst_ids.append(scene.add_instance(mesh_ids[inst.mesh], t))
                if inst.motion_transforms:
                    scene.set_instance_motion(inst_ids[-1],
                                              [_mat(m) for m in inst.motion_transforms])
            transforms.append(t.copy())
        self.scene = scene
        self._textures, self._texture_arrays = {}, []
        diffuse, emission, params = self._material_arrays(fs)
        self._set_materials(scene, fs, diffuse, emission, params)

        self._meshes, self._mesh_ids = meshes, mesh_ids
        self._instances = [(i.name, int(i.mesh)) for i in fs.instances]
        self._instance_ids, self._transforms = inst_ids, transforms
        self._moving = [bool(i.motion_transforms) for i in fs.instances]
        self._signature = fs.static_signature
        self._materials = (diffuse.copy(), emission.copy(), params.copy())

    def _incremental(self, fs: FrameScene, report: UpdateReport) -> None:
        scene = self.scene
        for k, (mesh, old) in enumerate(zip(fs.meshes, self._meshes)):
            if not mesh.deforming:
                report.static_meshes += 1          # static: not even looked at
                continue
            report.deforming_meshes += 1
            points = np.asarray(mesh.points, dtype=np.float32).reshape(-1, 3)
            normals = (None if mesh.normals is None else
                       np.asarray(mesh.normals, dtype=np.float32).reshape(-1, 3))
            if np.array_equal(points, old.points) and _optional_equal(normals, old.normals):
                continue
            p = padded_points(points)
            n = None if normals is None else padded_points(normals)
            with _naming(self._core, mesh.name, "mesh"):
                scene.update_mesh_points(self._mesh_ids[k], p, normals=n)
            old.points, old.normals = p, n
            report.meshes_updated += 1
        for k, inst in enumerate(fs.instances):
            if not inst.animated:
                report.static_instances += 1       # static: not even looked at
                continue
            report.animated_instances += 1
            t = _mat(inst.transform)
            if inst.motion_transforms:
                scene.set_instance_motion(self._instance_ids[k],
                                          [_mat(m) for m in inst.motion_transforms])
                self._moving[k] = True
                self._transforms[k] = t.copy()
                report.transforms_updated += 1
                continue
            if np.array_equal(t, self._transforms[k]) and not self._moving[k]:
                continue
            self._moving[k] = False
            scene.set_instance_transform(self._instance_ids[k], t)
            self._transforms[k] = t.copy()
            report.transforms_updated += 1
        diffuse, emission, params = self._material_arrays(fs)
        if not (np.array_equal(diffuse, self._materials[0]) and
                np.array_equal(emission, self._materials[1]) and
                np.array_equal(params, self._materials[2])):
            self._set_materials(scene, fs, diffuse, emission, params)
            self._materials = (diffuse.copy(), emission.copy(), params.copy())
            report.materials_updated = True

    def _set_materials(self, scene, fs, diffuse, emission, params) -> None:
        try:
            scene.set_materials(diffuse, emission, params)
        except (self._core.SceneError, ValueError, TypeError) as exc:
            raise _material_error(self._core, fs.materials, exc) from None

    def _add_light(self, scene, light) -> tuple:
        """Add ``light`` to the core scene; returns what it was given (compared from frame
        to frame: UpdateReport.lights_camera_changed)."""
        xf = _mat(light.transform)
        kw = dict(width=float(light.width), height=float(light.height),
                  radius=float(light.radius), length=float(light.length),
                  angle=float(light.angle), treat_as_point=bool(light.treat_as_point),
                  texture_id=self._light_texture(light),
                  cone_angle=float(getattr(light, "cone_angle", 180.0)),
                  cone_softness=float(getattr(light, "cone_softness", 0.0)),
                  focus=float(getattr(light, "focus", 0.0)),
                  focus_tint=tuple(float(c) for c in
                                   getattr(light, "focus_tint", (0.0, 0.0, 0.0))))
        radiance = tuple(float(c) for c in light.radiance)
        scene.add_light(light.kind, xf, radiance, **kw)
        return (str(light.kind), xf.tobytes(), radiance, tuple(sorted(kw.items())))

    def _lights_and_camera(self, fs: FrameScene) -> tuple:
        """Set the frame's lights and camera; returns what they were given."""
        scene = self.scene
        scene.clear_lights()
        given = []
        for light in fs.lights:
            with _naming(self._core, light.name, "light"):
                given.append(self._add_light(scene, light))
        cam = fs.camera
        if cam is None:
            raise BridgeError(f"time {fs.time:g}: the frame has no camera")
        with _naming(self._core, cam.name, "camera"):
            given.append(self._set_camera(scene, cam))
        return tuple(given)

    def _set_camera(self, scene, cam) -> tuple:
        xf = _mat(cam.transform)
        args = (float(cam.focal_length), float(cam.horizontal_aperture), float(cam.vertical_aperture))
        kw = dict(horizontal_aperture_offset=float(cam.horizontal_aperture_offset),
                  vertical_aperture_offset=float(cam.vertical_aperture_offset),
                  near=float(cam.near), far=float(cam.far),
                  f_stop=float(cam.f_stop), focus_distance=float(cam.focus_distance),
                  projection=str(cam.projection),
                  lens_unit=float(getattr(cam, "lens_unit", 0.001) or 0.001))
        scene.set_camera(xf, *args, **kw)
        return ("camera", xf.tobytes(), args, tuple(sorted(kw.items())))

    # -- public ----------------------------------------------------------
    def update(self, fs: FrameScene):
        """Bring the core scene to ``fs``; returns the committed ``core.Scene``."""
        reason = self._structure_change(fs)
        report = UpdateReport()
        if reason:
            self._build(fs)
            report.rebuilt, report.reason = True, reason
        else:
            self._incremental(fs, report)
        given = self._lights_and_camera(fs)
        report.lights_camera_changed = report.rebuilt or given != self._lights_camera
        self._lights_camera = given
        report.motion_blurred = sum(self._moving)
        report.motion_blur = bool(self.scene.motion_blur)
        self.scene.commit()
        self.last_update = report
        return self.scene
