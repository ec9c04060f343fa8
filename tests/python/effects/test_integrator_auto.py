"""--integrator auto: the rule, the frames it decides from, and the frame loop using it
(the default when neither a flag nor the stage chooses), with its choice in the sidecar."""
from __future__ import annotations

import json

import pytest

from effect_stages import build, inspect
from cmlt.analysis import Effect, FrameEffects, choose_integrator, sample_frames
from cmlt.analysis.auto import CAUSTIC_SHARE, HARD_BOUNCE, HARD_DIRECT, INDIRECT_NOISE
from cmlt.analysis.effects import EFFECT_NAMES
from cmlt.cli import main

GLASS = {"opacity": 0.0, "roughness": 0.0, "ior": 1.5}


def fake(time, caustic=0.0, direct=0.9, bounce=0.9, hits=200, indirect=0.0, rel_var=0.0):
    """FrameEffects with given probe numbers (caustic flux share, visibility, the indirect
    share of the first hits' irradiance and its estimate's relative variance)."""
    probes = {"targeted_paths": 1, "caustic_flux_targeted": caustic, "direct_flux": 1.0 - caustic,
              "direct_visible": direct, "bounce_visible": bounce, "lit_hits": direct,
              "camera_diffuse_hits": hits, "camera_paths": 256,
              "light_caustics": 0, "targeted_caustics": int(caustic > 0),
              "direct_irradiance": 1.0 - indirect, "indirect_irradiance": indirect,
              "indirect_rel_var": rel_var}
    eff = {n: Effect(n == "caustics" and caustic > 0) for n in EFFECT_NAMES}
    return FrameEffects(time, eff, probes=probes)


def test01_the_rule():
    assert choose_integrator([fake(1), fake(2)]).name == "pt"
    # caustics that matter in one frame decide for the shot
    c = choose_integrator([fake(1), fake(2, caustic=2 * CAUSTIC_SHARE)])
    assert c.name == "bdpt" and "caustics: at frame 2" in c.reason and c.frames == [1, 2]
    # caustics below the share do not
    c = choose_integrator([fake(1, caustic=0.5 * CAUSTIC_SHARE)])
    assert c.name == "pt" and "caustics carry at most" in c.reason
    # hard visibility needs both the direct and the one-bounce fractions small
    c = choose_integrator([fake(1, direct=0.5 * HARD_DIRECT, bounce=0.5 * HARD_BOUNCE)])
    assert c.name == "bdpt" and "hard visibility: at frame 1" in c.reason
    assert choose_integrator([fake(1, direct=0.5 * HARD_DIRECT, bounce=2 * HARD_BOUNCE)]).name \
        == "pt"
    assert choose_integrator([fake(1, direct=2 * HARD_DIRECT, bounce=0.5 * HARD_BOUNCE)]).name \
        == "pt"
    # a camera that sees nothing is no hard visibility
    assert choose_integrator([fake(1, direct=0.0, bounce=0.0, hits=0)]).name == "pt"
    # indirect hot spots: share^2 x relative variance of the one-bounce estimate
    c = choose_integrator([fake(1), fake(2, indirect=0.5, rel_var=4.4 * INDIRECT_NOISE)])
    assert c.name == "bdpt" and "indirect hot spots: at frame 2" in c.reason
    assert choose_integrator([fake(1, indirect=0.5, rel_var=3.6 * INDIRECT_NOISE)]).name == "pt"
    # a large relative variance of a small share is no hot spot
    assert choose_integrator([fake(1, indirect=0.05, rel_var=100 * INDIRECT_NOISE)]).name == "pt"
    assert fake(1, indirect=0.5, rel_var=4.0).indirect() == {"share": 0.5, "rel_var": 4.0, "noise": 1.0}


def test02_the_frames_it_decides_from():
    assert sample_frames([5, 6, 7], 1, 24) == [1.0, 12.0, 24.0]
    assert sample_frames([5, 6, 7]) == [5.0, 6.0, 7.0]
    assert sample_frames([3.0]) == [3.0]
    assert sample_frames([1, 2], 1.0, 1.0) == [1.0]
    assert sample_frames([1, 1.5, 2], 1.0, 2.0) == [1.0, 2.0]


