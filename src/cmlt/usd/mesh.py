"""UsdGeom.Mesh -> triangles with per-vertex normals and uvs (numpy, vectorised).

The topology (triangulation and, when a primvar is uniform or faceVarying,
the split of points into per-corner vertices) is computed once per prim and
reused while none of the topology attributes vary in time; only the points
(and varying primvars) are re-read per frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from ..scene import padded_points


class SkipPrim(Exception):
    """The prim cannot be rendered at this time; the message is the warning."""


@dataclass
class MeshGeom:
    """Triangulated geometry of one gprim in its object space (scene units)."""

    points: np.ndarray                     # float32 (N, 3), padded
    indices: np.ndarray                    # uint32 (M, 3)
    normals: Optional[np.ndarray]          # float32 (N, 3) or None
    uvs: Optional[np.ndarray]              # float32 (N, 2) or None
    tri_face: Optional[np.ndarray]         # int64 (M,) authored face of each triangle
    deforming: bool = False
    warnings: List[str] = field(default_factory=list)
    # per-vertex values the materials read through UsdPrimvarReaders:
    # PrimvarRequest -> float32 (N, request.width), rendering-space colours
    primvars: Optional[dict] = None


def _tstr(time: Usd.TimeCode) -> str:
    return "default" if time.IsDefault() else f"{time.GetValue():g}"


# ---------------------------------------------------------------- primvars

@dataclass
class _Primvar:
    name: str
    interp: str
    values: np.ndarray                     # (L, k) float64
    indices: Optional[np.ndarray]          # (I,) int64 or None
    varying: bool


_UV_NAMES = ("st", "uv", "st0", "UVMap", "map1")


def _read_primvar(pv: UsdGeom.Primvar, time, width: int) -> Optional[_Primvar]:
    if not pv or not pv.HasAuthoredValue():
        return None
    vals = pv.Get(time)
    if vals is None:
        return None
    arr = np.asarray(vals, dtype=np.float64)
    if arr.size == 0:
        return None
    arr = arr.reshape(-1, width) if arr.size % width == 0 else None
    if arr is None:
        return None
    idx = None
    varying = pv.ValueMightBeTimeVarying()
    interp = str(pv.GetInterpolation())
    if pv.IsIndexed():
        raw = pv.GetIndices(time)
        idx = np.asarray(raw, dtype=np.int64) if raw is not None else None
        ia = pv.GetIndicesAttr()
        varying = varying or (ia and ia.ValueMightBeTimeVarying())
    elif interp == UsdGeom.Tokens.faceVarying and len(arr) > 1:
        # Exporters often write one value per corner without indices; index
        # equal values so that corners sharing a point and a value share a vertex.
        arr, idx = _index_equal_rows(arr)
    return _Primvar(pv.GetPrimvarName(), interp, arr, idx, bool(varying))


def _index_equal_rows(arr: np.ndarray):
    """(unique rows, index of each row) by exact bit pattern."""
    a = np.ascontiguousarray(arr)
    view = a.view(np.dtype((np.void, a.dtype.itemsize * a.shape[1]))).reshape(-1)
    _, first, inv = np.unique(view, return_index=True, return_inverse=True)
    return a[first], inv.reshape(-1).astype(np.int64)


def find_uv_primvar(api: UsdGeom.PrimvarsAPI, preferred: Optional[str] = None):
    """The texture-coordinate primvar: ``preferred`` (the material's
    UsdPrimvarReader varname), else ``st``, else a texCoord2f primvar."""
    names = ([preferred] if preferred else []) + list(_UV_NAMES)
    for n in names:
        pv = api.GetPrimvar(n)
        if pv and pv.HasAuthoredValue():
            return pv
    for pv in api.GetPrimvarsWithAuthoredValues():
        tn = pv.GetTypeName()
        if tn in (Sdf.ValueTypeNames.TexCoord2fArray, Sdf.ValueTypeNames.TexCoord2dArray,
                  Sdf.ValueTypeNames.TexCoord2hArray):
            return pv
    return None


def _normals_primvar(prim, mesh: UsdGeom.Mesh, api, time) -> Optional[_Primvar]:
    pv = api.GetPrimvar("normals")
    if pv and pv.HasAuthoredValue():
        return _read_primvar(pv, time, 3)
    attr = mesh.GetNormalsAttr()
    if attr and attr.HasAuthoredValue():
        vals = attr.Get(time)
        if vals is None or len(vals) == 0:
            return None
        return _Primvar("normals", str(mesh.GetNormalsInterpolation()),
                        np.asarray(vals, dtype=np.float64).reshape(-1, 3), None,
                        attr.ValueMightBeTimeVarying())
    return None


def _natural_width(pv: UsdGeom.Primvar, time) -> int:
    """Components per element of a primvar's value (1 for float[]/int[])."""
    v = pv.Get(time)
    if v is None:
        return 1
    a = np.asarray(v)
    return int(a.shape[1]) if a.ndim == 2 else 1


