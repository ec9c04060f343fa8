"""cmlt.accuracy.peers without running a peer: the flag's parsing, the USD frame converted
for the peers (the Cornell box's meshes, materials, light and camera), the Lambert switch,
and a clear message naming the package when a peer is not installed."""
from __future__ import annotations

import importlib.util
import math
import os

import numpy as np
import pytest

from cmlt.accuracy import ShotFrame
from cmlt.accuracy.peers import (DEFAULT_PEER_INTEGRATORS, PeerSession, convert_frame,
                                 parse_peers, small_copy)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")


def test_01_parse_peers():
    assert parse_peers("mitsuba") == [("mitsuba", DEFAULT_PEER_INTEGRATORS["mitsuba"])]
    assert parse_peers("mitsuba:ptracer, luxcore:BIDIRCPU") == [("mitsuba", "ptracer"),
                                                                 ("luxcore", "BIDIRCPU")]
    with pytest.raises(ValueError, match="unknown peer 'pbrt'"):
        parse_peers("pbrt")
    with pytest.raises(ValueError, match="at least one"):
        parse_peers(" , ")


def test_02_cornell_converts():
    sf = ShotFrame(CORNELL, resolution=(16, 12), peer_scene=True)
    ps = sf.peer_scene
    assert ps is not None and ps.triangle_count() > 0 and ps.notes == []
    # world-space triangles of every instance; all indices valid
    for m in ps.meshes:
        assert m.T.min() >= 0 and m.T.max() < len(m.P) and np.isfinite(m.P).all()
    emissive = [m for m in ps.meshes if ps.materials[m.material].emissive]
    assert emissive, "the ceiling light becomes emitting triangles"
    c = ps.camera
    assert (c.width, c.height) == (16, 12) and 0 < c.hfov_deg < 180
    assert math.isclose(np.linalg.norm(c.target - c.origin), 1.0, rel_tol=1e-9)
    assert len(ps.digest()) == 12 and ps.digest() == convert_frame(sf.fs, CORNELL).digest()
    q = small_copy(ps)
    assert (q.camera.width, q.camera.height) == (16, 16) and (ps.camera.width, ps.camera.height) == (16, 12)


def test_03_lambert_switch():
    plain = ShotFrame(CORNELL, resolution=(8, 8))
    lam = ShotFrame(CORNELL, resolution=(8, 8), lambert=True)
    assert lam.lambert_materials and not plain.lambert_materials
    assert all(m.ior == 1.0 for m in lam.fs.materials if m.name in lam.lambert_materials)
    assert plain.digest() != lam.digest()                     # not the same cached reference


def test_04_missing_peer_is_named(monkeypatch, tmp_path):
    real = importlib.util.find_spec

    def find_spec(name, *a, **k):
        return None if name in ("mitsuba", "pyluxcore") else real(name, *a, **k)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    sf = ShotFrame(CORNELL, resolution=(8, 8), peer_scene=True)
    said = []
    session = PeerSession(["mitsuba", "luxcore"], small_copy(sf.peer_scene), 1, str(tmp_path),
                          say=said.append)
    try:
        for ren, module in (("mitsuba", "mitsuba"), ("luxcore", "pyluxcore")):
            st = session.status[ren]
            assert not st["ok"] and not session.available(ren)
            assert "not installed" in st["note"] and f"pip install {module}" in st["note"]
        assert session.workers == {}
    finally:
        session.close()