def _render(tmp_path, shot, *args):
    out = tmp_path / "r" / "f.####.exr"
    code = main(["render", shot, "--out", str(out), "--spp", "2", "--res", "16x12",
                 "--threads", "2", "--quiet", *args])
    assert code == 0
    return json.loads((tmp_path / "r" / "f.0001.exr.json").read_text())


def test03_auto_is_the_default_and_the_sidecar_says_what_it_chose(tmp_path):
    plain = build(tmp_path / "plain.usda")
    rec = _render(tmp_path, plain, "--frames", "1")
    assert rec["settings"]["integrator"] == "pt"
    assert rec["settings"]["integrator_auto"]["name"] == "pt"
    assert rec["settings_sources"]["integrator"].startswith("auto (default): ")
    glass = build(tmp_path / "glass.usda", sphere=GLASS)
    rec = _render(tmp_path, glass, "--frames", "1", "--integrator", "auto")
    assert rec["settings"]["integrator"] == "bdpt"
    assert rec["settings_sources"]["integrator"].startswith("auto (flag --integrator): caustics")


def test04_a_flag_or_the_stage_choosing_is_not_overridden(tmp_path):
    glass = build(tmp_path / "glass.usda", sphere=GLASS)
    rec = _render(tmp_path, glass, "--frames", "1", "--integrator", "bdpt")
    assert rec["settings"]["integrator"] == "bdpt" and "integrator_auto" not in rec["settings"]
    from pxr import Usd, UsdRender
    stage = Usd.Stage.Open(glass)
    prim = UsdRender.Settings(stage.GetPrimAtPath("/Render/Settings")).GetPrim()
    prim.ApplyAPI("CmltRenderSettingsAPI")
    prim.GetAttribute("cmlt:integrator").Set("pt")
    stage.GetRootLayer().Save()
    rec = _render(tmp_path, glass, "--frames", "1")
    assert rec["settings"]["integrator"] == "pt" and "integrator_auto" not in rec["settings"]


def test05_the_choice_is_printed_with_its_reason(tmp_path, capsys):
    shot = build(tmp_path / "glass.usda", sphere=GLASS)
    code = main(["render", shot, "--frames", "1", "--out", str(tmp_path / "p.####.exr"),
                 "--spp", "2", "--res", "16x12", "--threads", "2"])
    assert code == 0
    err = capsys.readouterr().err
    assert "cmlt: integrator auto: bdpt (caustics: at frame 1," in err


def test06_sidecars_record_the_effects_of_each_frame(tmp_path):
    shot = build(tmp_path / "moving.usda", move=True, shutter=(0.0, 0.5), sphere=GLASS)
    out = tmp_path / "m" / "m.####.exr"
    assert main(["render", shot, "--frames", "1:2", "--out", str(out), "--spp", "2",
                 "--res", "16x12", "--threads", "2", "--integrator", "pt", "--quiet"]) == 0
    for f in (1, 2):
        rec = json.loads((tmp_path / "m" / f"m.000{f}.exr.json").read_text())
        e = rec["effects"]
        assert e["time"] == f and list(e["effects"]) == list(EFFECT_NAMES)
        assert e["effects"]["motion_blur"] and e["effects"]["caustics"]
        assert e["probes"]["camera_paths"] == 256
    # the sidecar's effects are what inspect reports for the frame
    rep = inspect(shot, "--frames", "2")
    rec = json.loads((tmp_path / "m" / "m.0002.exr.json").read_text())
    assert rec["effects"]["effects"] == rep["per_frame"][0]["effects"]


def test07_bad_frames_for_inspect_are_a_usage_error(tmp_path, capsys):
    shot = build(tmp_path / "plain.usda")
    assert main(["inspect", shot, "--frames", "x:y", "--json"]) == 2
    assert "cmlt: error:" in capsys.readouterr().err