def _to_width(values: np.ndarray, width: int) -> np.ndarray:
    """(L, k) -> (L, width): a scalar is repeated, a narrower vector padded
    with 0, a wider one cut."""
    k = values.shape[1]
    if k == width:
        return values
    if k == 1:
        return np.repeat(values, width, axis=1)
    if k > width:
        return values[:, :width]
    return np.concatenate([values, np.zeros((len(values), width - k))], axis=1)


def _request_values(pv: UsdGeom.Primvar, req, raw: np.ndarray) -> np.ndarray:
    """A request's element values (L, width): fitted, colours converted from
    the primvar's authored colour space to the rendering space."""
    vals = _to_width(raw, req.width)
    if req.colour and req.width == 3 and len(vals):
        from ..color import authored_colorspace, get_config
        cs = authored_colorspace(pv.GetAttr())
        vals = np.asarray(get_config().to_rendering_space(
            np.ascontiguousarray(vals, dtype=np.float32), cs, prim=pv.GetAttr().GetPrim()),
            dtype=np.float64)
    return vals


def shape_primvars(prim, requests, n_points: int, time, warn) -> Optional[dict]:
    """Per-vertex request values for an intrinsic shape (Sphere, Cube ...): its
    tessellation has no authored vertices, so a constant primvar fills every
    vertex, any other interpolation gives its mean with a warning, a missing
    one the reader's fallback with a warning. None without requests."""
    if not requests:
        return None
    path = str(prim.GetPath())
    api = UsdGeom.PrimvarsAPI(prim)
    out = {}
    for req in requests:
        pv = api.GetPrimvar(req.varname)
        value = None
        if pv and pv.HasAuthoredValue():
            flat = pv.ComputeFlattened(time)
            if flat is not None and len(flat):
                raw = np.asarray(flat, dtype=np.float64)
                raw = raw.reshape(len(raw), -1)
                vals = _request_values(pv, req, raw)
                vals = vals[np.isfinite(vals).all(axis=1)]
                if len(vals):
                    value = vals.mean(axis=0)
                    if len(vals) > 1 and pv.GetInterpolation() != UsdGeom.Tokens.constant:
                        warn(f"{path}: primvar {req.varname} is {pv.GetInterpolation()} on an "
                             f"intrinsic {prim.GetTypeName()}; {req.reader} reads its mean")
        if value is None:
            value = np.asarray(req.fallback, dtype=np.float64)
            warn(f"{path}: has no primvar {req.varname}, which {req.reader} reads; using the "
                 f"reader's fallback {_fmt(req.fallback)}")
        out[req] = np.ascontiguousarray(np.tile(value, (n_points, 1)), dtype=np.float32)
    return out


def _fmt(v) -> str:
    return "(" + ", ".join(f"{float(x):g}" for x in v) + ")"


# ---------------------------------------------------------------- topology

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


# ---------------------------------------------------------------- reading

# ---------------------------------------------------------------- subdivision

