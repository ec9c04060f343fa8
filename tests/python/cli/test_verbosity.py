"""``-v`` levels (husk style): ``-v 0`` errors only, default normal, ``-v``/``-v 2``
verbose (set-up and a details line per frame), ``-vv``/``-v 3`` debug (settings with
their sources, scene update, effects). Each level's effect on stderr is checked on a
stage that also has a warning (a RenderVar cmlt does not render)."""
from __future__ import annotations

import json
import textwrap

import pytest

from cmlt.cli import main
from support.stages import facing_quad_shot

SHOT = facing_quad_shot(3.0, (0.5, 0.5, 0.5), textwrap.dedent('''\
    def RenderSettings "Settings"
    {
        rel camera = </Cam>
        rel products = </Product>
    }
    def RenderProduct "Product"
    {
        rel orderedVars = </Position>
    }
    def RenderVar "Position"
    {
        uniform string sourceName = "P"
        uniform token dataType = "point3f"
    }
    '''))


pytestmark = pytest.mark.usefixtures("builtin_color_config")


@pytest.fixture
def shot(tmp_path):
    p = tmp_path / "shot.usda"
    p.write_text(SHOT)
    return str(p)


def _err(shot, tmp_path, capsys, *flags):
    code = main(["render", shot, "--spp", "1", "--res", "16x12", "--integrator", "pt",
                 "--out", str(tmp_path / "v.exr"), *flags])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.err


WARNING = "cmlt: warning: /Position"
DETAIL = "cmlt: frame 1: 16x12, camera /Cam, pt 1 spp"
SETUP = "rendering space 'ACEScg'"
DEBUG = "cmlt: setting spp = 1 (flag --spp)"


def test01_level_0_prints_nothing(shot, tmp_path, capsys):
    assert _err(shot, tmp_path, capsys, "-v", "0") == ""


def test02_default_level_1_warnings_and_frame_lines_only(shot, tmp_path, capsys):
    err = _err(shot, tmp_path, capsys)
    assert WARNING in err and "frame 1: " in err and "1 frame(s) written" in err
    assert DETAIL not in err and SETUP not in err and DEBUG not in err
    assert DETAIL not in _err(shot, tmp_path, capsys, "-v", "1")


@pytest.mark.parametrize("flags", [("-v",), ("-v", "2"), ("--verbosity", "2")])
def test03_level_2_adds_setup_and_per_frame_details(shot, tmp_path, capsys, flags):
    err = _err(shot, tmp_path, capsys, *flags)
    assert WARNING in err and DETAIL in err and SETUP in err
    assert "load " in err and "render " in err and "scene rebuilt (first frame)" in err
    assert DEBUG not in err and "scene update {" not in err


@pytest.mark.parametrize("flags", [("-vv",), ("-v", "3"), ("-vvvv",), ("-V", "9")])
def test04_level_3_adds_settings_sources_scene_update_and_effects(shot, tmp_path, capsys,
                                                                  flags):
    err = _err(shot, tmp_path, capsys, *flags)
    assert WARNING in err and DETAIL in err and DEBUG in err
    assert "cmlt: frame 1: scene update {" in err and "cmlt: frame 1: effects {" in err


def test05_quiet_and_a_verbose_level_conflict(shot, tmp_path, capsys):
    code = main(["render", shot, "--out", str(tmp_path / "v.exr"), "--quiet", "-v", "2"])
    err = capsys.readouterr().err
    assert code == 2 and "--quiet" in err and "-v 2" in err


def test06_log_json_carries_details_as_events_and_stderr_stays_empty(shot, tmp_path, capsys):
    code = main(["render", shot, "--spp", "1", "--res", "16x12", "--integrator", "pt",
                 "--out", str(tmp_path / "v.exr"), "--log-json", "-v"])
    out = capsys.readouterr()
    assert code == 0 and out.err == ""
    events = [json.loads(line) for line in out.out.splitlines()]
    details = [e for e in events if e["event"] == "detail"]
    assert details and all(e["level"] == 2 for e in details)
    assert any(e["message"].startswith("frame 1: 16x12") for e in details)
