"""husk / usdrecord habits on ``cmlt render``: ``-o``, ``-f/-n/-i``, ``--res W H``,
``--frames 1-3``, ``-R/--settings PRIM``, ``--list-cameras``, ``--exposure`` for
previews, a warning for frames outside the stage's time range, and an unknown
flag that points at ``cmlt render --help``. The tiny shot (frames 1..3, 32x24
from its RenderSettings) is the conftest's."""
from __future__ import annotations

import json

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt.cli import main
from cmlt.color import load_config, set_config
from cmlt.io.exr import read_exr

FAST = ["--spp", "2", "--threads", "2", "--integrator", "pt"]

SETTINGS = '''def RenderSettings "Settings"
    {
        int2 resolution = (32, 24)
        rel camera = </World/Cam>
    }'''
SECOND_SETTINGS = SETTINGS + '''
    def RenderSettings "Small"
    {
        int2 resolution = (12, 8)
        rel camera = </World/Cam2>
    }'''
SECOND_CAMERA = '''def Scope "Looks"'''
CAM2 = '''def Camera "Cam2"
        {
            float focalLength = 24
            float horizontalAperture = 36
            float verticalAperture = 24
            double3 xformOp:translate = (0, 1.5, 9)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }
        def Scope "Looks"'''


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _settings_shot(make_shot):
    return make_shot("two_settings.usda", {SETTINGS: SECOND_SETTINGS, SECOND_CAMERA: CAM2})


def _size(path):
    spec = oiio.ImageInput.open(path).spec()
    return spec.width, spec.height


def test01_o_f_n_i_and_res_w_h(tiny_shot, tmp_path):
    out = str(tmp_path / "h.####.exr")
    assert main(["render", tiny_shot, "-o", out, "-f", "1", "-n", "2", "-i", "2",
                 "--res", "20", "10", *FAST, "--quiet"]) == 0
    assert sorted(p.name for p in tmp_path.glob("h.*.exr")) == ["h.0001.exr", "h.0003.exr"]
    assert _size(str(tmp_path / "h.0003.exr")) == (20, 10)
    side = json.loads((tmp_path / "h.0003.exr.json").read_text())
    assert side["frame"] == 3.0 and side["resolution"] == [20, 10]


def test02_dash_range_is_a_colon_range(tiny_shot, tmp_path):
    a, b = str(tmp_path / "a.####.exr"), str(tmp_path / "b.####.exr")
    assert main(["render", tiny_shot, "--frames", "1-2", "-o", a, *FAST, "--quiet"]) == 0
    assert main(["render", tiny_shot, "--frames", "1:2", "-o", b, *FAST, "--quiet"]) == 0
    for f in (1, 2):
        ia, _ = read_exr(str(tmp_path / f"a.{f:04d}.exr"))
        ib, _ = read_exr(str(tmp_path / f"b.{f:04d}.exr"))
        np.testing.assert_array_equal(ia, ib)


def test03_frames_outside_the_time_range_warn(tiny_shot, tmp_path, capsys):
    out = str(tmp_path / "o.####.exr")
    assert main(["render", tiny_shot, "--frames", "3-5", "-o", out, *FAST,
                 "--res", "8x6", "--log-json"]) == 0
    events = [json.loads(l) for l in capsys.readouterr().out.splitlines()]
    warned = [e["message"] for e in events if e["event"] == "warning"
              and "outside the stage's time range" in e["message"]]
    assert len(warned) == 1 and "4, 5" in warned[0] and "1..3" in warned[0], warned
    capsys.readouterr()
    assert main(["render", tiny_shot, "--frames", "1:3", "-o", out, *FAST,
                 "--res", "8x6", "--log-json"]) == 0
    assert "outside the stage's time range" not in capsys.readouterr().out