#: subdivision schemes refined with OpenSubdiv (``none``: rendered as authored)
SUBDIV_SCHEMES = ("catmullClark", "loop", "bilinear")
#: a mesh's own refinement level (``int cmlt:subdivisionLevel``; 0 = the control cage)
SUBDIV_LEVEL_ATTR = "cmlt:subdivisionLevel"
MAX_SUBDIV_LEVEL = 6
#: refined faces of one mesh at most: a higher level is lowered, with a warning
MAX_SUBDIV_FACES = 4_000_000
_default_level = 2


def default_subdiv_level() -> int:
    """Refinement level of subdivision surfaces without ``cmlt:subdivisionLevel``."""
    return _default_level


def set_default_subdiv_level(level: int) -> None:
    """Set :func:`default_subdiv_level` (0 renders every control cage as
    authored, with smooth normals). Meshes already read keep their level."""
    global _default_level
    level = int(level)
    if not 0 <= level <= MAX_SUBDIV_LEVEL:
        raise ValueError(f"subdivision level must be 0..{MAX_SUBDIV_LEVEL}, got {level}")
    _default_level = level


def subdiv_level_of(prim) -> int:
    """Refinement level of a mesh: 0 for ``subdivisionScheme = none`` (and
    unknown schemes), else its ``cmlt:subdivisionLevel`` if authored, else
    :func:`default_subdiv_level`."""
    scheme = UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Get()
    if scheme not in SUBDIV_SCHEMES:
        return 0
    attr = prim.GetAttribute(SUBDIV_LEVEL_ATTR)
    if attr and attr.HasAuthoredValue():
        try:
            return max(0, min(int(attr.Get()), MAX_SUBDIV_LEVEL))
        except (TypeError, ValueError):
            return default_subdiv_level()
    return default_subdiv_level()


