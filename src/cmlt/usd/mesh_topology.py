"""Topology of a UsdGeom.Mesh (mesh.py): triangulation (fans, concave polygons ear-clipped),
holes and winding, the split of points into per-corner vertices where a primvar is uniform
or faceVarying, and smooth normals."""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np
from pxr import UsdGeom

from .mesh_primvars import SkipPrim, _Primvar, _tstr


@dataclass
class _Topo:
    tri: np.ndarray                        # uint32 (M, 3) into output vertices
    tri_face: np.ndarray                   # int64 (M,)
    out_pt: Optional[np.ndarray]           # (V,) point of each output vertex, None = identity
    out_elem: dict                         # primvar name -> (V,) element index
    warnings: List[str]


def _elem_per_corner(pv: _Primvar, counts, fvi, n_faces, n_points, n_corners, path, tstr):
    """Element index of ``pv`` for every corner, or raise ValueError(warning)."""
    K = n_corners
    interp = pv.interp
    if interp == UsdGeom.Tokens.constant:
        elem = np.zeros(K, dtype=np.int64)
        expected = 1
    elif interp == UsdGeom.Tokens.uniform:
        elem = np.repeat(np.arange(n_faces, dtype=np.int64), counts)
        expected = n_faces
    elif interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
        elem = fvi.astype(np.int64, copy=False)
        expected = n_points
    elif interp == UsdGeom.Tokens.faceVarying:
        elem = np.arange(K, dtype=np.int64)
        expected = K
    else:
        raise ValueError(f"{path}: primvar {pv.name} has unknown interpolation '{interp}'; ignored")
    if pv.indices is not None:
        if len(pv.indices) < expected:
            raise ValueError(f"{path}: primvar {pv.name} ({interp}) has {len(pv.indices)} indices "
                             f"but needs {expected} (time {tstr}); ignored")
        if expected and (pv.indices[:expected].min() < 0 or pv.indices[:expected].max() >= len(pv.values)):
            bad = int(pv.indices[:expected].max())
            raise ValueError(f"{path}: primvar {pv.name} index {bad} is out of range "
                             f"({len(pv.values)} values, time {tstr}); ignored")
        elem = pv.indices[elem] if K else elem
    elif len(pv.values) < expected:
        raise ValueError(f"{path}: primvar {pv.name} ({interp}) has {len(pv.values)} values "
                         f"but needs {expected} (time {tstr}); ignored")
    return elem


def _needs_split(pv: _Primvar) -> bool:
    return pv.interp in (UsdGeom.Tokens.uniform, UsdGeom.Tokens.faceVarying)


def build_topology(path: str, counts, fvi, n_points: int, holes, left_handed: bool,
                   primvars: List[_Primvar], time,
                   points: Optional[np.ndarray] = None) -> Tuple[_Topo, List[_Primvar]]:
    """Triangulate (fan) and decide the output vertices. Raises SkipPrim.

    Returns the topology and the primvars that survived validation.
    """
    tstr = _tstr(time)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    fvi = np.asarray(fvi, dtype=np.int64).reshape(-1)
    F, K = len(counts), len(fvi)
    if F and counts.min() < 0:
        raise SkipPrim(f"{path}: faceVertexCounts has a negative entry ({int(counts.min())}) "
                       f"(time {tstr}); not rendered")
    total = int(counts.sum())
    if total != K:
        raise SkipPrim(f"{path}: faceVertexCounts sums to {total} but faceVertexIndices has "
                       f"{K} entries (time {tstr}); not rendered")
    if K:
        lo, hi = int(fvi.min()), int(fvi.max())
        if lo < 0:
            raise SkipPrim(f"{path}: faceVertexIndices refers to point {lo} (negative) "
                           f"(time {tstr}); not rendered")
        if hi >= n_points:
            raise SkipPrim(f"{path}: faceVertexIndices refers to point {hi} but points has "
                           f"{n_points} entries (time {tstr}); not rendered")
    warnings: List[str] = []
    keep = counts >= 3
    n_degenerate = int(F - keep.sum())
    if n_degenerate:
        warnings.append(f"{path}: {n_degenerate} face(s) with fewer than 3 vertices dropped")
    if holes is not None and len(holes):
        h = np.asarray(holes, dtype=np.int64).reshape(-1)
        h = h[(h >= 0) & (h < F)]
        keep[h] = False
    offsets = np.zeros(F, dtype=np.int64)
    if F:
        np.cumsum(counts[:-1], out=offsets[1:])
    kept = np.nonzero(keep)[0]
    ntri = counts[kept] - 2
    M = int(ntri.sum())
    tri_face = np.repeat(kept, ntri)
    tri_start = np.zeros(len(kept), dtype=np.int64)
    if len(kept):
        np.cumsum(ntri[:-1], out=tri_start[1:])
    j = np.arange(M, dtype=np.int64) - np.repeat(tri_start, ntri) + 1
    c0 = offsets[tri_face]
    c1 = c0 + j
    c2 = c1 + 1
    if points is not None and M:
        n_concave = _fix_concave(points, fvi, counts, offsets, kept, tri_start, c0, c1, c2)
        if n_concave:
            warnings.append(f"{path}: {n_concave} concave polygon(s) triangulated by ear clipping")
    if left_handed:
        c1, c2 = c2, c1
    corners = np.stack([c0, c1, c2], axis=1)          # (M, 3) corner ids

    good: List[_Primvar] = []
    elems = {}
    for pv in primvars:
        try:
            elems[pv.name] = _elem_per_corner(pv, counts, fvi, F, n_points, K, path, tstr)
            good.append(pv)
        except ValueError as exc:
            warnings.append(str(exc))

    split = [pv for pv in good if _needs_split(pv)]
    if not split:
        tri = fvi[corners] if M else np.zeros((0, 3), dtype=np.int64)
        out_elem = {}
        for pv in good:
            if pv.interp == UsdGeom.Tokens.constant:
                out_elem[pv.name] = np.zeros(n_points, dtype=np.int64)
            elif pv.indices is not None:
                out_elem[pv.name] = pv.indices[:n_points]
            else:
                out_elem[pv.name] = None                 # identity
        return _Topo(tri.astype(np.uint32), tri_face, None, out_elem, warnings), good

    # De-index: one output vertex per distinct (point, element of each split primvar).
    used = np.zeros(K, dtype=bool)
    used[corners.reshape(-1)] = True
    used_c = np.nonzero(used)[0]
    cols = [fvi[used_c]] + [elems[pv.name][used_c] for pv in split]
    key = cols[0].copy()
    fits = True
    for col in cols[1:]:
        m = int(col.max()) + 1 if len(col) else 1
        if key.size and int(key.max()) >= (1 << 62) // max(m, 1):
            fits = False
            break
        key = key * m + col
    if fits:
        _, rep, inv = np.unique(key, return_index=True, return_inverse=True)
    else:                                                   # pragma: no cover (huge meshes)
        _, rep, inv = np.unique(np.stack(cols, axis=1), axis=0, return_index=True,
                                return_inverse=True)
    inv = inv.reshape(-1)
    corner_to_out = np.full(K, -1, dtype=np.int64)
    corner_to_out[used_c] = inv
    rep_c = used_c[rep]                                     # representative corner per vertex
    tri = corner_to_out[corners]
    out_elem = {pv.name: elems[pv.name][rep_c] for pv in good}
    return _Topo(tri.astype(np.uint32), tri_face, fvi[rep_c], out_elem, warnings), good


