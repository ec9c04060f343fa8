"""`cmlt render` / `cmlt inspect` end to end against the real core and reader:
outputs, sidecars, resume, Ctrl-C, and one-line errors with exit codes."""
import glob
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from cmlt import __version__
from cmlt.cli import main
from cmlt.io.atomic import TEMP_MARKER
from cmlt.io.exr import read_exr

FAST = ["--spp", "4", "--res", "32x24", "--threads", "2"]


def _exrs(directory):
    return sorted(glob.glob(os.path.join(str(directory), "*.exr")))


def _temps(directory):
    return [n for n in os.listdir(directory) if TEMP_MARKER in n]


def test_01_render_three_frames_in_process(tiny_shot, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["render", tiny_shot, "--frames", "1:3", "--out", str(out / "tiny.####.exr"),
                 *FAST, "--seed", "3"])
    err = capsys.readouterr().err
    assert code == 0, err
    images = _exrs(out)
    assert [os.path.basename(p) for p in images] == ["tiny.0001.exr", "tiny.0002.exr",
                                                      "tiny.0003.exr"]
    assert sorted(glob.glob(str(out / "*.exr.json"))) == [p + ".json" for p in images]
    assert _temps(out) == []
    pixels = []
    for frame, path in zip((1, 2, 3), images):
        img, meta = read_exr(path)
        assert img.shape == (24, 32, 3)
        assert np.isfinite(img).all()
        assert img.mean() > 0                       # the light reaches the camera
        assert meta["cmlt:frame"] == frame and meta["cmlt:timeCode"] == frame
        assert meta["cmlt:integrator"] == "pt" and meta["cmlt:seed"] == 3
        assert meta["cmlt:spp"] == 4 and meta["cmlt:camera"] == "/World/Cam"
        assert meta["cmlt:version"] == __version__
        assert meta["colorInteropID"] == "lin_ap1_scene"
        doc = json.load(open(path + ".json"))
        assert doc["frame"] == frame and doc["time_code"] == frame
        assert doc["image"] == os.path.basename(path)
        assert doc["settings"]["spp"] == 4 and doc["settings"]["seed"] == 3
        assert doc["resolution"] == [32, 24]
        for key in ("time_s", "rays", "samples", "rays_per_s"):
            assert key in doc["stats"], key
        assert doc["stats"]["rays"] > 0
        # frame 1 builds the scene; 2 and 3 only move the box
        assert doc["scene_update"]["rebuilt"] == (frame == 1)
        if frame > 1:
            assert doc["scene_update"]["transforms_updated"] == 1
        pixels.append(img)
    assert not np.array_equal(pixels[0], pixels[1])   # the box moved


