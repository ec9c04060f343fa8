"""Checks and paths of the stage-reader tests (tests/python/usd/test_usd_*.py): the tiny
stages in tests/data/usd, world positions of an instance, triangle normals, the
contract every loaded FrameScene keeps, and authored colours in the rendering space."""
from __future__ import annotations

import os

import numpy as np

from cmlt.color import to_rendering_space as _to_acescg
from cmlt.scene import FrameScene

from . import DATA_USD


def acescg(rgb, source="lin_rec709"):
    """What the reader makes of an (untagged, linear Rec.709) authored colour."""
    return _to_acescg(tuple(float(c) for c in rgb), source)


DATA = str(DATA_USD)


def data(name):
    return os.path.join(DATA, name)


def world_points(scene: FrameScene, name: str) -> np.ndarray:
    """World positions (metres) of the instance called ``name``."""
    inst = next(i for i in scene.instances if i.name == name)
    p = scene.meshes[inst.mesh].points.astype(np.float64)
    return (inst.transform @ np.c_[p, np.ones(len(p))].T).T[:, :3]


def tri_normals(points, indices):
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(indices, dtype=np.int64)
    n = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def assert_clean(scene: FrameScene):
    """Contract checks: dtypes, shapes, no NaN, indices in range."""
    for m in scene.meshes:
        assert m.points.dtype == np.float32 and m.points.shape[1] == 3
        assert m.indices.dtype == np.uint32 and m.indices.shape[1] == 3
        assert np.isfinite(m.points).all()
        assert int(m.indices.max()) < len(m.points)
        for a in (m.normals, m.uvs):
            if a is not None:
                assert len(a) == len(m.points) and np.isfinite(a).all()
        assert m.material_ids.dtype == np.uint32 and len(m.material_ids) == len(m.indices)
        assert int(m.material_ids.max()) < len(scene.materials)
    for i in scene.instances:
        assert i.transform.shape == (4, 4) and np.isfinite(i.transform).all()
