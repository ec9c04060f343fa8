"""No raw Python warning reaches stderr from ``cmlt render`` or ``cmlt inspect``.

A texture file that exists but is not an image used to print Python's two raw
``UserWarning`` lines: the default integrator (``auto``) analyses the frame
before the frame loop catches the scene bridge's warnings, and ``cmlt inspect``
analyses it too. The renders run in a child process (as a user runs them), so
stderr is the CLI's own and Python's default warning display is in force.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings

from cmlt.shot.py_warnings import WarningRouter, warning_text
from test_bad_input import MISSING_TEXTURE

OWN = ("cmlt: ", "frame ", "┏", "┃", "┡", "│", "└", "flicker =", "cmlt render summary")
#: the stage of test_bad_input's missing-texture test, its texture a file that is no image
BROKEN_TEXTURE = {old: new.replace("missing_tex.png", "broken.png")
                  for old, new in MISSING_TEXTURE.items()}


def _cmlt(args, cwd):
    env = dict(os.environ)
    env.pop("OCIO", None)
    return subprocess.run([sys.executable, "-m", "cmlt", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def _raw(err):
    return [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(OWN)]


def _broken_shot(make_shot, tmp_path):
    shot = make_shot("broken.usda", BROKEN_TEXTURE)
    (tmp_path / "broken.png").write_text("not a png")
    return shot


def test01_render_with_auto_integrator_has_no_raw_warning(make_shot, tmp_path):
    shot = _broken_shot(make_shot, tmp_path)
    proc = _cmlt(["render", shot, "--out", str(tmp_path / "b.####.exr"), "--spp", "2",
                  "--res", "32x24", "--frames", "1-2"], str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    assert _raw(proc.stderr) == [], proc.stderr
    assert "UserWarning" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if "broken.png" in ln]
    assert len(lines) == 1, proc.stderr                      # once per cause, both frames
    assert lines[0].startswith("cmlt: warning: /World/Looks/Tex: texture file ")
    assert "cannot be read" in lines[0]


def test02_log_json_gets_it_as_one_warning_event(make_shot, tmp_path):
    shot = _broken_shot(make_shot, tmp_path)
    proc = _cmlt(["render", shot, "--out", str(tmp_path / "j.####.exr"), "--spp", "2",
                  "--res", "32x24", "--frames", "1-2", "--log-json"], str(tmp_path))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    events = [json.loads(ln) for ln in proc.stdout.splitlines()]
    warns = [e["message"] for e in events if e["event"] == "warning" and "broken.png" in
             e["message"]]
    assert len(warns) == 1 and warns[0].startswith("/World/Looks/Tex: "), warns


def test03_inspect_prints_it_as_a_cmlt_warning(make_shot, tmp_path):
    shot = _broken_shot(make_shot, tmp_path)
    proc = _cmlt(["inspect", shot], str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    assert _raw(proc.stderr) == [], proc.stderr
    assert any(ln.startswith("cmlt: warning: /World/Looks/Tex: ") and "broken.png" in ln
               for ln in proc.stderr.splitlines()), proc.stderr


def test04_a_library_warning_names_its_category_and_origin():
    router = WarningRouter()
    got = []
    with router.routing():
        warnings.warn_explicit("something odd", RuntimeWarning, "/lib/site-packages/x.py", 7)
        warnings.warn_explicit("  spread\n over lines ", UserWarning,
                               os.path.join(os.path.dirname(warning_text.__code__.co_filename),
                                            "bridge.py"), 3)
        assert router.attach(got.extend) == ["RuntimeWarning from x.py:7: something odd",
                                             "spread over lines"]
        warnings.warn_explicit("later", FutureWarning, "/lib/y.py", 1)
    assert got == ["FutureWarning from y.py:1: later"]
