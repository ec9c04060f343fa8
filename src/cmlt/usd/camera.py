"""UsdGeom.Camera -> :class:`cmlt.scene.Camera`, which camera, and the framing camera.

Camera.transform is rigid (rotation + translation in metres); USD cameras
look down local -Z with +Y up. Focal length and apertures are kept in their
authored lens unit (tenths of a scene unit, i.e. mm on a cm stage) -- only
their ratios matter to a pinhole -- and ``Camera.lens_unit`` says how many
metres one lens unit is (metersPerUnit / 10). Clipping range and
focusDistance are converted to metres.

A camera under a scaled transform sees a scaled world: its clipping range,
focus distance and lens unit are lengths in the camera's own space, so they
scale with it (by ``cbrt|det|`` of the camera-to-world matrix in metres, which
is metersPerUnit for an unscaled camera); the rigid part of the transform is
kept as the camera's pose.
"""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Tuple

import numpy as np
from pxr import Usd, UsdGeom

from ..scene import Camera
from .errors import UsdLoadError
from .lights import rigid_and_scale
from .stage import prim_at, stage_file


#: largest float32: camera lengths beyond it would reach the core as inf
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def gf_to_np(m) -> np.ndarray:
    """Gf.Matrix4d (row-vector) -> float64 (4, 4) column-vector matrix."""
    return np.array(m, dtype=np.float64).reshape(4, 4).T.copy()


#: an instance transform's thinnest axis relative to its widest, at least: below it the
#: core's float32 world-to-object transform of a ray (Embree inverts the instance
#: matrix) overflows into rays Embree refuses (found by the stage fuzzer: a scale of
#: -1e-30 on one axis)
MIN_AXIS_RATIO = 1e-6


def condition_instance_transform(m: np.ndarray):
    """(transform, note) for a column-vector 4x4 object-to-world instance transform:
    ``m`` itself with note None when the core can trace it; with its thinnest axes
    widened to MIN_AXIS_RATIO of its widest (a flattened object stays where it was,
    thicker by less than a millionth of its size) and a note saying so; or (None, why)
    when nothing sensible can be traced (not finite, collapsed to a point, beyond
    float32)."""
    if not np.isfinite(m).all():
        return None, "is not finite"
    a = m[:3, :3]
    frob = float(np.sqrt((a * a).sum()))
    if not frob > 0.0:
        return None, "collapses the object to a point"
    if frob > _FLOAT32_MAX / 16 or float(np.abs(m[:3, 3]).max()) > _FLOAT32_MAX / 16:
        return None, "reaches beyond float32's range"
    # fast path: s_min >= |det| / frob^2, so |det| >= ratio * frob^3 keeps s_min >= ratio * s_max
    if abs(float(np.linalg.det(a))) >= MIN_AXIS_RATIO * frob ** 3:
        return m, None
    u, sv, vt = np.linalg.svd(a)
    floor = float(sv[0]) * MIN_AXIS_RATIO
    if not floor > 1e-30:
        return None, f"makes the object smaller than float32 can invert (scale {sv[0]:.3g})"
    if float(sv[-1]) >= floor:
        return m, None
    out = m.copy()
    out[:3, :3] = u @ np.diag(np.maximum(sv, floor)) @ vt
    return out, (f"is nearly singular (axis scales {', '.join(f'{x:.3g}' for x in sv)}); its "
                 f"thinnest axis is widened to {floor:.3g} so that rays can be traced through it")


def _finite(v, default):
    try:
        f = float(v)
    except (TypeError, ValueError):
        return default
    return f if math.isfinite(f) else default


