"""The material tables the core takes from a frame's materials and meshes.

``core.Scene.set_materials`` gets one row per material in the column layout
:data:`MATERIAL_PARAM_COLUMNS` (constants, texture ids and channels), followed
by :data:`PRIMVAR_PARAM_COLUMNS` when some material reads primvars;
``core.Scene.add_mesh(primvars=...)`` gets each mesh's primvars placed at the
columns :func:`primvar_layout` gives them. :mod:`.bridge` builds and updates
the core scene with them.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ["BridgeError", "MATERIAL_PARAM_COLUMNS", "PRIMVAR_PARAM_COLUMNS", "MAX_PRIMVAR_COLUMNS",
           "IDENTITY_ST_TRANSFORM", "material_params", "primvar_layout", "primvar_array",
           "texture_channel", "resolve_wrap_modes"]


class BridgeError(ValueError):
    """A FrameScene the core cannot take (message names the prim)."""


#: Column layout of the ``params`` table of ``core.Scene.set_materials``
#: (src/core/materials/material.h, ``material_col``). Texture columns hold a
#: texture id from ``Scene.add_texture`` or -1; channel columns 0..3 (r, g, b, a).
MATERIAL_PARAM_COLUMNS = (
    "specular_r", "specular_g", "specular_b", "use_specular_workflow", "metallic",
    "roughness", "clearcoat", "clearcoat_roughness", "opacity", "opacity_threshold", "ior",
    "tex_diffuse", "tex_emission", "tex_specular", "tex_normal", "tex_metallic",
    "tex_roughness", "tex_clearcoat", "tex_clearcoat_roughness", "tex_opacity",
    "ch_metallic", "ch_roughness", "ch_clearcoat", "ch_clearcoat_roughness", "ch_opacity",
)
#: Appended to MATERIAL_PARAM_COLUMNS when some material reads primvars: the
#: first column of the mesh's ``primvars`` array each input reads (-1: none).
PRIMVAR_PARAM_COLUMNS = (
    "pv_diffuse", "pv_specular", "pv_metallic", "pv_roughness", "pv_clearcoat",
    "pv_clearcoat_roughness", "pv_opacity",
)
_COL = {name: i for i, name in enumerate(MATERIAL_PARAM_COLUMNS + PRIMVAR_PARAM_COLUMNS)}
#: columns of a mesh's primvars array the core interpolates at a hit (k_max_primvar_columns)
MAX_PRIMVAR_COLUMNS = 8
#: UsdUVTexture output -> channel read by a scalar input
_CHANNELS = {"rgb": 0, "r": 0, "g": 1, "b": 2, "a": 3}


def material_params(m, texture_ids=None, primvar_columns=None) -> np.ndarray:
    """One row of the params table for a :class:`cmlt.scene.Material`.

    ``texture_ids`` maps an input name (``diffuseColor``, ``roughness`` …) to
    ``(texture id, channel)``; inputs without an entry use their constant.
    ``primvar_columns`` (None: the row has no primvar columns) maps the layout
    key of a primvar (:func:`primvar_layout`) to its first column; inputs whose
    ``primvar_request`` is there read it per hit."""
    ncols = len(MATERIAL_PARAM_COLUMNS) + (len(PRIMVAR_PARAM_COLUMNS)
                                           if primvar_columns is not None else 0)
    row = np.full(ncols, -1.0, dtype=np.float32)
    row[0:3] = m.specular
    row[_COL["use_specular_workflow"]] = 1.0 if m.use_specular_workflow else 0.0
    for name in ("metallic", "roughness", "clearcoat", "clearcoat_roughness", "opacity",
                 "opacity_threshold", "ior"):
        row[_COL[name]] = float(getattr(m, name))
    row[_COL["ch_metallic"]:_COL["ch_opacity"] + 1] = 0.0
    row[_COL["ch_opacity"]] = 3.0
    for usd_name, (tid, ch) in (texture_ids or {}).items():
        col = _TEXTURE_INPUTS.get(usd_name)
        if col is None:
            continue
        row[_COL["tex_" + col]] = float(tid)
        if "ch_" + col in _COL:
            row[_COL["ch_" + col]] = float(ch)
    for usd_name, rec in (m.inputs or {}).items() if primvar_columns is not None else ():
        key = rec.get("primvar_request") if isinstance(rec, dict) else None
        col = _TEXTURE_INPUTS.get(usd_name)
        if key is None or col is None or ("pv_" + col) not in _COL or key not in primvar_columns:
            continue
        row[_COL["pv_" + col]] = float(primvar_columns[key])
    return row


#: primvar inputs that read 3 columns (the rest read 1)
_COLOUR_PRIMVAR_INPUTS = ("diffuseColor", "specularColor")


def primvar_layout(materials, warn=None) -> dict:
    """The columns of the meshes' ``primvars`` arrays: {key: (first column,
    width, fill)} for every distinct ``primvar_request`` of the materials'
    inputs, in material order. ``fill`` is what a mesh without that key gets
    (the request's fallback, else the material's constant). Requests past
    MAX_PRIMVAR_COLUMNS are left out (``warn`` is told); their inputs keep
    their constants."""
    layout, col = {}, 0
    for m in materials:
        for name, rec in (m.inputs or {}).items():
            key = rec.get("primvar_request") if isinstance(rec, dict) else None
            if key is None or key in layout or name not in _TEXTURE_INPUTS:
                continue
            width = int(getattr(key, "width", 0) or
                        (3 if name in _COLOUR_PRIMVAR_INPUTS else 1))
            if col + width > MAX_PRIMVAR_COLUMNS:
                if warn is not None:
                    warn(f"{m.name}: input {name} reads primvar "
                         f"{getattr(key, 'varname', key)}, but the frame's materials already "
                         f"read {col} primvar columns (at most {MAX_PRIMVAR_COLUMNS}); "
                         f"using its fallback")
                continue
            fill = getattr(key, "fallback", None)
            if fill is None:
                attr = {"diffuseColor": "diffuse", "specularColor": "specular",
                        "clearcoatRoughness": "clearcoat_roughness"}.get(name, name)
                fill = getattr(m, attr, 0.0)
            fill = tuple(float(x) for x in (fill if isinstance(fill, (tuple, list))
                                            else (fill,)))
            fill = (fill * width)[:width] if len(fill) == 1 else (fill + (0.0,) * width)[:width]
            layout[key] = (col, width, fill)
            col += width
    return layout


def primvar_array(mesh, layout) -> Optional[np.ndarray]:
    """float32 (N, K) for the core (``Scene.add_mesh(primvars=...)``): the
    mesh's ``primvars`` placed at their layout columns; None when the mesh has
    none of them."""
    pvs = getattr(mesh, "primvars", None)
    if not pvs or not layout:
        return None
    n = int(np.asarray(mesh.points).reshape(-1, 3).shape[0])
    if not any(k in pvs for k in layout):
        return None
    k_total = max(c + w for c, w, _ in layout.values())
    out = np.empty((n, k_total), dtype=np.float32)
    for key, (c, w, fill) in layout.items():
        a = pvs.get(key)
        if a is None:
            out[:, c:c + w] = np.asarray(fill, dtype=np.float32)
            continue
        a = np.asarray(a, dtype=np.float32)
        if a.ndim == 1:
            a = a[:, None]
        if a.shape[0] != n or a.shape[1] not in (1, w):
            raise BridgeError(f"{mesh.name}: primvar {getattr(key, 'varname', key)} has shape "
                              f"{a.shape}, expected ({n}, {w})")
        out[:, c:c + w] = a
    if not np.isfinite(out).all():
        raise BridgeError(f"{mesh.name}: primvars contain NaN or Inf")
    return out


#: UsdPreviewSurface input name -> the suffix of its tex_/ch_ columns.
_TEXTURE_INPUTS = {
    "diffuseColor": "diffuse", "emissiveColor": "emission", "specularColor": "specular",
    "normal": "normal", "metallic": "metallic", "roughness": "roughness",
    "clearcoat": "clearcoat", "clearcoatRoughness": "clearcoat_roughness",
    "opacity": "opacity",
}


#: UsdTransform2d identity as the 2x3 matrix (row-major a, b, tx, c, d, ty) of
#: ``core.Scene.add_texture(st_transform=...)``: st' = (a s + b t + tx, c s + d t + ty)
IDENTITY_ST_TRANSFORM = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)


def resolve_wrap_modes(path: str, wrap_s, wrap_t):
    """The wrap modes the core gets for a UsdUVTexture: ``black``, ``clamp``,
    ``repeat`` or ``mirror`` as authored; ``useMetadata`` (the shader's
    default, or anything unknown: the reader warned about it) -> the file's
    own wrap metadata (:func:`cmlt.usd.color.texture_wrap_metadata`), else
    ``black``, as the UsdPreviewSurface spec says (and Storm does: a
    clamp-to-border sampler)."""
    from ..usd.color import WRAP_TOKENS, texture_wrap_metadata

    ws, wt = str(wrap_s or "useMetadata"), str(wrap_t or "useMetadata")
    meta = (None, None)
    if ws not in WRAP_TOKENS or wt not in WRAP_TOKENS:
        meta = texture_wrap_metadata(path)
    if ws not in WRAP_TOKENS:
        ws = meta[0] or "black"
    if wt not in WRAP_TOKENS:
        wt = meta[1] or "black"
    return ws, wt


def texture_channel(output) -> int:
    """The channel a scalar input reads from a UsdUVTexture ``output`` (rgb, r, g, b, a)."""
    return _CHANNELS.get(str(output or "rgb"), 0)
