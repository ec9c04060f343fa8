"""Primvars of a UsdGeom.Mesh (mesh.py): reading them with their interpolation, the uv
set a material reads, and the per-vertex columns of the materials' UsdPrimvarReaders;
also the mesh reader's SkipPrim."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from pxr import Sdf, Usd, UsdGeom


class SkipPrim(Exception):
    """The prim cannot be rendered at this time; the message is the warning."""


def _tstr(time: Usd.TimeCode) -> str:
    return "default" if time.IsDefault() else f"{time.GetValue():g}"


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
