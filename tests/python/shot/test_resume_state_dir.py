"""Resuming an interrupted sequence keeps the temporal state (issue 6 / DESIGN.md
§4): the Ctrl-C hint carries --state-dir when one was used, and resuming a
pssmlt/cmlt sequence without one warns that its chains start fresh."""
from __future__ import annotations

import shlex

import pytest

import cmlt.shot as shot_pkg
from cmlt.cli import _resume_command, main
from cmlt.shot import RenderCancelled, RenderOptions, render_sequence

MLT = ["--integrator", "pssmlt", "--spp", "4", "--res", "8x6", "--threads", "2",
       "--chains", "16", "--bootstrap-samples", "64"]


def test01_resume_command_keeps_the_state_dir():
    argv = ["render", "s.usda", "--frames", "1:9", "--state-dir", "st"]
    assert _resume_command(argv, "st") == "cmlt render s.usda --frames 1:9 --state-dir st --resume"
    # an abbreviated flag (argparse accepts --state) is spelt out
    cmd = shlex.split(_resume_command(["render", "s.usda", "--state", "st"], "st"))
    assert cmd[-2:] == ["--state-dir", "st"] and "--resume" in cmd
    assert "--state-dir" not in _resume_command(["render", "s.usda"], None)
    assert _resume_command(["render", "s.usda", "--state-dir=st"], "st").count("state-dir") == 1


def test02_ctrl_c_hint_names_the_state_dir(tiny_shot, tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise RenderCancelled(2.0, [str(tmp_path / "a.0001.exr")], 1)

    monkeypatch.setattr(shot_pkg, "render_sequence", interrupted)
    code = main(["render", tiny_shot, "--frames", "1:3", "--out", str(tmp_path / "a.####.exr"),
                 "--state", str(tmp_path / "st"), *MLT])
    assert code == 130
    err = capsys.readouterr().err
    hint = next(line for line in err.splitlines() if "to continue:" in line)
    cmd = shlex.split(hint.split("to continue: ", 1)[1])
    assert "--resume" in cmd
    assert cmd[cmd.index("--state-dir") + 1] == str(tmp_path / "st")


def _opts(**kw):
    return RenderOptions(integrator="pssmlt", spp=4, resolution=(8, 6), threads=2, chains=16,
                         bootstrap_samples=64, **kw)


def test03_resume_without_state_dir_warns_that_chains_start_fresh(tiny_shot, tmp_path):
    pattern = str(tmp_path / "r.####.exr")
    render_sequence(tiny_shot, "1", pattern, _opts(), progress=False, quiet=True)
    res = render_sequence(tiny_shot, "1:2", pattern, _opts(), resume=True, progress=False,
                          quiet=True)
    assert len(res.skipped) == 1 and len(res.written) == 1
    cold = [w for w in res.warnings if "--resume without --state-dir" in w]
    assert len(cold) == 1, res.warnings
    assert "frame 2 follows frame 1" in cold[0] and "chains start fresh" in cold[0]


def test04_resume_with_state_dir_or_pt_does_not_warn(tiny_shot, tmp_path):
    pattern = str(tmp_path / "s.####.exr")
    state = str(tmp_path / "state")
    render_sequence(tiny_shot, "1", pattern, _opts(state_dir=state), progress=False, quiet=True)
    res = render_sequence(tiny_shot, "1:2", pattern, _opts(state_dir=state), resume=True,
                          progress=False, quiet=True)
    assert not any("--resume without --state-dir" in w for w in res.warnings), res.warnings
    assert res.written and res.skipped
    pt = RenderOptions(spp=1, resolution=(8, 6), threads=2)
    ptpat = str(tmp_path / "p.####.exr")
    render_sequence(tiny_shot, "1", ptpat, pt, progress=False, quiet=True)
    res = render_sequence(tiny_shot, "1:2", ptpat, pt, resume=True, progress=False, quiet=True)
    assert not any("--state-dir" in w for w in res.warnings)      # pt has no temporal state
