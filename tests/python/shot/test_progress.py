"""What a user sees while and after a sequence renders (issue 6): the
progress reporter under a fake terminal (live rate from the first frame,
ETA, per-frame lines), and the completion summary with the frame-to-frame
flicker in the table and in `--log-json`'s `sequence_done`."""
from __future__ import annotations

import io
import json
import os
import time

import numpy as np
import pytest
from rich.console import Console

from cmlt.cli import main
from cmlt.io.exr import read_exr
from cmlt.metrics import FrameDifferenceFlicker, flicker
from cmlt.shot.progress import (JsonReporter, Reporter, format_flicker, sequence_summary,
                                summary_table)
from cmlt.shot.sequence import SequenceResult

FAST = ["--spp", "4", "--res", "32x24", "--threads", "2"]


# ---------------------------------------------------------------- flicker

def test01_accumulated_flicker_equals_the_metric(rng):
    """FrameDifferenceFlicker (one frame at a time) gives cmlt.metrics.flicker's
    frame-difference TF and GF for an unbroken run."""
    frames = [rng.uniform(0.5, 1.5, (6, 8, 3)) * (1 + 0.1 * k) for k in range(5)]
    acc = FrameDifferenceFlicker()
    for img in frames:
        acc.add(img)
    rep = flicker(frames)
    assert acc.pairs == 4 and acc.frames == 5
    assert acc.tf == pytest.approx(rep.tf, rel=1e-12)
    assert acc.gf == pytest.approx(rep.gf, rel=1e-12)
    d = acc.as_dict()
    assert d["flicker"] == pytest.approx(rep.tf) and d["flicker_pairs"] == 4


def test02_flicker_pairs_only_consecutive_frames(rng):
    a, b, c = (rng.uniform(0, 1, (4, 4, 3)) for _ in range(3))
    acc = FrameDifferenceFlicker()
    acc.add(a)
    assert acc.tf is None and acc.as_dict()["flicker"] is None      # one frame: not measured
    acc.add(b, follows=False)                                        # a gap (--resume)
    assert acc.pairs == 0 and acc.tf is None
    acc.add(c)
    norm = np.mean([a.mean(), b.mean(), c.mean()])
    assert acc.tf == pytest.approx(np.mean(np.abs(c - b)) / norm)
    black = FrameDifferenceFlicker()
    black.add(np.zeros((2, 2, 3)))
    black.add(np.zeros((2, 2, 3)))
    assert black.tf is None and black.gf is None                     # not normalisable


def test03_summary_reports_the_flicker(rng):
    res = SequenceResult(frames=[1.0, 2.0], written=["a", "b"],
                         stats={1.0: {"time_s": 1.0, "rays": 10}, 2.0: {"time_s": 1.0, "rays": 10}},
                         flicker={"flicker": 0.0123, "global_flicker": 0.01, "flicker_pairs": 1})
    s = sequence_summary(res)
    assert s["flicker"] == 0.0123 and s["global_flicker"] == 0.01 and s["flicker_pairs"] == 1
    buf = io.StringIO()
    Console(file=buf, width=200).print(summary_table(res))
    text = buf.getvalue()
    assert "flicker" in text and "1.23 %" in text and "consecutive frames" in text
    assert format_flicker(None) == "-"
    assert sequence_summary(SequenceResult())["flicker"] is None


def test04_log_json_sequence_done_has_the_measured_flicker(tiny_shot, tmp_path, capsys):
    """Three frames rendered: sequence_done's flicker is the frame-difference TF of
    the three EXRs written (the same number `cmlt flicker` would print)."""
    pattern = str(tmp_path / "f.####.exr")
    assert main(["render", tiny_shot, "--frames", "1:3", "--out", pattern, *FAST,
                 "--log-json"]) == 0
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    done = events[-1]
    assert done["event"] == "sequence_done"
    images = [read_exr(str(tmp_path / f"f.{f:04d}.exr"))[0] for f in (1, 2, 3)]
    want = flicker(images)
    assert done["flicker_pairs"] == 2
    assert done["flicker"] == pytest.approx(want.tf, rel=1e-5)
    assert done["global_flicker"] == pytest.approx(want.gf, rel=1e-5, abs=1e-9)
    assert done["flicker"] > 0                       # the box moves: frames differ