def test_02_render_as_subprocess(tiny_shot, tmp_path):
    out = tmp_path / "sub"
    proc = subprocess.run([sys.executable, "-m", "cmlt", "render", tiny_shot, "--frames", "2,3",
                           "--out", str(out / "f_$F4.exr"), *FAST],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert [os.path.basename(p) for p in _exrs(out)] == ["f_0002.exr", "f_0003.exr"]
    assert "Traceback" not in proc.stderr
    assert "2 frame(s) written" in proc.stderr


def test_03_default_frame_and_output(tiny_shot, tmp_path, monkeypatch, capsys):
    """No --frames: the stage's start frame; no --out: renders/<stem>.####.exr."""
    monkeypatch.chdir(tmp_path)
    assert main(["render", tiny_shot, *FAST, "--quiet"]) == 0
    assert _exrs(tmp_path / "renders") == [str(tmp_path / "renders" / "tiny.0001.exr")]
    assert capsys.readouterr().err == ""                 # --quiet


def test_04_half_and_compression(tiny_shot, tmp_path):
    path = tmp_path / "h.exr"
    assert main(["render", tiny_shot, "--frames", "2", "--out", str(path), *FAST,
                 "--half", "--compression", "piz", "--quiet"]) == 0
    img, meta = read_exr(str(path))
    assert meta["format"] == "half" and meta["compression"] == "piz"


def test_05_resume_skips_existing_frames(tiny_shot, tmp_path, capsys):
    pattern = str(tmp_path / "r.####.exr")
    assert main(["render", tiny_shot, "--frames", "1", "--out", pattern, *FAST, "-q"]) == 0
    first = tmp_path / "r.0001.exr"
    before = (first.read_bytes(), first.stat().st_mtime_ns)
    capsys.readouterr()
    assert main(["render", tiny_shot, "--frames", "1:3", "--out", pattern, *FAST, "--resume"]) == 0
    err = capsys.readouterr().err
    assert "1 frame(s) already rendered" in err
    assert (first.read_bytes(), first.stat().st_mtime_ns) == before
    assert len(_exrs(tmp_path)) == 3


def test_06_same_seed_same_pixels(tiny_shot, tmp_path):
    """Re-rendering a frame with the same seed gives identical pixels, and the
    thread count does not change them (DESIGN.md §6)."""
    a, b = str(tmp_path / "a.exr"), str(tmp_path / "b.exr")
    assert main(["render", tiny_shot, "--frames", "2", "--out", a, *FAST, "-q"]) == 0
    assert main(["render", tiny_shot, "--frames", "2", "--out", b, "--spp", "4",
                 "--res", "32x24", "--threads", "1", "-q"]) == 0
    assert np.array_equal(read_exr(a)[0], read_exr(b)[0])


def test_07_loader_warnings_printed_once(make_shot, tmp_path, capsys):
    shot = make_shot("warn.usda", {"float focalLength = 24": "float focalLength = 0"})
    assert main(["render", shot, "--frames", "1:3", "--out", str(tmp_path / "w.#.exr"),
                 *FAST]) == 0
    err = capsys.readouterr().err
    assert err.count("focalLength is 0") == 1, err
    doc = json.load(open(tmp_path / "w.3.exr.json"))
    assert any("focalLength is 0" in w for w in doc["warnings"])


def _bad(make_shot, tiny_shot, tmp_path):
    out = str(tmp_path / "bad.####.exr")
    return {
        "missing file": (["render", str(tmp_path / "nope.usda"), "--out", out], 2,
                         "nope.usda: no such file"),
        "bad frames": (["render", tiny_shot, "--frames", "3:1", "--out", out], 2,
                       "--frames '3:1'"),
        "garbage frames": (["render", tiny_shot, "--frames", "one", "--out", out], 2,
                           "--frames 'one'"),
        "bad res": (["render", tiny_shot, "--res", "32by24", "--out", out], 2, "--res"),
        "zero res": (["render", tiny_shot, "--res", "0x24", "--out", out], 2, "--res"),
        "missing camera": (["render", tiny_shot, "--camera", "/World/Nope", "--out", out], 2,
                           "--camera /World/Nope: no prim"),
        "not a camera": (["render", tiny_shot, "--camera", "/World/Floor", "--out", out], 2,
                         "--camera /World/Floor: prim is a Mesh"),
        "unknown integrator": (["render", tiny_shot, "--integrator", "magic", "--out", out], 2,
                               "--integrator = 'magic' is not an allowed value"),
        "stage settings typo": (["render", make_shot("typo.usda", {
            "int2 resolution = (32, 24)":
            "int2 resolution = (32, 24)\n            uniform int cmlt:maxDept = 3"}),
            "--out", out], 1, "/Render/Settings: cmlt:maxDept is not a CmltRenderSettingsAPI "
            "attribute; did you mean cmlt:maxDepth?"),
        "no frame token": (["render", tiny_shot, "--frames", "1:2",
                            "--out", str(tmp_path / "x.exr")], 2, "--out"),
        "bad spp": (["render", tiny_shot, "--spp", "0", "--out", out], 2, "--spp"),
        "tcps=0": (["render", make_shot("tcps.usda", {"timeCodesPerSecond = 24":
                                                       "timeCodesPerSecond = 0"}),
                    "--out", out], 1, "timeCodesPerSecond is 0"),
        "tcps<0": (["render", make_shot("tcpsneg.usda", {"timeCodesPerSecond = 24":
                                                          "timeCodesPerSecond = -24"}),
                    "--out", out], 1, "timeCodesPerSecond is -24; it must be > 0"),
        "bad colorspace": (["render", tiny_shot, "--output-colorspace", "nope", "--out", out], 2,
                           "--output-colorspace 'nope': unknown colour space"),
        "bad ocio config": (["render", tiny_shot, "--ocio-config", str(tmp_path / "no.ocio"),
                             "--out", out], 2, "--ocio-config"),
        "unwritable out": (["render", tiny_shot, *FAST, "--out", _file_as_dir(tmp_path)], 2,
                           "cannot write into"),
        "inspect missing": (["inspect", str(tmp_path / "gone.usda")], 2, "gone.usda: no such file"),
        "no command": ([], 2, "COMMAND"),
    }


def _file_as_dir(tmp_path):
    (tmp_path / "afile").write_text("")
    return str(tmp_path / "afile" / "x.####.exr")


BAD_CASES = ["bad ocio config", "unwritable out", "bad colorspace", "missing file", "bad frames", "garbage frames", "bad res", "zero res",
             "missing camera", "not a camera", "unknown integrator", "stage settings typo", "no frame token",
             "bad spp", "tcps=0", "tcps<0", "inspect missing", "no command"]


@pytest.mark.parametrize("case", BAD_CASES)
def test_08_bad_input_one_line_error(case, make_shot, tiny_shot, tmp_path, capsys):
    argv, code, fragment = _bad(make_shot, tiny_shot, tmp_path)[case]
    assert main(argv) == code
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("cmlt: error: ")
    assert fragment in lines[0], lines[0]
    assert "Traceback" not in captured.err
    assert not glob.glob(str(tmp_path / "bad.*"))


def test_09_bad_input_as_subprocess(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "cmlt", "render", str(tmp_path / "nope.usda")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"cmlt: error: {tmp_path / 'nope.usda'}: no such file"


def test_10_inspect_and_version(tiny_shot, capsys):
    assert main(["inspect", tiny_shot]) == 0
    out = capsys.readouterr().out
    assert "/World/Cam" in out and "1 .. 3" in out
    assert "settings in force:" in out and "spp" in out
    assert main(["--version"]) == 0
    import cmlt._core
    assert capsys.readouterr().out.strip() == f"cmlt {__version__} (core {cmlt._core.isa})"


def test_11_ctrl_c_keeps_finished_frames(make_shot, tmp_path):
    """SIGINT mid-sequence: exit 130, finished frames intact, the partial
    frame not written, no temporaries, a resume hint; --resume finishes."""
    shot = make_shot("long.usda", {"endTimeCode = 3": "endTimeCode = 200"})
    out = tmp_path / "int"
    # --no-frame-hold: the shot is static, and held frames take no time, so on a loaded
    # machine all 200 could be written before the signal arrives
    cmd = [sys.executable, "-m", "cmlt", "render", shot, "--frames", "1:200",
           "--out", str(out / "i.####.exr"), "--spp", "128", "--res", "64x48", "--threads", "2",
           "--no-frame-hold"]
    # the child's SIGINT at its default disposition: a shell runs a background job with
    # SIGINT ignored, which the child would inherit (Python then installs no handler)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 240
    while time.time() < deadline and not (out.is_dir() and _exrs(out)):
        time.sleep(0.05)
    time.sleep(0.2)                        # into the next frame
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    done = _exrs(out)
    assert 1 <= len(done) < 200, err
    assert _temps(out) == []
    for p in done:                          # every image complete, with its sidecar
        img, _ = read_exr(p)
        assert img.shape == (48, 64, 3) and np.isfinite(img).all()
        assert os.path.isfile(p + ".json")
    assert "--resume" in err and "the partial frame was not written" in err
    assert "Traceback" not in err
    # the printed command resumes (only a few frames, to keep the test short)
    resume = [sys.executable, "-m", "cmlt", "render", shot, "--frames", f"1:{len(done) + 2}",
              "--out", str(out / "i.####.exr"), "--spp", "4", "--res", "64x48", "--resume", "-q"]
    proc = subprocess.run(resume, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    assert len(_exrs(out)) == len(done) + 2


def test_12_stage_settings_then_flags(make_shot, tmp_path):
    """flag > stage (CmltRenderSettingsAPI) > default, recorded in the sidecar."""
    shot = make_shot("st.usda", {"int2 resolution = (32, 24)":
                                 "int2 resolution = (16, 12)\n"
                                 "            uniform int cmlt:spp = 2\n"
                                 "            uniform int cmlt:seed = 9"})
    assert main(["render", shot, "--frames", "1", "--out", str(tmp_path / "a.exr"), "-q"]) == 0
    doc = json.load(open(tmp_path / "a.exr.json"))
    assert doc["settings"]["spp"] == 2 and doc["settings"]["seed"] == 9
    assert doc["settings_sources"]["spp"] == "stage:/Render/Settings"
    assert doc["settings"]["max_depth"] == 64 and doc["settings_sources"]["max_depth"] == "default"
    assert doc["resolution"] == [16, 12] and doc["stats"]["spp"] == 2
    assert main(["render", shot, "--frames", "1", "--out", str(tmp_path / "b.exr"), "-q",
                 "--spp", "3", "--res", "8x6"]) == 0
    doc = json.load(open(tmp_path / "b.exr.json"))
    assert doc["settings"]["spp"] == 3 and doc["settings_sources"]["spp"] == "flag --spp"
    assert doc["settings"]["seed"] == 9
    assert doc["resolution"] == [8, 6] and read_exr(str(tmp_path / "b.exr"))[0].shape == (6, 8, 3)


def test_13_core_settings_errors_name_their_source():
    from cmlt.settings import RenderSettings
    from cmlt.shot.core_settings import settings_message as _settings_message
    rs = RenderSettings(integrator="bdpt")
    msg, usage = _settings_message("RenderSettings.integrator: unknown integrator 'bdpt'", rs,
                                   {"integrator": "flag --integrator"})
    assert (msg, usage) == ("--integrator 'bdpt': unknown integrator 'bdpt'", True)
    msg, usage = _settings_message("RenderSettings.integrator: unknown integrator 'bdpt'", rs,
                                   {"integrator": "stage:/Render/Settings"})
    assert (msg, usage) == ("/Render/Settings: cmlt:integrator = 'bdpt': unknown integrator "
                            "'bdpt'", False)


def test_14_fractional_frames(tiny_shot, tmp_path):
    """Sub-frames render at their own time code and get three decimals."""
    assert main(["render", tiny_shot, "--frames", "1:2x0.5", "--out", str(tmp_path / "s.####.exr"),
                 *FAST, "-q"]) == 0
    names = [os.path.basename(p) for p in _exrs(tmp_path)]
    assert names == ["s.0001.500.exr", "s.0001.exr", "s.0002.exr"]
    doc = json.load(open(tmp_path / "s.0001.500.exr.json"))
    assert doc["time_code"] == 1.5
    images = [read_exr(str(tmp_path / n))[0] for n in ("s.0001.exr", "s.0001.500.exr",
                                                       "s.0002.exr")]
    assert not np.array_equal(images[0], images[1]) and not np.array_equal(images[1], images[2])


def test_15_output_colorspace(tiny_shot, tmp_path):
    """--output-colorspace converts the pixels from ACEScg with OCIO and
    declares the space in the header; the default writes ACEScg unchanged."""
    from cmlt.color import from_rendering_space
    a, b = str(tmp_path / "acescg.exr"), str(tmp_path / "rec709.exr")
    assert main(["render", tiny_shot, "--frames", "2", "--out", a, *FAST, "-q"]) == 0
    assert main(["render", tiny_shot, "--frames", "2", "--out", b, *FAST, "-q",
                 "--output-colorspace", "lin_rec709"]) == 0
    img_a, meta_a = read_exr(a)
    img_b, meta_b = read_exr(b)
    assert meta_a["colorInteropID"] == "lin_ap1_scene"
    assert meta_b["colorInteropID"] == "lin_rec709_scene"
    assert np.allclose(meta_b["chromaticities"], [0.64, 0.33, 0.3, 0.6, 0.15, 0.06, 0.3127, 0.329])
    assert not np.allclose(img_a, img_b)
    np.testing.assert_allclose(img_b, from_rendering_space(img_a.copy(), "lin_rec709"),
                               rtol=1e-5, atol=1e-7)
    assert json.load(open(b + ".json"))["settings"]["output_colorspace"] == "Linear Rec.709 (sRGB)"
