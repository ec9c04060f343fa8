"""What a frame's core scene takes in memory, per triangle (``cmlt inspect``, the sidecar).

The figure comes from the core (``cmlt._core.scene_memory``, src/core/scene/scene_memory.h):
Embree's BVHs as its memory monitor counted them, plus the mesh arrays the core reads at
hits (points, indices, normals, uvs, material ids, primvars), its per-triangle light
map and the world-space points of meshes placed once by a static instance, divided by the triangles of the meshes (an instanced mesh counts once).
"""
from __future__ import annotations

from typing import Dict, Optional

__all__ = ["scene_memory", "format_memory"]

#: the parts of ``mesh_bytes``, in the order the text report lists them
MESH_PARTS = ("point_bytes", "index_bytes", "normal_bytes", "uv_bytes", "material_id_bytes",
              "primvar_bytes", "light_map_bytes", "placed_point_bytes")


def scene_memory(core, scene) -> Optional[Dict[str, float]]:
    """The committed ``scene``'s memory record (a dict of ints and ``bytes_per_triangle``),
    or None without a scene."""
    if scene is None:
        return None
    return dict(core.scene_memory(scene))


def _size(n: float) -> str:
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:.2f} {unit}"
    return f"{int(n)} B"


def format_memory(mem: Optional[Dict[str, float]]) -> str:
    """One line for ``cmlt inspect``."""
    if not mem:
        return "memory: no scene (no camera)"
    parts = ", ".join(f"{k[:-6].replace('_', ' ')} {_size(mem[k])}" for k in MESH_PARTS
                      if mem.get(k))
    return (f"memory: {mem['triangles']:,} triangles in {mem['meshes']} mesh(es), "
            f"{mem['instances']} instance(s): {mem['bytes_per_triangle']:.1f} bytes/triangle "
            f"(BVH {_size(mem['bvh_bytes'])}; mesh arrays {_size(mem['mesh_bytes'])}: "
            f"{parts or 'none'})")