def read_camera(prim, time, mpu: float, world_m: np.ndarray, warnings: List[str]) -> Camera:
    """Read a UsdGeom.Camera at ``time``; ``world_m`` is camera->world in metres."""
    path = str(prim.GetPath())
    cam = UsdGeom.Camera(prim)

    def get(attr, default):
        v = attr.Get(time) if attr else None
        return _finite(v, default) if v is not None else default

    if not np.isfinite(np.asarray(world_m, dtype=np.float64)).all():
        raise UsdLoadError(f"{path}: the camera's transform is not finite (time "
                           f"{'default' if time.IsDefault() else f'{time.GetValue():g}'})")
    xf, axes = rigid_and_scale(world_m)
    # metres per camera-space unit: metersPerUnit times the transform's (uniform) scale
    det = abs(float(np.linalg.det(np.asarray(world_m, dtype=np.float64)[:3, :3])))
    unit = det ** (1.0 / 3.0) if math.isfinite(det) and det > 0 else float(mpu)
    if abs(unit / float(mpu) - 1.0) < 1e-9:
        unit = float(mpu)           # unscaled: exactly metersPerUnit (no rounding of the cube root)
    proj = cam.GetProjectionAttr().Get(time) or "perspective"
    near, far = 1.0, 1.0e6
    cr = cam.GetClippingRangeAttr().Get(time)
    if cr is not None:
        near, far = _finite(cr[0], near), _finite(cr[1], far)
    c = Camera(
        name=path,
        transform=xf,
        projection=str(proj) if str(proj) in ("perspective", "orthographic") else "perspective",
        focal_length=get(cam.GetFocalLengthAttr(), 50.0),
        horizontal_aperture=get(cam.GetHorizontalApertureAttr(), 20.955),
        vertical_aperture=get(cam.GetVerticalApertureAttr(), 15.2908),
        horizontal_aperture_offset=get(cam.GetHorizontalApertureOffsetAttr(), 0.0),
        vertical_aperture_offset=get(cam.GetVerticalApertureOffsetAttr(), 0.0),
        near=near * unit,
        far=far * unit,
        f_stop=get(cam.GetFStopAttr(), 0.0),
        focus_distance=get(cam.GetFocusDistanceAttr(), 0.0) * unit,
        shutter_open=get(cam.GetShutterOpenAttr(), 0.0),
        shutter_close=get(cam.GetShutterCloseAttr(), 0.0),
        lens_unit=unit / 10.0,
    )
    if c.focal_length <= 0:
        warnings.append(f"{path}: focalLength is {c.focal_length:g}; using 50")
        c.focal_length = 50.0
    if c.horizontal_aperture <= 0 or c.vertical_aperture <= 0:
        warnings.append(f"{path}: apertures must be > 0 ({c.horizontal_aperture:g}, "
                        f"{c.vertical_aperture:g}); using 20.955 x 15.2908")
        c.horizontal_aperture, c.vertical_aperture = 20.955, 15.2908
    if not (0.0 <= c.f_stop < _FLOAT32_MAX):
        warnings.append(f"{path}: fStop is {c.f_stop:g}; using 0 (a pinhole)")
        c.f_stop = 0.0
    if not (0.0 <= c.focus_distance < _FLOAT32_MAX):     # the core holds it in float32
        warnings.append(f"{path}: focusDistance is {c.focus_distance:g} m; using 0 (no focus plane)")
        c.focus_distance = 0.0
    if not (c.lens_unit > 0.0 and c.lens_unit < _FLOAT32_MAX):
        warnings.append(f"{path}: its transform's scale gives a lens unit of {c.lens_unit:g} m; "
                        f"using metersPerUnit / 10")
        c.lens_unit = mpu / 10.0
    if c.far >= _FLOAT32_MAX:
        c.far = 1.0e30
    if not (0 < c.near < c.far):
        warnings.append(f"{path}: clippingRange ({near:g}, {far:g}) is not 0 < near < far; "
                        f"using (0.01, 1e6) m")
        c.near, c.far = 0.01, 1.0e6
    return c


def framing_camera(bounds: Optional[Tuple[np.ndarray, np.ndarray]], up_axis: str,
                   resolution: Tuple[int, int]) -> Camera:
    """A camera that frames ``bounds`` (world, metres), as usdrecord does
    without a camera: a front view along the up-axis convention -- for a
    Y-up stage it sits on +Z looking down -Z with +Y up; for a Z-up stage it
    sits on -Y looking down +Y with +Z up. The whole bounding sphere fits in
    the narrower field of view (50 mm lens, 35 mm-style 20.955 mm aperture,
    vertical aperture from the image aspect)."""
    w, h = resolution
    focal, hap = 50.0, 20.955
    vap = hap * h / max(w, 1)
    if bounds is None:
        centre, radius = np.zeros(3), 1.0
    else:
        lo, hi = bounds
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
    half_fov = math.atan(0.5 * min(hap, vap) / focal)
    dist = radius / math.sin(half_fov) * 1.05
    m = np.eye(4)
    if up_axis == "Z":
        # camera -Z -> world +Y, camera +Y -> world +Z, camera +X -> world +X
        m[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
        m[:3, 3] = centre + np.array([0.0, -dist, 0.0])
    else:
        m[:3, 3] = centre + np.array([0.0, 0.0, dist])
    near = max(dist - 2.0 * radius, dist * 1e-3)
    return Camera(name="<framing>", transform=m, focal_length=focal,
                  horizontal_aperture=hap, vertical_aperture=vap,
                  near=near, far=dist + 2.0 * radius, lens_unit=0.001)


def camera_at_path(stage, path) -> "Usd.Prim":
    """The Camera prim at ``path``; UsdLoadError naming the stage when there is
    none or it is not a Camera."""
    path = str(path)
    prim = prim_at(stage, path)
    if prim is None:
        raise UsdLoadError(f"{stage_file(stage)}: camera {path} does not exist")
    if not prim.IsA(UsdGeom.Camera):
        raise UsdLoadError(f"{stage_file(stage)}: camera {path} is a "
                           f"{prim.GetTypeName() or 'typeless prim'}, not a Camera")
    return prim


def stage_cameras(stage) -> List:
    """Every Camera prim of the stage, instance proxies included, in traversal order."""
    return [p for p in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies())
            if p.IsA(UsdGeom.Camera)]


