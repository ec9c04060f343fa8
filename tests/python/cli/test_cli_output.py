"""`cmlt render` output options end to end (issue 6): previews, crop windows,
header metadata, `cmlt inspect --image`, `--log-json`, `--quiet`, the summary
table; `cmlt contact-sheet` is in test_contact_sheet_cli.py."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt import __version__
from cmlt.cli import main
from cmlt.color import get_config, load_config, set_config
from cmlt.io.exr import read_exr, read_header

FAST = ["--spp", "4", "--res", "32x24", "--threads", "2"]


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _read(path):
    buf = oiio.ImageBuf(path)
    spec = buf.spec()
    pix = np.asarray(buf.get_pixels(buf.spec().format), copy=True)
    return spec, pix.reshape(spec.height, spec.width, spec.nchannels)


# ---------------------------------------------------------------- previews

@pytest.mark.parametrize("fmt", ["png", "jpg"])
def test01_preview_beside_each_exr_through_the_display_view(tiny_shot, tmp_path, capsys, fmt):
    out = str(tmp_path / "r" / "t.####.exr")
    args = ["render", tiny_shot, "--frames", "1:2", "--out", out, *FAST, "--preview", "--quiet"]
    if fmt == "jpg":
        args += ["--preview-format", "jpg"]
    assert main(args) == 0, capsys.readouterr().err
    for f in (1, 2):
        exr = tmp_path / "r" / f"t.{f:04d}.exr"
        pv = tmp_path / "r" / f"t.{f:04d}.{fmt}"
        assert exr.is_file() and pv.is_file()
        spec, pix = _read(str(pv))
        assert (spec.width, spec.height, spec.nchannels) == (32, 24, 3)
        assert spec.format == oiio.UINT8
        img, _ = read_exr(str(exr))                      # ACEScg (the default output)
        cfg = get_config()
        want = cfg.display_transform(img, None, None, dtype=np.uint8)
        if fmt == "png":
            np.testing.assert_array_equal(pix, want)     # lossless: exactly the transform
        else:
            assert np.abs(pix.astype(int) - want.astype(int)).mean() < 6
        doc = json.load(open(str(exr) + ".json"))
        assert doc["preview"] == pv.name
        assert doc["settings"]["display"] == "sRGB - Display"
        assert doc["settings"]["view"] == cfg.default_view("sRGB - Display")


def test02_preview_other_view_differs(tiny_shot, tmp_path, capsys):
    cfg = get_config()
    views = list(cfg.ocio.getViews("sRGB - Display"))
    other = next(v for v in views if v != cfg.default_view("sRGB - Display") and "Raw" not in v)
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    assert main(["render", tiny_shot, "--out", str(a), *FAST, "--preview", "-q"]) == 0
    assert main(["render", tiny_shot, "--out", str(b), *FAST, "--preview", "-q",
                 "--display", "sRGB - Display", "--view", other]) == 0
    assert not np.array_equal(_read(str(tmp_path / "a.png"))[1], _read(str(tmp_path / "b.png"))[1])


@pytest.mark.parametrize("flag,value", [("--display", "No Such Display"),
                                        ("--view", "No Such View")])
def test03_unknown_display_or_view_is_a_usage_error(tiny_shot, tmp_path, capsys, flag, value):
    code = main(["render", tiny_shot, "--out", str(tmp_path / "x.exr"), *FAST, "--preview",
                 flag, value])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"cmlt: error: {flag}")
    assert value in err[0] and not (tmp_path / "x.exr").exists()


# ---------------------------------------------------------------- crop, metadata

def test04_crop_sets_data_and_display_windows(tiny_shot, tmp_path, capsys):
    full, crop = tmp_path / "full.exr", tmp_path / "crop.exr"
    assert main(["render", tiny_shot, "--out", str(full), *FAST, "-q",
                 "--aov", "depth,variance"]) == 0
    assert main(["render", tiny_shot, "--out", str(crop), *FAST, "-q", "--crop", "4,2,20,18",
                 "--aov", "depth,variance"]) == 0
    inp = oiio.ImageInput.open(str(crop))
    spec = inp.spec()
    inp.close()
    assert (spec.x, spec.y, spec.width, spec.height) == (4, 2, 16, 16)          # data window
    assert (spec.full_x, spec.full_y, spec.full_width, spec.full_height) == (0, 0, 32, 24)
    h = read_header(str(crop))
    assert h["data_window"] == (4, 2, 20, 18) and h["display_window"] == (0, 0, 32, 24)
    a, _ = read_exr(str(full))
    b, _ = read_exr(str(crop))
    np.testing.assert_array_equal(b, a[2:18, 4:20])      # same seed: the same pixels
    assert json.load(open(str(crop) + ".json"))["settings"]["crop"] == [4, 2, 20, 18]


@pytest.mark.parametrize("crop", ["0,0,33,24", "30,0,40,10"])
def test05_crop_outside_the_frame_names_the_flag(tiny_shot, tmp_path, capsys, crop):
    code = main(["render", tiny_shot, "--out", str(tmp_path / "x.exr"), *FAST, "--crop", crop])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--crop" in err[0] and "32x24" in err[0]


@pytest.mark.parametrize("crop", ["1,2,3", "5,5,5,9", "a,b,c,d", "-1,0,4,4"])
def test06_malformed_crop(tiny_shot, tmp_path, capsys, crop):
    assert main(["render", tiny_shot, "--out", str(tmp_path / "x.exr"), f"--crop={crop}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--crop" in err[0]


def test07_header_metadata(tiny_shot, tmp_path, capsys):
    out = tmp_path / "m.####.exr"
    assert main(["render", tiny_shot, "--frames", "2", "--out", str(out), *FAST, "--seed", "9",
                 "-q"]) == 0
    h = read_header(str(tmp_path / "m.0002.exr"))
    md = h["cmlt"]
    assert md["frame"] == 2 and md["timeCode"] == 2
    assert md["shot"] == os.path.abspath(tiny_shot) and md["camera"] == "/World/Cam"
    assert md["integrator"] == "pt" and md["seed"] == 9 and md["spp"] == 4
    params = json.loads(md["integratorParameters"])
    assert params["spp"] == 4 and params["seed"] == 9 and params["integrator"] == "pt"
    # paths traced: the image and the default gaussian's one-pixel ring, 4 passes
    assert md["samples"] == (32 + 2) * (24 + 2) * 4 and md["renderTime"] > 0 and md["rays"] > 0
    assert md["version"] == __version__
    assert h["colorspace"] == "lin_ap1_scene" and len(h["chromaticities"]) == 8


def test08_b_estimates_and_mutations_go_into_the_header_when_reported():
    from types import SimpleNamespace
    from cmlt.settings import RenderSettings
    from cmlt.shot.output import header_metadata as _header_metadata

    fs = SimpleNamespace(time=3.0)
    md = _header_metadata(3.0, fs, "/s.usda", "/cam", RenderSettings(),
                          {"time_s": 1.5, "b": 0.25, "b_stderr": 0.01, "mutations": 1000,
                           "mutations_per_pixel": 2.5})
    assert md["b"] == 0.25 and md["bStderr"] == 0.01 and md["mutations"] == 1000
    assert md["mutationsPerPixel"] == 2.5 and md["renderTime"] == 1.5
    md = _header_metadata(3.0, fs, "/s.usda", "/cam", RenderSettings(), {"time_s": 1.0})
    assert "b" not in md and "mutations" not in md


# ---------------------------------------------------------------- inspect --image

def test09_inspect_image_prints_the_header(tiny_shot, tmp_path, capsys):
    out = tmp_path / "i.exr"
    assert main(["render", tiny_shot, "--out", str(out), *FAST, "-q", "--crop", "0,0,16,12",
                 "--aov", "albedo,normal"]) == 0
    capsys.readouterr()
    assert main(["inspect", "--image", str(out)]) == 0
    text = capsys.readouterr().out
    for want in ("channels (9):", "albedo.R", "N.X", "data window:    (0, 0) - (15, 11)  [16 x 12]",
                 "display window: (0, 0) - (31, 23)  [32 x 24]", "colour space: lin_ap1_scene",
                 "chromaticities: (0.713, 0.293", "compression: zip", "cmlt metadata:",
                 "integrator", "seed", "renderTime"):
        assert want in text, (want, text)
    assert re.search(rf"^  version +{re.escape(__version__)}$", text, re.M)


@pytest.mark.parametrize("args,needle", [
    (["inspect", "--image", "nope.exr"], "--image nope.exr: no such file"),
    (["inspect"], "give a SHOT"),
])
def test10_inspect_errors(args, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


# ---------------------------------------------------------------- farm output

def _run(args, cwd):
    return subprocess.run([sys.executable, "-m", "cmlt", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


def test11_log_json_is_one_object_per_line_and_nothing_else(make_shot, tmp_path):
    shot = make_shot("warn.usda", {"float focalLength = 24": "float focalLength = 0"})
    proc = _run(["render", shot, "--frames", "1:3", "--out", str(tmp_path / "j.####.exr"),
                 *FAST, "--log-json", "--preview"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    events = [json.loads(line) for line in proc.stdout.splitlines()]   # every line parses
    kinds = [e["event"] for e in events]
    assert kinds[0] == "warning" or kinds[0] == "sequence_start"
    assert kinds.count("frame_start") == 3 and kinds.count("frame_done") == 3
    assert kinds[-1] == "sequence_done"
    assert sum(k == "warning" for k in kinds) == 1                     # printed once
    assert "focalLength is 0" in next(e for e in events if e["event"] == "warning")["message"]
    done = [e for e in events if e["event"] == "frame_done"]
    assert [e["frame"] for e in done] == [1.0, 2.0, 3.0]
    for e in done:
        assert os.path.isfile(e["path"]) and e["time_s"] > 0 and e["rays_per_s"] > 0
        assert e["rays"] > 0
    end = events[-1]
    assert end["frames"] == 3 and end["total_time_s"] > 0 and end["mean_frame_time_s"] > 0
    assert end["rays_per_s"] > 0 and len(end["previews"]) == 3
    assert all("t" in e for e in events)


def test12_log_json_errors_are_events_too(tiny_shot, tmp_path):
    proc = _run(["render", tiny_shot, "--out", str(tmp_path / "x.exr"), "--camera", "/nope",
                 "--log-json"], tmp_path)
    assert proc.returncode == 2
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    assert events and events[-1]["event"] == "error" and "--camera" in events[-1]["message"]
    assert events[-1]["exit_code"] == 2
    assert proc.stderr.strip().startswith("cmlt: error: --camera")


def test13_quiet_prints_nothing_not_even_warnings(make_shot, tmp_path, capsys):
    shot = make_shot("warn.usda", {"float focalLength = 24": "float focalLength = 0"})
    assert main(["render", shot, "--out", str(tmp_path / "q.exr"), *FAST, "--quiet"]) == 0
    cap = capsys.readouterr()
    assert cap.err == "" and cap.out == ""


def test14_quiet_and_log_json_exclusive(tiny_shot, capsys):
    assert main(["render", tiny_shot, "--quiet", "--log-json"]) == 2
    assert "not allowed with" in capsys.readouterr().err


def test15_summary_table_on_completion(tiny_shot, tmp_path, capsys):
    assert main(["render", tiny_shot, "--frames", "1:3", "--out", str(tmp_path / "s.#.exr"),
                 *FAST]) == 0
    err = capsys.readouterr().err
    assert "cmlt render summary" in err
    for col in ("frames", "total time", "mean / frame", "rays/s"):
        assert col in err
    row = [line for line in err.splitlines() if "rays/s" in line and " s " in line][-1]
    assert " 3 " in row