def _fix_concave(points, fvi, counts, offsets, kept, tri_start, c0, c1, c2) -> int:
    """Re-triangulate concave polygons (>= 4 vertices) by ear clipping, in
    place in the corner arrays c0/c1/c2 (fan order otherwise). Returns the
    number of polygons changed. Uses the points at topology-build time."""
    big = kept[counts[kept] >= 4]
    if len(big) == 0 or not np.isfinite(points).all():
        return 0
    n = counts[big]
    corner = np.repeat(offsets[big], n) + (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n))
    local = corner - np.repeat(offsets[big], n)
    nxt = np.repeat(offsets[big], n) + (local + 1) % np.repeat(n, n)
    prv = np.repeat(offsets[big], n) + (local - 1) % np.repeat(n, n)
    p, pn, pp = points[fvi[corner]], points[fvi[nxt]], points[fvi[prv]]
    starts = np.cumsum(n) - n
    normal = np.add.reduceat(np.cross(p, pn), starts, axis=0)          # Newell
    turn = np.einsum("ij,ij->i", np.cross(p - pp, pn - p), np.repeat(normal, n, axis=0))
    reflex = np.add.reduceat((turn < 0).astype(np.int64), starts) > 0
    if not reflex.any():
        return 0
    pos_in_kept = {int(f): k for k, f in enumerate(kept)}
    changed = 0
    for f, nrm in zip(big[reflex], normal[reflex]):
        cnt, off = int(counts[f]), int(offsets[f])
        tris = _ear_clip(points[fvi[off:off + cnt]], nrm)
        if tris is None:
            continue
        t0 = int(tri_start[pos_in_kept[int(f)]])
        rows = slice(t0, t0 + cnt - 2)
        c0[rows], c1[rows], c2[rows] = off + tris[:, 0], off + tris[:, 1], off + tris[:, 2]
        changed += 1
    return changed


def _ear_clip(poly: np.ndarray, normal: np.ndarray):
    """Ear clipping of one simple polygon (its points in order) whose
    winding is counter-clockwise about ``normal``. Local indices (n-2, 3)."""
    ln = np.linalg.norm(normal)
    if ln == 0:
        return None
    w = normal / ln
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, w)
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    q = np.stack([poly @ u, poly @ v], axis=1)
    idx = list(range(len(q)))
    out = []

    def cross(o, a, b):
        return (q[a, 0] - q[o, 0]) * (q[b, 1] - q[o, 1]) - (q[a, 1] - q[o, 1]) * (q[b, 0] - q[o, 0])

    guard = 0
    while len(idx) > 3 and guard < 4 * len(q) ** 2:
        guard += 1
        m = len(idx)
        for k in range(m):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % m]
            if cross(i0, i1, i2) <= 0:
                continue                                   # reflex or flat
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                if cross(i0, i1, j) >= 0 and cross(i1, i2, j) >= 0 and cross(i2, i0, j) >= 0:
                    inside = True
                    break
            if not inside:
                out.append((i0, i1, i2))
                idx.pop(k)
                break
        else:
            return None                                    # not simple: keep the fan
    if len(idx) != 3:
        return None
    out.append(tuple(idx))
    return np.asarray(out, dtype=np.int64)


# ---------------------------------------------------------------- normals

def smooth_normals(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (float64), zero where undefined."""
    n = np.zeros_like(points, dtype=np.float64)
    if len(tri) == 0:
        return n
    p = points.astype(np.float64)
    t = tri.astype(np.int64)
    fn = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    for k in range(3):
        for c in range(3):
            n[:, c] += np.bincount(t[:, k], weights=fn[:, c], minlength=len(p))
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    np.divide(n, ln, out=n, where=ln > 0)
    return n
