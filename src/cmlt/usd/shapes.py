"""Tessellation of the intrinsic gprims (Sphere, Cube, Cylinder, Cone,
Capsule, Plane) into triangle meshes in their object space (scene units).

Surfaces of revolution are built around local Z and then turned onto the
authored ``axis`` with a proper rotation (cyclic permutation of the axes), so
winding stays counter-clockwise seen from outside. Curved parts carry smooth
normals, caps and cube faces flat ones. Resolution: 64 segments around,
32 along a sphere's meridian.
"""
from __future__ import annotations

import math
from typing import List, Tuple

import numpy as np
from pxr import UsdGeom

from ..scene import padded_points
from .mesh import MeshGeom, SkipPrim

SEGMENTS = 64
RINGS = 32

# (r, z, n_r, n_z) profile points; consecutive points form a band.
Profile = List[Tuple[float, float, float, float]]


def _revolve(bands: List[Profile], segments: int = SEGMENTS):
    pts, nrm, uvs, tris = [], [], [], []
    base = 0
    theta = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    c, s = np.cos(theta), np.sin(theta)
    for band in bands:
        prof = np.asarray(band, dtype=np.float64)          # (R, 4)
        R = len(prof)
        r, z, nr, nz = prof[:, 0:1], prof[:, 1:2], prof[:, 2:3], prof[:, 3:4]
        P = np.stack([r * c, r * s, np.broadcast_to(z, (R, segments + 1))], axis=-1)
        N = np.stack([nr * c, nr * s, np.broadcast_to(nz, (R, segments + 1))], axis=-1)
        U = np.stack(np.meshgrid(theta / (2 * math.pi), np.linspace(0, 1, R)), axis=-1)
        idx = base + np.arange(R * (segments + 1)).reshape(R, segments + 1)
        a, b = idx[:-1, :-1], idx[:-1, 1:]
        cc, d = idx[1:, 1:], idx[1:, :-1]
        t = np.concatenate([np.stack([a, b, cc], -1).reshape(-1, 3),
                            np.stack([a, cc, d], -1).reshape(-1, 3)])
        pts.append(P.reshape(-1, 3))
        nrm.append(N.reshape(-1, 3))
        uvs.append(U.reshape(-1, 2))
        tris.append(t)
        base += R * (segments + 1)
    P = np.concatenate(pts)
    T = np.concatenate(tris)
    area = np.linalg.norm(np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]), axis=1)
    T = T[area > 1e-12 * max(1.0, float(np.abs(P).max()) ** 2)]
    return P, T, np.concatenate(nrm), np.concatenate(uvs)


def _sphere_profile(radius: float, z0: float = 0.0, z1: float = 0.0,
                    rings: int = RINGS) -> Tuple[Profile, Profile]:
    """Lower and upper hemispheres (for a capsule the centres are z0 and z1)."""
    lower, upper = [], []
    half = rings // 2
    for i in range(half + 1):
        phi = -math.pi / 2 + (math.pi / 2) * i / half         # -90..0 degrees
        lower.append((radius * math.cos(phi), z0 + radius * math.sin(phi),
                      math.cos(phi), math.sin(phi)))
        phi2 = (math.pi / 2) * i / half                       # 0..90 degrees
        upper.append((radius * math.cos(phi2), z1 + radius * math.sin(phi2),
                      math.cos(phi2), math.sin(phi2)))
    return lower, upper


def _to_axis(P, N, axis: str):
    if axis == "X":
        perm = [2, 0, 1]       # local z -> X
    elif axis == "Y":
        perm = [1, 2, 0]       # local z -> Y
    else:
        return P, N
    return P[:, perm], N[:, perm]


def sphere(radius: float):
    lower, upper = _sphere_profile(radius)
    return _revolve([lower[:-1] + upper])


def frustum(r_bottom: float, r_top: float, height: float, caps: bool = True):
    h2 = height / 2.0
    slope = np.array([height, r_bottom - r_top], dtype=np.float64)
    slope /= max(np.linalg.norm(slope), 1e-30)
    bands: List[Profile] = [[(r_bottom, -h2, slope[0], slope[1]), (r_top, h2, slope[0], slope[1])]]
    if caps:
        if r_bottom > 0:
            bands.append([(0.0, -h2, 0.0, -1.0), (r_bottom, -h2, 0.0, -1.0)])
        if r_top > 0:
            bands.append([(r_top, h2, 0.0, 1.0), (0.0, h2, 0.0, 1.0)])
    return _revolve(bands)