def refine_subdivision(path, mesh, points, counts, fvi, primvars, level, time):
    """Refine a subdivision mesh's cage with OpenSubdiv (``cmlt._core.subdivide``):
    returns (limit points, face counts, face vertex indices, primvars on the
    refined mesh, the authored face of each refined face, warnings).

    Authored normals are ignored (UsdGeom: a subdivision surface's normals
    come from the surface); the limit normals become vertex normals. Vertex
    and varying primvars are refined like the points, faceVarying ones by
    OpenSubdiv's face-varying rules (``faceVaryingLinearInterpolation``),
    uniform ones follow their authored face, constant ones stay."""
    import cmlt._core as core
    tstr = _tstr(time)
    warnings: List[str] = []
    n_points = len(points)
    n_faces = len(counts)
    counts = np.asarray(counts, dtype=np.int64)
    keep = counts >= 3
    if not keep.all():
        raise SkipPrim(f"{path}: {int((~keep).sum())} face(s) with fewer than 3 vertices; a "
                       f"subdivision surface needs polygons (time {tstr}); not rendered")
    scheme = str(mesh.GetSubdivisionSchemeAttr().Get())
    if scheme == "loop" and (counts != 3).any():
        warnings.append(f"{path}: subdivisionScheme loop needs triangles but the mesh has "
                        f"{int((counts != 3).sum())} other polygon(s); refined as catmullClark")
        scheme = "catmullClark"
    asked = level
    while level > 1 and n_faces * 4 ** level > MAX_SUBDIV_FACES:   # each level: 4 faces per face
        level -= 1
    if level < asked:
        warnings.append(f"{path}: {n_faces} faces: subdivided to level {level}, not {asked} "
                        f"(at most {MAX_SUBDIV_FACES} refined faces)")

    def arr(getter, dtype):
        v = getter().Get(time)
        return np.ascontiguousarray(np.asarray(v if v is not None else [], dtype=dtype).reshape(-1))

    vertex_pvs, fvar_pvs, uniform_pvs, const_pvs = [], [], [], []
    K = len(fvi)
    for pv in primvars:
        if pv.name == "normals":
            continue
        try:
            elem = _elem_per_corner(pv, counts, fvi, n_faces, n_points, K, path, tstr)
        except ValueError as exc:
            warnings.append(str(exc))
            continue
        if pv.interp == UsdGeom.Tokens.constant:
            const_pvs.append(pv)
        elif pv.interp == UsdGeom.Tokens.uniform:
            face_elem = pv.indices[:n_faces] if pv.indices is not None else np.arange(n_faces)
            uniform_pvs.append((pv, face_elem))
        elif pv.interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
            vals = pv.values[pv.indices[:n_points]] if pv.indices is not None else \
                pv.values[:n_points]
            vertex_pvs.append((pv, vals))
        else:
            fvar_pvs.append((pv, elem))
    vdata = np.ascontiguousarray(np.concatenate([v for _, v in vertex_pvs], axis=1),
                                 dtype=np.float64) if vertex_pvs else None
    fvar = [(np.ascontiguousarray(pv.values, dtype=np.float64),
             np.ascontiguousarray(elem, dtype=np.int32)) for pv, elem in fvar_pvs]
    try:
        r = core.subdivide(
            np.ascontiguousarray(points, dtype=np.float64),
            np.ascontiguousarray(counts, dtype=np.int32), np.ascontiguousarray(fvi, dtype=np.int32),
            scheme=scheme, level=int(level),
            crease_indices=arr(mesh.GetCreaseIndicesAttr, np.int32),
            crease_lengths=arr(mesh.GetCreaseLengthsAttr, np.int32),
            crease_sharpnesses=arr(mesh.GetCreaseSharpnessesAttr, np.float32),
            corner_indices=arr(mesh.GetCornerIndicesAttr, np.int32),
            corner_sharpnesses=arr(mesh.GetCornerSharpnessesAttr, np.float32),
            hole_indices=arr(mesh.GetHoleIndicesAttr, np.int32),
            interpolate_boundary=str(mesh.GetInterpolateBoundaryAttr().Get() or "edgeAndCorner"),
            face_varying_linear=str(mesh.GetFaceVaryingLinearInterpolationAttr().Get()
                                    or "cornersPlus1"),
            smooth_triangles=str(mesh.GetTriangleSubdivisionRuleAttr().Get()) == "smooth",
            vertex_data=vdata, face_varying=fvar, name=path)
    except ValueError as exc:                            # SceneError, bad arguments
        raise SkipPrim(f"{path}: cannot be subdivided (time {tstr}): {exc}; not rendered") \
            from None
    parent = np.asarray(r["face_parent"], dtype=np.int64)
    out: List[_Primvar] = list(const_pvs)
    col = 0
    for pv, vals in vertex_pvs:
        k = vals.shape[1]
        out.append(_Primvar(pv.name, UsdGeom.Tokens.vertex,
                            np.asarray(r["vertex_data"][:, col:col + k]), None, pv.varying))
        col += k
    for (pv, _), (values, indices) in zip(fvar_pvs, r["face_varying"]):
        out.append(_Primvar(pv.name, UsdGeom.Tokens.faceVarying, np.asarray(values),
                            np.asarray(indices, dtype=np.int64), pv.varying))
    for pv, face_elem in uniform_pvs:
        out.append(_Primvar(pv.name, UsdGeom.Tokens.uniform, pv.values[face_elem[parent]], None,
                            pv.varying))
    out.append(_Primvar("normals", UsdGeom.Tokens.vertex, np.asarray(r["normals"]), None, True))
    return (np.asarray(r["points"]), np.asarray(r["face_counts"], dtype=np.int64),
            np.asarray(r["face_indices"], dtype=np.int64), out, parent, warnings)