def test04_settings_prim_chosen_with_R(make_shot, tmp_path, capsys):
    shot = _settings_shot(make_shot)
    out = str(tmp_path / "s.exr")
    assert main(["render", shot, "-o", out, *FAST, "--quiet"]) == 0
    assert _size(out) == (32, 24)                       # the first RenderSettings prim
    assert main(["render", shot, "-o", out, "-R", "/Render/Small", *FAST, "--quiet"]) == 0
    assert _size(out) == (12, 8)                        # and its camera
    assert json.loads((tmp_path / "s.exr.json").read_text())["camera"] == "/World/Cam2"
    assert main(["render", shot, "-o", out, "--settings", "/Render/Nope", *FAST]) == 2
    err = capsys.readouterr().err
    assert "--settings /Render/Nope" in err and "/Render/Settings, /Render/Small" in err
    assert main(["render", shot, "--list-cameras", "-R", "/Render/Small"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines == ["  /World/Cam", "* /World/Cam2"]
    assert main(["render", shot, "--list-cameras"]) == 0
    assert capsys.readouterr().out.splitlines() == ["* /World/Cam", "  /World/Cam2"]


def test05_exposure_scales_previews_only(tiny_shot, tmp_path):
    base, bright = str(tmp_path / "e0.exr"), str(tmp_path / "e1.exr")
    for out, stops in ((base, "0"), (bright, "1")):
        assert main(["render", tiny_shot, "-o", out, *FAST, "--preview", "--exposure", stops,
                     "--quiet"]) == 0
    i0, _ = read_exr(base)
    i1, _ = read_exr(bright)
    np.testing.assert_array_equal(i0, i1)               # the EXR as rendered
    p0 = np.asarray(oiio.ImageBuf(str(tmp_path / "e0.png")).get_pixels(oiio.FLOAT))
    p1 = np.asarray(oiio.ImageBuf(str(tmp_path / "e1.png")).get_pixels(oiio.FLOAT))
    lit = p0 > 0.05
    assert lit.any() and (p1[lit] >= p0[lit]).all() and p1[lit].mean() > 1.1 * p0[lit].mean()


def test06_flag_errors(tiny_shot, tmp_path, capsys):
    assert main(["render", tiny_shot, "--bogus"]) == 2
    assert "see `cmlt render --help`" in capsys.readouterr().err
    assert main(["render", tiny_shot, "--frames", "1", "-f", "1"]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["render", tiny_shot, "-n", "3"]) == 2
    assert "need -f/--frame" in capsys.readouterr().err


def _purpose_shot(tmp_path):
    from pxr import Usd, UsdGeom
    path = str(tmp_path / "purposes.usda")
    st = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    cam = UsdGeom.Camera.Define(st, "/World/Cam")
    cam.AddTranslateOp().Set((0, 0, 10))
    for name, purpose, x in (("Plain", None, -3), ("Hi", "render", -1), ("Lo", "proxy", 1),
                             ("Guide", "guide", 3)):
        s = UsdGeom.Sphere.Define(st, f"/World/Asset/{name}")
        s.AddTranslateOp().Set((x, 0, 0))
        if purpose:
            s.CreatePurposeAttr(purpose)
    st.GetRootLayer().Save()
    return path


def test07_purpose(tmp_path, capsys):
    from cmlt.usd import load_frame, open_stage
    shot = _purpose_shot(tmp_path)

    def names(purposes):
        fs = load_frame(open_stage(shot), None, resolution=(8, 8), purposes=purposes)
        return sorted(i.name.rsplit("/", 1)[-1] for i in fs.instances)

    assert names(None) == ["Hi", "Plain"]             # proxy has a render sibling; no guide
    assert names(("proxy",)) == ["Lo", "Plain"]
    assert names(("render", "proxy", "guide")) == ["Guide", "Hi", "Lo", "Plain"]
    out = str(tmp_path / "p.exr")
    assert main(["render", shot, "-o", out, "--res", "8x8", "--spp", "1", "--purpose",
                 "geometry,proxy", "--quiet"]) == 0
    assert json.loads((tmp_path / "p.exr.json").read_text())["stats"] is not None
    assert main(["render", shot, "-o", out, "--purpose", "preview"]) == 2
    assert "unknown purpose 'preview'" in capsys.readouterr().err
