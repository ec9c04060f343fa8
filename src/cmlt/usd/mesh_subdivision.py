"""Subdivision surfaces of a UsdGeom.Mesh (mesh.py): the refinement level of a mesh and the
refinement of its cage with OpenSubdiv (``cmlt._core.subdivide``)."""

from __future__ import annotations

from typing import List

import numpy as np
from pxr import UsdGeom

from .mesh_primvars import SkipPrim, _Primvar, _tstr
from .mesh_topology import _elem_per_corner


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