class MeshReader:
    """Reads one UsdGeom.Mesh prim, caching what does not change in time."""

    TOPO_ATTRS = ("faceVertexCounts", "faceVertexIndices", "holeIndices", "orientation")

    def __init__(self, prim, uv_name: Optional[str] = None,
                 uv_fallback: Optional[Tuple[float, float]] = None, uv_reader: str = "",
                 primvar_requests=()):
        """``uv_name``: the primvar the material's UsdPrimvarReader_float2
        reads (for the texture shader ``uv_reader``); where the mesh lacks it, every vertex gets the
        reader's ``uv_fallback`` (the spec's "fetch failed" value), with a
        warning. Without ``uv_fallback``, a missing ``uv_name`` falls back to
        ``st`` or another texCoord2f primvar (see :func:`find_uv_primvar`).

        ``primvar_requests``: the :class:`cmlt.usd.shading.PrimvarRequest`
        of the materials' UsdPrimvarReaders; each becomes per-vertex columns
        of ``MeshGeom.primvars`` (any interpolation: constant, uniform,
        vertex, varying, faceVarying; indexed or not), the reader's fallback
        where the mesh lacks the primvar (with a warning naming the mesh)."""
        self.path = str(prim.GetPath())
        self.uv_name = uv_name
        self.uv_fallback = None if uv_fallback is None else \
            tuple(float(v) for v in uv_fallback)
        self.uv_reader = uv_reader
        self.requests = tuple(primvar_requests or ())
        self.topo: Optional[_Topo] = None
        self.topo_key = None
        self.static_geom: Optional[MeshGeom] = None
        self._pv_cache: dict = {}               # primvars that do not vary in time

    def _subdiv_level(self, prim, mesh) -> int:
        return subdiv_level_of(prim)

    def _varying(self, prim) -> Tuple[bool, bool]:
        topo = any(prim.GetAttribute(a).ValueMightBeTimeVarying()
                   for a in self.TOPO_ATTRS if prim.GetAttribute(a))
        pts = prim.GetAttribute("points")
        return topo, bool(pts and pts.ValueMightBeTimeVarying())

    def read(self, prim, time, skinned_points=None) -> MeshGeom:
        """The geometry at ``time``. ``skinned_points``: points posed by
        UsdSkel (skeleton space, see :mod:`cmlt.usd.skel`) replacing the
        authored ones; the mesh is then deforming, and authored normals (not
        skinned) are replaced by smooth normals of the posed points."""
        if self.static_geom is not None and skinned_points is None:
            return self.static_geom
        path = self.path
        tstr = _tstr(time)
        mesh = UsdGeom.Mesh(prim)
        api = UsdGeom.PrimvarsAPI(prim)
        topo_varying, pts_varying = self._varying(prim)
        skinned = skinned_points is not None

        pts_v = skinned_points if skinned else mesh.GetPointsAttr().Get(time)
        points = np.asarray(pts_v, dtype=np.float64).reshape(-1, 3) if pts_v is not None \
            else np.zeros((0, 3))
        if len(points) == 0:
            raise SkipPrim(f"{path}: has no points (time {tstr}); not rendered")

        primvars: List[_Primvar] = []
        npv = self._pv_cache.get("normals")
        if npv is None:
            npv = _normals_primvar(prim, mesh, api, time)
            if npv is not None and not npv.varying:
                self._pv_cache["normals"] = npv
        had_normals = npv is not None
        if npv is not None and not skinned:
            primvars.append(npv)
        uv_missing = False
        if self.uv_name and self.uv_fallback is not None:
            named = api.GetPrimvar(self.uv_name)
            uv_missing = not (named and named.HasAuthoredValue())
        uvpv = None if uv_missing else find_uv_primvar(api, self.uv_name)
        uv = self._pv_cache.get("st")
        if uv is None:
            uv = _read_primvar(uvpv, time, 2) if uvpv is not None else None
            if uv is not None and not uv.varying:
                self._pv_cache["st"] = uv
        if uv is not None:
            uv.name = "st"                     # internal name
            if npv is not None and npv.name == "st":   # pragma: no cover
                npv.name = "normals"
            primvars.append(uv)
        req_pv = {}                             # request index -> (Usd primvar, _Primvar)
        for k, req in enumerate(self.requests):
            cache_key = f"pv:{k}"
            upv = api.GetPrimvar(req.varname)
            if not (upv and upv.HasAuthoredValue()):
                continue
            rp = self._pv_cache.get(cache_key)
            if rp is None:
                rp = _read_primvar(upv, time, _natural_width(upv, time))
                if rp is not None and not rp.varying:
                    self._pv_cache[cache_key] = rp
            if rp is None:
                continue
            rp.name = cache_key
            primvars.append(rp)
            req_pv[k] = upv
        pv_varying = any(pv.varying for pv in primvars)
        pv_key = tuple((pv.name, pv.interp, pv.indices is not None,
                        len(pv.values)) for pv in primvars)

        level = self._subdiv_level(prim, mesh)
        subdiv_warnings: List[str] = []
        if level > 0:
            # a subdivision surface: refine the cage (every read; a static mesh is read once)
            counts = mesh.GetFaceVertexCountsAttr().Get(time)
            fvi = mesh.GetFaceVertexIndicesAttr().Get(time)
            left = mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded
            counts = np.asarray(counts if counts is not None else [], dtype=np.int64)
            fvi = np.asarray(fvi if fvi is not None else [], dtype=np.int64)
            points, counts, fvi, primvars, parent, subdiv_warnings = refine_subdivision(
                path, mesh, points, counts, fvi, primvars, level, time)
            # (refined quads are convex enough for a fan: no concavity pass, which would
            # cost more than the refinement itself)
            topo, _ = build_topology(path, counts, fvi, len(points), None, left, primvars, time)
            topo.tri_face = parent[topo.tri_face]         # the authored face of each triangle
            self.topo, self.topo_key = None, None
        elif self.topo is None or topo_varying or self.topo_key != pv_key or \
                any(pv.varying and pv.indices is not None for pv in primvars):
            counts = mesh.GetFaceVertexCountsAttr().Get(time)
            fvi = mesh.GetFaceVertexIndicesAttr().Get(time)
            holes = mesh.GetHoleIndicesAttr().Get(time)
            left = mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded
            counts = np.asarray(counts if counts is not None else [], dtype=np.int64)
            fvi = np.asarray(fvi if fvi is not None else [], dtype=np.int64)
            topo, _ = build_topology(path, counts, fvi, len(points),
                                     np.asarray(holes) if holes is not None else None,
                                     left, primvars, time, points=points)
            self.topo, self.topo_key = topo, pv_key
            self._tri_pts = None
        if level <= 0:
            topo = self.topo
        warnings = subdiv_warnings + list(topo.warnings)

        # gather per-vertex arrays
        out_pts = points if topo.out_pt is None else points[topo.out_pt]
        normals = uvs = None
        for pv in primvars:
            if pv.name not in topo.out_elem:
                continue                       # dropped by validation
            e = topo.out_elem[pv.name]
            vals = pv.values if e is None else pv.values[e]
            if pv.name.startswith("pv:"):
                continue                       # material primvars: below
            if pv.name == "normals":
                if not np.isfinite(vals).all():
                    warnings.append(f"{path}: normals contain NaN/Inf (time {tstr}); ignored")
                    continue
                ln = np.linalg.norm(vals, axis=1, keepdims=True)
                normals = np.divide(vals, ln, out=np.zeros_like(vals), where=ln > 0)
            else:
                if not np.isfinite(vals).all():
                    warnings.append(f"{path}: primvar {uvpv.GetPrimvarName()} contains NaN/Inf "
                                    f"(time {tstr}); replaced by 0")
                    vals = np.where(np.isfinite(vals), vals, 0.0)
                uvs = vals
        if uv_missing:
            uvs = np.tile(np.asarray(self.uv_fallback, dtype=np.float64), (len(out_pts), 1))
            by = f"texture {self.uv_reader}" if self.uv_reader else "its material"
            warnings.append(f"{path}: has no primvar {self.uv_name}, which {by} reads through "
                            f"a UsdPrimvarReader_float2; textures use the reader's fallback st "
                            f"({self.uv_fallback[0]:g}, {self.uv_fallback[1]:g})")
        mat_pvs = self._material_primvars(primvars, req_pv, topo, len(out_pts), warnings, tstr) \
            if self.requests else None
        if len(out_pts) != len(points) and topo.out_pt is None:   # pragma: no cover
            raise SkipPrim(f"{path}: point count changed (time {tstr}); not rendered")

        tri = topo.tri
        tri_face = topo.tri_face
        finite = np.isfinite(out_pts).all(axis=1)
        if not finite.all():
            n_bad = int((~np.isfinite(points).all(axis=1)).sum())
            ok = finite[tri.astype(np.int64)].all(axis=1)
            n_drop = int((~ok).sum())
            tri, tri_face = tri[ok], tri_face[ok]
            out_pts = np.where(finite[:, None], out_pts, 0.0)
            warnings.append(f"{path}: {n_bad} of {len(points)} points are NaN/Inf (time {tstr}); "
                            f"{n_drop} triangle(s) using them dropped")
        if len(tri) == 0:
            raise SkipPrim("; ".join(warnings + [f"{path}: no renderable faces (time {tstr}); "
                                                 f"not rendered"]))
        if normals is None:
            scheme = mesh.GetSubdivisionSchemeAttr().Get()
            if (scheme and scheme != UsdGeom.Tokens.none) or (skinned and had_normals):
                # the control cage of a subdivision surface is shaded smooth
                normals = smooth_normals(out_pts, tri)
        with np.errstate(over="ignore", invalid="ignore"):
            p32 = out_pts.astype(np.float32)
        if not np.isfinite(p32).all():
            raise SkipPrim(f"{path}: points overflow float32 (time {tstr}); not rendered")
        geom = MeshGeom(
            points=padded_points(p32),
            indices=np.ascontiguousarray(tri, dtype=np.uint32),
            normals=None if normals is None else np.ascontiguousarray(normals, dtype=np.float32),
            uvs=None if uvs is None else np.ascontiguousarray(uvs, dtype=np.float32),
            tri_face=tri_face,
            # points or normals may change from frame to frame (USD time samples)
            deforming=bool(skinned or pts_varying or (npv is not None and npv.varying)),
            warnings=warnings,
            primvars=mat_pvs,
        )
        if not (topo_varying or pts_varying or pv_varying or skinned):
            self.static_geom = geom
        return geom

    def _material_primvars(self, primvars, req_pv, topo, n_out, warnings, tstr) -> dict:
        """MeshGeom.primvars: per request, float32 (n_out, width) at the output
        vertices; the reader's fallback where the mesh lacks the primvar (or
        validation dropped it), non-finite values replaced by it."""
        by_name = {pv.name: pv for pv in primvars}
        out = {}
        for k, req in enumerate(self.requests):
            name = f"pv:{k}"
            pv = by_name.get(name)
            fb = np.asarray(req.fallback, dtype=np.float64)
            if pv is None or name not in topo.out_elem:
                why = "has no primvar" if k not in req_pv else "cannot use primvar"
                warnings.append(f"{self.path}: {why} {req.varname}, which {req.reader} reads "
                                f"(time {tstr}); using the reader's fallback {_fmt(req.fallback)}")
                out[req] = np.ascontiguousarray(np.tile(fb, (n_out, 1)), dtype=np.float32)
                continue
            elem_vals = _request_values(req_pv[k], req, pv.values)
            bad = ~np.isfinite(elem_vals).all(axis=1)
            if bad.any():
                warnings.append(f"{self.path}: primvar {req.varname} has {int(bad.sum())} "
                                f"NaN/Inf value(s) (time {tstr}); the reader's fallback there")
                elem_vals = np.where(bad[:, None], fb[None, :], elem_vals)
            e = topo.out_elem[name]
            vals = elem_vals[:n_out] if e is None else elem_vals[e]
            out[req] = np.ascontiguousarray(vals, dtype=np.float32)
        return out
