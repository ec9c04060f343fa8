"""The core's scene probes (cmlt._core.probe_scene): deterministic, and their two
estimators of the caustic flux — emitted light paths and paths aimed at the specular
surfaces — agree (they estimate the same integral with different sampling)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import cmlt._core as core
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage

from effect_stages import build

SEQUENCES = Path(__file__).resolve().parents[3] / "sequences"


def scene_of(path, frame=1.0):
    stage = open_stage(str(path))
    fs = load_frame(stage, frame)
    return SceneBridge(core).update(fs), fs, stage


def test01_same_seed_same_answer_other_seed_other_numbers():
    scene, fs, _keep = scene_of(SEQUENCES / "caustic_glass" / "shot.usda")
    a = core.probe_scene(scene, 64, 64, seed=7)
    b = core.probe_scene(scene, 64, 64, seed=7)
    c = core.probe_scene(scene, 64, 64, seed=8)
    assert a == b
    assert a["direct_flux"] != c["direct_flux"]
    assert a["light_paths"] == 1024 and a["targeted_paths"] == 1024 and a["camera_paths"] == 256


@pytest.mark.statistical
def test02_emitted_and_targeted_caustic_flux_agree():
    """Independent seeds give independent estimates; the means of the two estimators
    must agree within 4 standard errors of their difference (false alarm ~6e-5)."""
    scene, fs, _keep = scene_of(SEQUENCES / "caustic_glass" / "shot.usda")
    em, tg = [], []
    for seed in range(24):
        r = core.probe_scene(scene, 64, 64, seed=seed, light_paths=4096, targeted_paths=1024,
                             camera_paths=1)
        em.append(r["caustic_flux_emitted"])
        tg.append(r["caustic_flux_targeted"])
    em, tg = np.asarray(em), np.asarray(tg)
    se = math.sqrt(em.var(ddof=1) / len(em) + tg.var(ddof=1) / len(tg))
    assert tg.mean() > 0 and em.mean() > 0
    assert abs(em.mean() - tg.mean()) < 4 * se, (em.mean(), tg.mean(), se)
    # the aimed paths are the better estimator: that is why they exist
    assert tg.std() < em.std()


def test03_no_specular_surface_no_targeted_paths(tmp_path):
    scene, fs, _keep = scene_of(build(tmp_path / "plain.usda"))
    r = core.probe_scene(scene, 48, 36)
    assert r["candidate_area"] == 0 and r["targeted_paths"] == 0
    assert r["light_caustics"] == 0 and r["caustic_flux_emitted"] == 0
    assert r["direct_flux"] > 0 and r["camera_diffuse_hits"] > 0
    # the room is open to the camera and lit from above: most light samples arrive
    assert r["direct_visible"] > 0.3


def test04_bad_arguments_name_the_field(tmp_path):
    scene, fs, _keep = scene_of(build(tmp_path / "plain.usda"))
    with pytest.raises(core.SettingsError, match="light_samples must be 1..64"):
        core.probe_scene(scene, 48, 36, light_samples=0)
    with pytest.raises(core.SettingsError, match="width and height"):
        core.probe_scene(scene, 0, 36)
    with pytest.raises(core.SceneError, match="no camera"):
        core.probe_scene(core.Scene(), 48, 36)