#: the largest coordinate the core traces (scene/scene.h k_max_coordinate)
MAX_COORDINATE = 1e15


def farthest_mesh(meshes, instances) -> Optional[str]:
    """The name of the mesh whose placed bounds (instance_bounds, instance by instance)
    reach farthest from the origin: the one that sets the framing camera's distance; or
    None."""
    best, name = -1.0, None
    for inst in instances:
        b = instance_bounds(meshes, [inst])
        r = np.inf if b is None else float(np.max(np.abs(np.concatenate(b))))
        if b is not None and r > best:
            best, name = r, meshes[inst.mesh].name
    return name


def instance_bounds(meshes, instances) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """World-space bounds (lo, hi) of the points the instances use, or None."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    by_mesh: Dict[int, List[np.ndarray]] = {}
    for inst in instances:
        by_mesh.setdefault(inst.mesh, []).append(inst.transform)
    for mi, xs in by_mesh.items():
        p = meshes[mi].points
        used = np.zeros(len(p), dtype=bool)
        used[meshes[mi].indices.reshape(-1)] = True
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


#: UsdRender.Settings.aspectRatioConformPolicy values cmlt honours
CONFORM_POLICIES = ("expandAperture", "cropAperture", "adjustApertureWidth",
                    "adjustApertureHeight", "adjustPixelAspectRatio")


def conform_aperture(cam: Camera, resolution, policy: str = "expandAperture",
                     warnings: Optional[List[str]] = None, where: str = "") -> Camera:
    """Fit the camera's aperture to the image aspect as UsdRender's
    ``aspectRatioConformPolicy`` says (the core frames the image by the horizontal
    aperture, the vertical extent following the image aspect A = width / height):

    * ``expandAperture`` (UsdRender's default): the authored aperture stays whole in
      the image, the other direction grows: ha' = max(ha, va A);
    * ``cropAperture``: the image stays inside the aperture: ha' = min(ha, va A);
    * ``adjustApertureWidth``: va kept, ha' = va A;
    * ``adjustApertureHeight``: ha kept (va' = ha / A);
    * ``adjustPixelAspectRatio``: cmlt's pixels are square; warned, treated as
      ``expandAperture``.

    The vertical aperture is set to the extent the image shows (ha' / A). Applied
    when the stage has render settings (:func:`cmlt.usd.load_frame`)."""
    w, h = resolution
    aspect = float(w) / float(h)
    ha, va = float(cam.horizontal_aperture), float(cam.vertical_aperture)
    if policy not in CONFORM_POLICIES or policy == "adjustPixelAspectRatio":
        if warnings is not None:
            warnings.append(f"{where or cam.name}: aspectRatioConformPolicy {policy!r} is not "
                            "supported (square pixels); using expandAperture")
        policy = "expandAperture"
    if policy == "expandAperture":
        ha_new = max(ha, va * aspect)
    elif policy == "cropAperture":
        ha_new = min(ha, va * aspect)
    elif policy == "adjustApertureWidth":
        ha_new = va * aspect
    else:
        ha_new = ha
    with np.errstate(over="ignore"):
        ok = bool(np.isfinite(np.float32(ha_new)) and np.isfinite(np.float32(ha_new / aspect))
                  and ha_new > 0)
    if not ok:                          # the core holds apertures in float32
        if warnings is not None:
            warnings.append(f"{cam.name}: the aperture conformed by {policy} is not finite in "
                            f"single precision ({ha:g} x {va:g}); the horizontal aperture "
                            "spans the width instead")
        return cam
    cam.horizontal_aperture = ha_new
    cam.vertical_aperture = ha_new / aspect
    return cam
