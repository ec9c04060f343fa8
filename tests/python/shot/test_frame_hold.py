"""Frame holding (frame_job.hold_key, --no-frame-hold): a frame whose core scene and
random numbers are the frame before's takes that frame's render.

A static shot with stored seeds renders the same image every frame (the streams are
keyed by seed, chain and dimension, never by the frame; the carried chains keep their
starts), so the held frames must be bit-identical to rendering them — for pt and for
cmlt with carried chains and the smoothed normalisation — and no frame of a shot where
something moves (a light, the camera) may be held. With a target error, a static shot's
later frames then stop at once: the first frame's estimate and stop reason, no work.
"""
import json
import os

import numpy as np
import pytest

from cmlt.metrics import load_image
from cmlt.shot import RenderOptions, render_sequence

import support

STATIC = os.path.join(str(support.SEQUENCES), "static_flicker", "shot.usda")
MOVING = os.path.join(str(support.SEQUENCES), "moving_light", "shot.usda")
PAN = os.path.join(str(support.SEQUENCES), "camera_pan", "shot.usda")
CHAINS = dict(mlt_paths="all", chains=64, bootstrap_samples=1024)


def _run(tmp_path, name, shot, frames="1:4", **kw):
    base = dict(integrator="pt", resolution=(32, 24), spp=16, threads=0)
    base.update(kw)
    r = render_sequence(shot, frames, str(tmp_path / name / "f.####.exr"), RenderOptions(**base),
                        progress=False, quiet=True)
    return ([load_image(p) for p in r.written],
            [json.load(open(p + ".json"))["stats"] for p in r.written])


@pytest.mark.parametrize("integrator,extra", [("pt", {}), ("cmlt", CHAINS)], ids=["pt", "cmlt"])
def test_a_static_shot_holds_its_first_frame_bit_for_bit(tmp_path, integrator, extra):
    held, st = _run(tmp_path, "hold", STATIC, integrator=integrator, **extra)
    every, st0 = _run(tmp_path, "every", STATIC, integrator=integrator, hold_frames=False, **extra)
    assert [s.get("held_from_frame") for s in st] == [None, 1.0, 1.0, 1.0]
    assert all("held_from_frame" not in s for s in st0)
    for a, b in zip(held, every):
        assert np.array_equal(a, b)
    assert all(s["time_s"] == 0.0 and s["rays"] == 0 for s in st[1:])
    assert st[0]["rays"] > 0 and all(s["rays"] > 0 for s in st0)


@pytest.mark.parametrize("shot", [MOVING, PAN], ids=["moving_light", "camera_pan"])
def test_nothing_is_held_where_something_moves(tmp_path, shot):
    _, st = _run(tmp_path, "m", shot, frames="1:3")
    assert all("held_from_frame" not in s for s in st)


def test_a_time_budget_renders_every_frame(tmp_path):
    _, st = _run(tmp_path, "t", STATIC, frames="1:2", spp=1 << 20, time_budget=0.2)
    assert all("held_from_frame" not in s for s in st)


def test_a_static_shot_stops_at_its_target_error_at_once_after_the_first_frame(tmp_path):
    _, st = _run(tmp_path, "target", STATIC, frames="1:3", spp=4096, target_error=0.02)
    assert st[0]["stop_reason"] == "target" and st[0]["time_s"] > 0
    for s in st[1:]:
        assert s["held_from_frame"] == 1.0 and s["time_s"] == 0.0
        assert s["stop_reason"] == "target"
        assert s["error_estimate"]["relmse"] == st[0]["error_estimate"]["relmse"] <= 0.02


@pytest.mark.parametrize("flag", [[], ["--no-frame-hold"]], ids=["default", "no-frame-hold"])
def test_the_command_line_flag(tmp_path, flag):
    from cmlt.cli import main as cli_main
    out = str(tmp_path / "cli" / "f.####.exr")
    code = cli_main(["render", STATIC, "--frames", "1:2", "--res", "16x16", "--spp", "4",
                     "--integrator", "pt", "--out", out, "--quiet"] + flag)
    assert code == 0
    second = json.load(open(out.replace("####", "0002") + ".json"))["stats"]
    assert second.get("held_from_frame") == (None if flag else 1.0)
