"""Bytes per triangle of the core scene (core.scene_memory, cmlt inspect, the sidecar):
the mesh arrays are counted exactly, Embree's BVH as its memory monitor sees it (checked
against the process's resident memory), and a dense 1M-triangle mesh stays compact."""
import importlib.util
import json

import numpy as np
import pytest

import cmlt._core as core   # the real core: an ImportError is a failure, not a skip

import support
from cmlt.scene import padded_points

_spec = importlib.util.spec_from_file_location(
    "dense_make_shot", support.ROOT / "sequences" / "dense" / "make_shot.py")
dense = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(dense)


def _sphere_scene(rings, segments, *, normals=True, uvs=True, material_ids=None):
    pts, nrm, uv, counts, quads = dense.sphere_grid(rings, segments, 1.0)
    q = quads.reshape(-1, 4)
    tri = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]).astype(np.uint32)
    scene = core.Scene()
    arrays = dict(points=padded_points(pts), indices=np.ascontiguousarray(tri))
    if normals:
        arrays["normals"] = padded_points(nrm)
    if uvs:
        arrays["uvs"] = np.ascontiguousarray(uv, dtype=np.float32)
    if material_ids is not None:
        arrays["material_ids"] = material_ids(len(tri))
    mid = scene.add_mesh("sphere", **arrays)
    scene.add_instance(mid, np.eye(4))
    scene.commit()
    return scene, len(pts), len(tri)


def test_01_mesh_arrays_counted_exactly():
    scene, nv, nt = _sphere_scene(40, 80, material_ids=lambda n: np.arange(n, dtype=np.uint32) % 1)
    m = core.scene_memory(scene)
    assert (m["triangles"], m["vertices"], m["meshes"], m["instances"]) == (nt, nv, 1, 1)
    # float32 x 3 per point (+ the spare row Embree reads), uint32 x 3 per triangle,
    # float32 x 3 per normal, x 2 per uv; the material ids were handed per triangle
    assert m["point_bytes"] == 12 * (nv + 1)
    assert m["index_bytes"] == 12 * nt
    assert m["normal_bytes"] == 12 * nv and m["uv_bytes"] == 8 * nv
    assert m["material_id_bytes"] == 4 * nt
    # the one static instance: its points placed in world space, float32 x 3 per point
    assert m["placed_point_bytes"] == 12 * nv
    assert m["mesh_bytes"] == sum(m[k] for k in ("point_bytes", "index_bytes", "normal_bytes",
                                                   "uv_bytes", "material_id_bytes",
                                                   "primvar_bytes", "light_map_bytes",
                                                   "placed_point_bytes"))
    assert m["total_bytes"] == m["mesh_bytes"] + m["bvh_bytes"]
    assert m["bytes_per_triangle"] == pytest.approx(m["total_bytes"] / nt)
    bare, _, _ = _sphere_scene(40, 80, normals=False, uvs=False)
    b = core.scene_memory(bare)
    assert b["normal_bytes"] == b["uv_bytes"] == b["material_id_bytes"] == 0


def test_02_one_material_id_for_a_uniform_mesh_through_the_bridge():
    """The bridge hands a mesh whose triangles share a material one id, not one per
    triangle, and the image is the same as with per-triangle ids."""
    from cmlt.shot.bridge import _material_ids
    ids = _material_ids(np.full(10, 3, dtype=np.int64))
    assert ids.tolist() == [3]
    assert _material_ids(np.array([0, 1, 1], dtype=np.uint32)).tolist() == [0, 1, 1]
    scene, nv, nt = _sphere_scene(10, 20, material_ids=lambda n: np.zeros(1, dtype=np.uint32))
    assert core.scene_memory(scene)["material_id_bytes"] == 0


_RSS_CHILD = """
import os, sys
import numpy as np
import cmlt._core as core
from cmlt.scene import padded_points
sys.path.insert(0, sys.argv[1])
from make_shot import sphere_grid
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
pts, nrm, uv, counts, quads = sphere_grid(300, 600, 1.0)
q = quads.reshape(-1, 4)
tri = np.ascontiguousarray(np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]).astype(np.uint32))
p = padded_points(pts)
scene = core.Scene()
mid = scene.add_mesh("sphere", p, tri)
scene.add_instance(mid, np.eye(4))
before = rss()
scene.commit()
grown = rss() - before
m = core.scene_memory(scene)
print(m["bvh_bytes"], m["placed_point_bytes"], grown)
"""


def test_03_bvh_bytes_match_resident_memory():
    """The monitor's count of Embree's memory (plus the world-space points the commit
    places for a static instance of a small mesh: none for this large one) agrees with
    what a fresh process gains in resident memory while the commit builds them (the
    arrays exist before; a fresh process, so that no freed heap of earlier tests is
    reused)."""
    import subprocess
    import sys
    out = subprocess.run([sys.executable, "-c", _RSS_CHILD,
                          str(support.ROOT / "sequences" / "dense")],
                         capture_output=True, text=True, check=True).stdout
    bvh, placed, grown = (int(v) for v in out.split())
    assert bvh > 0
    assert placed == 0  # 180,000 points: too many to keep placed (Scene::k_place_max_points)
    built = bvh + placed
    assert 0.7 * built < grown < 1.3 * built, (bvh, placed, grown)


def test_04_dense_mesh_compact():
    """1M triangles (the sequences/dense sphere, vertex normals and uvs): the mesh arrays
    take at most 64 bytes per triangle and the BVH is built compact (a mesh this large:
    accel.h k_compact_bvh_triangles; Embree's default leaves take about 65 bytes per
    triangle here, compact ones about 37)."""
    scene, nv, nt = _sphere_scene(500, 1000)
    m = core.scene_memory(scene)
    assert nt == 1_000_000
    assert m["mesh_bytes"] / nt <= 64.0
    assert m["bvh_bytes"] / nt <= 45.0, m
    assert m["bytes_per_triangle"] == pytest.approx((m["mesh_bytes"] + m["bvh_bytes"]) / nt)


def test_05_inspect_and_sidecar_report_memory(tmp_path):
    from cmlt.cli import main
    shot = str(support.ROOT / "sequences" / "cornell" / "shot.usda")
    out = tmp_path / "inspect.json"
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["inspect", shot, "--json"]) == 0
    mem = json.loads(buf.getvalue())["memory"]
    assert mem["triangles"] > 0 and mem["bytes_per_triangle"] == pytest.approx(
        mem["total_bytes"] / mem["triangles"])
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["inspect", shot]) == 0
    assert f"{mem['triangles']:,} triangles" in buf.getvalue()
    assert "bytes/triangle" in buf.getvalue()
    img = tmp_path / "f.####.exr"
    assert main(["render", shot, "--frames", "1", "--res", "16x16", "--spp", "1",
                 "--integrator", "pt", "--out", str(img), "--quiet"]) == 0
    side = json.loads((tmp_path / "f.0001.exr.json").read_text())["memory"]
    # the same scene: the same mesh arrays; Embree's allocations for the small top level
    # depend on its build threads, so the BVH agrees to a few per cent
    for key in ("meshes", "instances", "triangles", "vertices", "mesh_bytes"):
        assert side[key] == mem[key], key
    assert side["bvh_bytes"] == pytest.approx(mem["bvh_bytes"], rel=0.05)
