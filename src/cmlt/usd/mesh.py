"""UsdGeom.Mesh -> triangles with per-vertex normals and uvs (numpy, vectorised).

The topology (triangulation and, when a primvar is uniform or faceVarying,
the split of points into per-corner vertices) is computed once per prim and
reused while none of the topology attributes vary in time; only the points
(and varying primvars) are re-read per frame.

Modules: mesh_primvars (reading primvars), mesh_topology (triangulation, per-corner
vertices, normals), mesh_subdivision (OpenSubdiv); this one reads a prim with them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np
from pxr import UsdGeom

from ..scene import padded_points
from .mesh_primvars import (SkipPrim, _fmt, _natural_width, _normals_primvar, _Primvar, _read_primvar,
                            _request_values, _tstr, find_uv_primvar)
from .mesh_subdivision import refine_subdivision, subdiv_level_of
from .mesh_topology import _Topo, build_topology, smooth_normals


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