def test05_summary_table_shows_flicker_and_single_frame_shows_none(tiny_shot, tmp_path, capsys):
    assert main(["render", tiny_shot, "--frames", "1:2", "--out", str(tmp_path / "s.#.exr"),
                 *FAST]) == 0
    err = capsys.readouterr().err
    header = next(line for line in err.splitlines() if "frames" in line and "rays/s" in line)
    assert header.rstrip(" ┃").endswith("flicker")
    row = [line for line in err.splitlines() if " %" in line and "rays/s" in line]
    assert row, err                                   # a measured value, not "-"
    assert main(["render", tiny_shot, "--frames", "1", "--out", str(tmp_path / "one.exr"),
                 *FAST, "--log-json"]) == 0
    done = [json.loads(x) for x in capsys.readouterr().out.splitlines()][-1]
    assert done["flicker"] is None and done["flicker_pairs"] == 0


# ---------------------------------------------------------------- progress reporter

def _terminal_reporter():
    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=160, highlight=False,
                      color_system=None)
    return Reporter(console=console), buf


def _rate(rep):
    task = next(t for t in rep._progress.tasks if t.description.startswith("frame"))
    return task.fields["rate"], task


def test06_live_rate_from_the_first_frame_then_rays_per_second():
    """Frame 1: the core has not counted rays yet, so the bar shows samples/s from
    the progress callback's samples so far; once a frame finished, rays/s from its
    rays per sample."""
    rep, buf = _terminal_reporter()
    assert rep.show_progress                          # a (fake) terminal: bars on
    with rep:
        rep.start_sequence(2)
        rep.start_frame(1)
        rep.frame_budget(1000)                        # e.g. 250 pixels x 4 spp
        rep._frame_t0 -= 2.0                          # 2 s into the frame
        rep.frame_progress(8, 16)                     # half the samples: 500 in 2 s
        rate, _ = _rate(rep)
        assert rate.startswith("~") and rate.endswith("samples/s"), rate
        assert float(rate[1:].split()[0]) == pytest.approx(250, rel=0.02)
        rep.end_frame(1, "out.0001.exr", {"rays": 5000, "samples": 1000, "time_s": 1.0,
                                          "rays_per_s": 5000.0}, 16)
        rep.start_frame(2)
        rep.frame_budget(1000)
        rep._frame_t0 -= 2.0
        rep.frame_progress(8, 16)
        rate, _ = _rate(rep)
        assert rate.startswith("~") and rate.endswith(" krays/s"), rate
        assert float(rate[1:].split()[0]) == pytest.approx(1.25, rel=0.02)  # 5 rays x 250/s
    out = buf.getvalue()
    assert "frame 1: 1.00 s, 5.00 krays/s -> out.0001.exr" in out


def test07_rate_unknown_without_a_sample_budget():
    rep, _ = _terminal_reporter()
    assert rep.live_rate(8, 16, 2.0) == ""            # no frame_budget (a time budget)
    rep.frame_budget(None)
    assert rep.live_rate(8, 16, 2.0) == ""
    rep.frame_budget(1000)
    assert rep.live_rate(0, 16, 2.0) == ""            # nothing done yet


def test08_eta_is_shown_while_a_frame_renders():
    rep, buf = _terminal_reporter()
    with rep:
        rep.start_sequence(1)
        rep.start_frame(1)
        rep.frame_budget(1000)
        rep.frame_progress(4, 16)
        time.sleep(0.3)
        rep.frame_progress(8, 16)
        _, task = _rate(rep)
        assert task.time_remaining is not None and 0.1 < task.time_remaining < 5.0
        rep._progress.refresh()
    out = buf.getvalue()
    assert "frame 1" in out and "8/16" in out and "samples/s" in out
    assert "0:00:0" in out                            # elapsed and remaining columns


def test09_no_terminal_no_bars_but_frame_lines():
    buf = io.StringIO()
    rep = Reporter(console=Console(file=buf, force_terminal=False, width=120))
    assert not rep.show_progress
    with rep:
        rep.start_sequence(1)
        rep.start_frame(3)
        rep.frame_budget(100)
        rep.frame_progress(1, 2)                      # no bar: nothing stored, no error
        rep.end_frame(3, "x.exr", {"time_s": 0.5, "rays_per_s": 2.5e6}, 2)
    assert buf.getvalue().strip() == "frame 3: 0.50 s, 2.50 Mrays/s -> x.exr"
    quiet_buf = io.StringIO()
    q = Reporter(console=Console(file=quiet_buf, force_terminal=True), quiet=True)
    with q:
        q.warn("w")
        q.end_frame(1, "y.exr", {"time_s": 1.0}, 1)
    assert quiet_buf.getvalue() == ""


def test10_json_reporter_accepts_the_budget_and_stays_silent_per_chunk():
    buf = io.StringIO()
    rep = JsonReporter(buf)
    rep.start_sequence(1)
    rep.start_frame(1)
    rep.frame_budget(100)
    rep.frame_progress(1, 2)
    kinds = [json.loads(line)["event"] for line in buf.getvalue().splitlines()]
    assert kinds == ["sequence_start", "frame_start"]