def capsule(radius: float, height: float):
    lower, upper = _sphere_profile(radius, -height / 2.0, height / 2.0)
    return _revolve([lower + upper])


def cube(size: float):
    h = size / 2.0
    pts, nrm, uvs, tris = [], [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(pts)
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pts.append(h * (n + du * u + dv * v))
                nrm.append(n)
                uvs.append(((du + 1) / 2, (dv + 1) / 2))
            tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(pts), np.array(tris), np.array(nrm), np.array(uvs, dtype=np.float64)


def plane(width: float, length: float):
    w, l = width / 2.0, length / 2.0
    P = np.array([(-w, -l, 0), (w, -l, 0), (w, l, 0), (-w, l, 0)], dtype=np.float64)
    N = np.tile([0.0, 0.0, 1.0], (4, 1))
    U = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], dtype=np.float64)
    return P, np.array([(0, 1, 2), (0, 2, 3)]), N, U


def _get(prim, name, default, time):
    attr = prim.GetAttribute(name)
    if not attr:
        return default
    v = attr.Get(time)
    return default if v is None else v


def shape_key(prim, time):
    """A hashable description of the intrinsic shape, and whether it varies."""
    t = str(prim.GetTypeName())
    names = {
        "Sphere": ("radius",), "Cube": ("size",),
        "Cylinder": ("radius", "height", "axis"), "Cone": ("radius", "height", "axis"),
        "Capsule": ("radius", "height", "axis"), "Plane": ("width", "length", "axis"),
        "Cylinder_1": ("radiusTop", "radiusBottom", "height", "axis"),
        "Capsule_1": ("radiusTop", "radiusBottom", "height", "axis"),
    }[t]
    vals, varying = [], False
    for n in names:
        attr = prim.GetAttribute(n)
        v = attr.Get(time) if attr else None
        varying = varying or bool(attr and attr.ValueMightBeTimeVarying())
        vals.append((n, v if not isinstance(v, float) else float(v)))
    return (t, tuple(vals)), varying


def tessellate(prim, time) -> MeshGeom:
    """Tessellate an intrinsic gprim. Raises SkipPrim for a bad size."""
    t = str(prim.GetTypeName())
    path = str(prim.GetPath())
    axis = str(_get(prim, "axis", "Z", time))

    def positive(name, default):
        v = float(_get(prim, name, default, time))
        if not math.isfinite(v) or v < 0:
            raise SkipPrim(f"{path}: {name} is {v:g}; must be finite and >= 0; not rendered")
        return v

    if t == "Sphere":
        P, T, N, U = sphere(positive("radius", 1.0))
    elif t == "Cube":
        P, T, N, U = cube(positive("size", 2.0))
    elif t == "Cylinder":
        r = positive("radius", 1.0)
        P, T, N, U = frustum(r, r, positive("height", 2.0))
    elif t == "Cylinder_1":
        P, T, N, U = frustum(positive("radiusBottom", 1.0), positive("radiusTop", 1.0),
                             positive("height", 2.0))
    elif t == "Cone":
        P, T, N, U = frustum(positive("radius", 1.0), 0.0, positive("height", 2.0))
    elif t == "Capsule":
        P, T, N, U = capsule(positive("radius", 0.5), positive("height", 1.0))
    elif t == "Capsule_1":
        r = 0.5 * (positive("radiusTop", 0.5) + positive("radiusBottom", 0.5))
        P, T, N, U = capsule(r, positive("height", 1.0))
    elif t == "Plane":
        P, T, N, U = plane(positive("width", 2.0), positive("length", 2.0))
    else:                                                    # pragma: no cover
        raise SkipPrim(f"{path}: {t} is not an intrinsic shape")
    if len(T) == 0:
        raise SkipPrim(f"{path}: {t} has zero size; not rendered")
    P, N = _to_axis(P, N, axis)
    if _get(prim, "orientation", "rightHanded", time) == UsdGeom.Tokens.leftHanded:
        T = T[:, [0, 2, 1]]
    return MeshGeom(points=padded_points(P), indices=np.ascontiguousarray(T, dtype=np.uint32),
                    normals=np.ascontiguousarray(N, dtype=np.float32),
                    uvs=np.ascontiguousarray(U, dtype=np.float32), tri_face=None)
