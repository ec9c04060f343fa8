"""The gallery's assets (docs/gallery/build_gallery.py; rendered by ``make gallery``,
not here) are built and read without a warning: the chess set's OpenPBR materials
come from its ``.mtlx`` document (not grey) and its ``look`` variant changes them,
the ball's floor texture is read from inside its ``.usdz``, its ``lighting=none``
variant leaves the stage without lights, and the portrait's texture is the
photograph matplotlib ships."""
from __future__ import annotations

import importlib.util
import os

import pytest

from cmlt.color import load_config, set_config
from cmlt.usd import load_frame, open_stage

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))))


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


@pytest.fixture(scope="module")
def gallery():
    spec = importlib.util.spec_from_file_location(
        "build_gallery", os.path.join(ROOT, "docs", "gallery", "build_gallery.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _diffuse(fs, mesh):
    m = next(m for m in fs.meshes if m.name == mesh)
    return fs.materials[int(m.material_ids[0])].diffuse


def test01_chess_materials_and_variant(gallery, tmp_path):
    from cmlt.usd.diagnostics import capture_usd_diagnostics
    with capture_usd_diagnostics():
        path = gallery.build_chess(str(tmp_path / "chess"))
    fs = load_frame(open_stage(path), 1, resolution=(16, 12))
    assert fs.warnings == []
    assert fs.up_axis == "Z" and fs.meters_per_unit == pytest.approx(0.01)
    classic = _diffuse(fs, "/Chess/White/pawn0")
    assert min(classic) > 0.5                              # ivory, not the 0.18 fallback
    wood = _diffuse(load_frame(open_stage(path, variants=["look=wood"]), 1,
                               resolution=(16, 12)), "/Chess/White/pawn0")
    assert wood[0] > 1.5 * wood[2]                         # maple
    assert {l.kind for l in fs.lights} == {"dome", "distant"}


def test02_ball_usdz_floor_and_lighting_variant(gallery, tmp_path):
    path = gallery.build_ball(str(tmp_path / "ball"))
    assert not os.path.exists(tmp_path / "ball" / "floor_src")   # only the package is left
    fs = load_frame(open_stage(path), 1, resolution=(16, 12))
    assert fs.warnings == []
    floor = next(m for m in fs.meshes if m.name == "/Ball/Floor/Plane")
    mat = fs.materials[int(floor.material_ids[0])]
    assert mat.inputs["diffuseColor"]["texture"].endswith("floor.usdz[tex/floor.png]")
    assert mat.inputs["diffuseColor"]["unresolved"] is None
    unlit = load_frame(open_stage(path, variants=["lighting=none"]), 1, resolution=(16, 12),
                       default_light="dome-key")
    assert sorted(l.name for l in unlit.lights) == ["<default fill dome>",
                                                    "<default key light>"]


def test03_portrait_photo_from_matplotlib(gallery, tmp_path):
    path = gallery.build_portrait(str(tmp_path / "portrait"))
    assert os.path.getsize(tmp_path / "portrait" / "grace_hopper.jpg") > 10000
    fs = load_frame(open_stage(path), 1, resolution=(16, 12))
    assert fs.warnings == []
    canvas = next(m for m in fs.meshes if m.name == "/Portrait/Canvas")
    tex = fs.materials[int(canvas.material_ids[0])].inputs["diffuseColor"]["texture"]
    assert tex.endswith("grace_hopper.jpg") and os.path.isfile(tex)
