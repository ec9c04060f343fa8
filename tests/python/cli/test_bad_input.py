"""Bad input and faults as a hostile user makes them: each gives one clear line naming
the flag, file or prim, and no finished frame is lost or replaced by a worse one.

Every test builds the bad input, runs the CLI (in process, so it stays fast) and checks
both the message and the files left behind."""
import glob
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from cmlt.cli import main
from cmlt.io.atomic import TEMP_MARKER, temp_name
from cmlt.io.exr import HALF_MAX, read_exr

FAST = ["--spp", "4", "--res", "32x24", "--threads", "2"]


def _errors(err):
    return [ln for ln in err.strip().splitlines() if ln.strip()]


def _one_error(err, *fragments):
    lines = _errors(err)
    assert len(lines) == 1, err
    assert lines[0].startswith("cmlt: error: "), lines[0]
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    assert "Traceback" not in err and "internal error" not in err
    return lines[0]


def _render(shot, out, *extra):
    return main(["render", shot, "--out", str(out), *FAST, "-q", *extra])


def _snapshot(directory):
    """{name: bytes} of every file in directory."""
    return {n: open(os.path.join(directory, n), "rb").read()
            for n in sorted(os.listdir(directory)) if os.path.isfile(os.path.join(directory, n))}


# -- --out ----------------------------------------------------------------------------

@pytest.mark.parametrize("name, fragments", [
    ("x.png", ["--out", "x.png", "scene-linear OpenEXR", "--preview"]),
    ("x.jpg", ["--out", "x.jpg", "8-bit, clipped"]),
    ("y.foo", ["--out", "y.foo", "unknown extension '.foo'", ".exr"]),
    ("noext", ["--out", "noext", "no file extension"]),
])
def test01_out_that_is_not_an_exr_is_refused_and_leaves_nothing(tiny_shot, tmp_path, capsys,
                                                              name, fragments):
    out = tmp_path / "o"
    out.mkdir()
    assert _render(tiny_shot, out / name, "--frames", "1") == 2
    _one_error(capsys.readouterr().err, *fragments)
    assert os.listdir(out) == []                # no stray sidecar, no temporary


@pytest.mark.parametrize("trailing_slash", [False, True])
def test02_out_into_an_existing_directory_is_refused(tiny_shot, tmp_path, capsys, trailing_slash):
    d = tmp_path / "d"
    d.mkdir()
    arg = str(d) + (os.sep if trailing_slash else "")
    assert _render(tiny_shot, arg, "--frames", "1") == 2
    _one_error(capsys.readouterr().err, f"--out {arg}", "directory", "shot.####.exr")
    assert os.listdir(d) == [] and not os.path.exists(str(d) + ".json")
    assert sorted(os.listdir(tmp_path)) == ["d", "tiny.usda"]


def test03_out_below_a_file_names_the_file(tiny_shot, tmp_path, capsys):
    (tmp_path / "afile").write_text("keep")
    assert _render(tiny_shot, tmp_path / "afile" / "x.####.exr", "--frames", "1") == 2
    _one_error(capsys.readouterr().err, "--out", "cannot write into", "afile", "not a directory")
    assert (tmp_path / "afile").read_text() == "keep"


# -- --half ---------------------------------------------------------------------------

def test04_half_clamps_beyond_its_range_and_warns(make_shot, tmp_path, capsys):
    bright = make_shot("bright.usda", {"float inputs:intensity = 8":
                                       "float inputs:intensity = 800000"})
    out = tmp_path / "h.####.exr"
    assert main(["render", bright, "--out", str(out), *FAST, "--frames", "1", "--half"]) == 0
    err = capsys.readouterr().err
    warn = [ln for ln in err.splitlines() if "--half" in ln]
    assert len(warn) == 1 and "clamped" in warn[0] and "65504" in warn[0], err
    img, meta = read_exr(str(tmp_path / "h.0001.exr"))
    assert meta["format"] == "half"
    assert np.isfinite(img).all()
    assert img.max() == HALF_MAX                # clamped to the largest half, not Inf
    doc = json.load(open(tmp_path / "h.0001.exr.json"))
    assert any("--half" in w for w in doc["warnings"])
    # a float render of the same frame keeps the values above half's range
    assert main(["render", bright, "--out", str(tmp_path / "f.####.exr"), *FAST,
                 "--frames", "1", "-q"]) == 0
    full, _ = read_exr(str(tmp_path / "f.0001.exr"))
    assert full.max() > HALF_MAX


def test05_half_within_range_does_not_warn(tiny_shot, tmp_path, capsys):
    assert main(["render", tiny_shot, "--out", str(tmp_path / "h.####.exr"), *FAST,
                 "--frames", "1", "--half"]) == 0
    assert "--half" not in capsys.readouterr().err


# -- --frames -------------------------------------------------------------------------

def test06_frames_far_outside_the_stage_are_refused_unless_forced(tiny_shot, tmp_path, capsys):
    out = tmp_path / "o"
    assert _render(tiny_shot, out / "f.####.exr", "--frames", "1:1000000") == 2
    _one_error(capsys.readouterr().err, "--frames '1:1000000'", "time range 1..3",
               "--force-frames")
    assert not out.exists()
    # a few frames beyond the range: rendered, with a warning naming the range
    assert main(["render", tiny_shot, "--out", str(out / "f.####.exr"), *FAST,
                 "--frames", "3:5"]) == 0
    err = capsys.readouterr().err
    warn = [ln for ln in err.splitlines() if "outside the stage's time range" in ln]
    assert len(warn) == 1 and "2 of 3 frame(s)" in warn[0] and "4, 5" in warn[0], err
    assert len(glob.glob(str(out / "f.*.exr"))) == 3


def test07_force_frames_lets_a_long_range_through(tiny_shot):
    from cmlt.shot.frames import check_stage_range, far_outside_limit, parse_frames

    frames = parse_frames("1:500", 1, 3)
    with pytest.raises(Exception, match="--force-frames"):
        check_stage_range(frames, 1, 3, spec="1:500")
    warning = check_stage_range(frames, 1, 3, spec="1:500", force=True)
    assert "497 of 500" in warning
    # a static stage rendered 24 times (a flicker measurement) is fine
    assert far_outside_limit(1) >= 24
    assert check_stage_range(parse_frames("1:24"), 1, 1, has_range=False) is None


# -- --chains -------------------------------------------------------------------------

@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
def test08_chains_beyond_the_budget_run_what_the_budget_feeds(tiny_shot, tmp_path, capsys,
                                                             integrator):
    import cmlt._core as core

    out = tmp_path / "c.####.exr"
    assert main(["render", tiny_shot, "--out", str(out), *FAST, "--frames", "1",
                 "--integrator", integrator, "--chains", "100000000", "--mlt-paths", "all"]) == 0
    err = capsys.readouterr().err
    warn = [ln for ln in err.splitlines() if "--chains 100000000" in ln]
    assert len(warn) == 1 and "feeds only" in warn[0], err
    doc = json.load(open(tmp_path / "c.0001.exr.json"))
    st = core.RenderSettings()
    st.integrator, st.spp, st.width, st.height, st.chains = integrator, 4, 32, 24, 100000000
    st.mlt_paths = "all"
    n = core.temporal_chain_count(st)
    assert 1 <= n < 100000000
    assert doc["stats"]["chains"] == n          # the count the driver asks is the render's


@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
def test09_chains_that_do_not_fit_in_memory_are_refused_before_allocating(
        tiny_shot, tmp_path, capsys, integrator):
    # a time budget lifts the sample budget, so every chain asked would run
    out = tmp_path / "o"
    assert main(["render", tiny_shot, "--out", str(out / "c.####.exr"), "--res", "32x24",
                 "--threads", "2", "-q", "--frames", "1", "--integrator", integrator,
                 "--time", "0.5", "--chains", "2000000000", "--mlt-paths", "all"]) == 2
    _one_error(capsys.readouterr().err, "--chains 2000000000", "GiB", "use at most")
    assert not out.exists()


def test10_chain_memory_rule():
    from cmlt.shot.preflight import CHAIN_BYTES, chain_memory_problem

    gib = 1024 ** 3
    assert chain_memory_problem(1000, "--chains 1000", available=gib) is None
    msg = chain_memory_problem(gib // CHAIN_BYTES, "--chains N", available=gib)
    assert msg.startswith("--chains N: ") and "use at most" in msg


# -- --resume -------------------------------------------------------------------------

def test11_resume_renders_truncated_empty_and_orphan_frames_again(tiny_shot, tmp_path, capsys):
    pattern = str(tmp_path / "r.####.exr")
    assert _render(tiny_shot, pattern, "--frames", "1:4") == 0
    f1, f2, f3, f4 = (str(tmp_path / f"r.000{k}.exr") for k in (1, 2, 3, 4))
    pixels = {p: read_exr(p)[0] for p in (f1, f2, f3, f4)}
    kept = open(f1, "rb").read(), os.stat(f1).st_mtime_ns
    with open(f2, "r+b") as fh:             # truncated
        fh.truncate(os.path.getsize(f2) // 2)
    open(f3, "wb").close()                  # empty
    os.remove(f4 + ".json")                 # image without its sidecar
    capsys.readouterr()
    assert main(["render", tiny_shot, "--out", pattern, *FAST, "--frames", "1:4",
                 "--resume"]) == 0
    err = capsys.readouterr().err
    assert "1 frame(s) already rendered, 3 to go" in err, err
    for path, why in ((f2, "corrupt"), (f3, "empty"), (f4, "sidecar")):
        line = [ln for ln in err.splitlines() if path in ln and "not a finished frame" in ln]
        assert len(line) == 1 and why in line[0], (path, err)
    assert (open(f1, "rb").read(), os.stat(f1).st_mtime_ns) == kept    # finished: untouched
    for p in (f2, f3, f4):                  # same seed: the frames come back bit for bit
        assert np.array_equal(read_exr(p)[0], pixels[p])
        assert json.load(open(p + ".json"))["image"] == os.path.basename(p)


def test12_resume_keeps_finished_frames_untouched(tiny_shot, tmp_path, capsys):
    pattern = str(tmp_path / "r.####.exr")
    assert _render(tiny_shot, pattern, "--frames", "1:2") == 0
    stamps = {p: os.stat(p).st_mtime_ns for p in glob.glob(str(tmp_path / "r.*"))}
    assert _render(tiny_shot, pattern, "--frames", "1:2", "--resume") == 0
    assert {p: os.stat(p).st_mtime_ns for p in stamps} == stamps
    # a finished frame of another size is not this render's: rendered again
    assert main(["render", tiny_shot, "--out", pattern, "--spp", "4", "--res", "16x12",
                 "--threads", "2", "--frames", "1", "--resume"]) == 0
    err = capsys.readouterr().err
    assert "it is 32x24, this render is 16x12" in err
    assert read_exr(str(tmp_path / "r.0001.exr"))[0].shape == (12, 16, 3)


# -- temporaries of a killed render ---------------------------------------------------

def _dead_pid():
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test13_temporaries_of_a_killed_render_are_removed_on_the_next_run(tiny_shot, tmp_path,
                                                                       capsys):
    from cmlt.io import atomic

    out = tmp_path / "o"
    out.mkdir()
    host = atomic._host()
    dead = _dead_pid()
    stale = [out / f".r.0001{TEMP_MARKER}{host}-{dead}.png",        # a 0-byte preview
             out / f".r.0001{TEMP_MARKER}{host}-{dead}.exr"]
    for p in stale:
        p.write_bytes(b"")
    alive = out / f".r.0002{TEMP_MARKER}{host}-{os.getppid()}.png"   # its writer runs
    other_host = out / f".r.0003{TEMP_MARKER}otherhost-{dead}.png"   # another machine's
    mine = out / ".notes.txt"
    for p in (alive, other_host, mine):
        p.write_bytes(b"x")
    assert main(["render", tiny_shot, "--out", str(out / "r.####.exr"), *FAST, "--frames", "1",
                 "--preview"]) == 0
    err = capsys.readouterr().err
    assert "removed 2 temporary file(s) left by a render that was killed" in err, err
    assert not any(p.exists() for p in stale)
    assert alive.exists() and other_host.exists() and mine.exists()
    assert {n for n in os.listdir(out) if TEMP_MARKER in n} == {alive.name, other_host.name}


def test14_temp_names_carry_host_and_pid():
    from cmlt.io.atomic import parse_temp_name

    t = os.path.basename(temp_name("/r/shot.0001.exr"))
    assert t.startswith(".shot.0001" + TEMP_MARKER) and t.endswith(".exr")
    host, pid = parse_temp_name(t)
    assert pid == os.getpid() and host and host in t
    assert parse_temp_name(".shot.0001.tmp-123.exr") == (None, 123)   # older, host-less
    assert parse_temp_name("shot.0001.exr") is None


# -- a frame that fails to write ------------------------------------------------------

def test15_a_failed_write_leaves_the_previous_frame_as_it_was(tiny_shot, tmp_path, capsys,
                                                             monkeypatch):
    import cmlt.shot.frame_job as frame_job

    pattern = str(tmp_path / "r.####.exr")
    assert _render(tiny_shot, pattern, "--frames", "1", "--preview", "--seed", "1") == 0
    good = _snapshot(tmp_path)

    real = frame_job.write_exr

    def half_written(path, *args, **kwargs):
        with open(path, "wb") as fh:              # a torn image, then the disk is full
            fh.write(b"\x76\x2f\x31\x01")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(frame_job, "write_exr", half_written)
    code = _render(tiny_shot, pattern, "--frames", "1", "--preview", "--seed", "2")
    assert code == 1
    _one_error(capsys.readouterr().err, "r.0001.exr", "No space left on device")
    assert _snapshot(tmp_path) == good      # image, sidecar and preview all the old ones
    assert not [n for n in os.listdir(tmp_path) if TEMP_MARKER in n]
    monkeypatch.setattr(frame_job, "write_exr", real)


# -- reading truncated images ---------------------------------------------------------

@pytest.fixture
def broken_sequence(tiny_shot, tmp_path):
    """Frames 1..3 of a sequence, frame 2 cut at ``cut`` bytes."""
    pattern = str(tmp_path / "s.####.exr")
    assert _render(tiny_shot, pattern, "--frames", "1:3") == 0

    def cut(nbytes):
        path = str(tmp_path / "s.0002.exr")
        data = open(str(tmp_path / "s.0001.exr"), "rb").read()
        open(path, "wb").write(data[:nbytes] if nbytes >= 0 else data[:len(data) + nbytes])
        return pattern, path
    return cut


def _read_commands(pattern, path, tmp_path):
    first = pattern.replace("####", "0001")
    return [["inspect", "--image", path], ["compare", first, path], ["flicker", pattern],
            ["contact-sheet", pattern, "--out", str(tmp_path / "sheet.png")]]


@pytest.mark.parametrize("nbytes, why", [(0, "the file is empty"),
                                         (10, "truncated or corrupt OpenEXR file"),
                                         (1200, "cannot read"),
                                         (-600, "")])
def test16_truncated_exr_is_one_line_naming_the_file(broken_sequence, tmp_path, capfd,
                                                     nbytes, why):
    pattern, path = broken_sequence(nbytes)
    capfd.readouterr()
    for argv in _read_commands(pattern, path, tmp_path):
        if argv[0] == "inspect" and nbytes < 0:
            continue                        # the header is whole: inspect prints it
        code = main(argv)
        err = capfd.readouterr().err        # file-descriptor level: OpenEXR's own lines too
        assert code in (1, 2), (argv, err)
        line = _one_error(err, path, why)
        assert "EXR Error" not in line and "EXR_ERR" not in line, line
    assert not os.path.exists(tmp_path / "sheet.png")


# -- textures and lights --------------------------------------------------------------

MISSING_TEXTURE = {
    "rel material:binding = </World/Looks/Red>": "rel material:binding = </World/Looks/Tex>",
    'def Scope "Looks"\n    {': '''def Scope "Looks"
    {
        def Material "Tex"
        {
            token outputs:surface.connect = </World/Looks/Tex/PBR.outputs:surface>
            def Shader "PBR"
            {
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor.connect = </World/Looks/Tex/Img.outputs:rgb>
                token outputs:surface
            }
            def Shader "Img"
            {
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @missing_tex.png@
                float3 outputs:rgb
            }
        }''',
}


def test17_texture_warnings_are_cmlt_warnings(make_shot, tmp_path, capfd):
    shot = make_shot("tex.usda", MISSING_TEXTURE)
    assert main(["render", shot, "--out", str(tmp_path / "t.####.exr"), *FAST,
                 "--frames", "1"]) == 0
    err = capfd.readouterr().err
    assert "UserWarning" not in err and "warnings.warn" not in err, err
    lines = [ln for ln in err.splitlines() if "missing_tex.png" in ln]
    # one cause, one warning: the reader's (the bridge does not repeat it)
    assert len(lines) == 1 and lines[0].startswith("cmlt: warning: /World/Looks/Tex: "), err
    doc = json.load(open(tmp_path / "t.0001.exr.json"))
    assert any("cannot be resolved" in w and "/World/Looks/Tex" in w for w in doc["warnings"])
    # --quiet: nothing at all
    assert main(["render", shot, "--out", str(tmp_path / "q.####.exr"), *FAST,
                 "--frames", "1", "-q"]) == 0
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("light", ["RectLight", "SphereLight", "DistantLight", "DomeLight"])
def test18_negative_light_intensity_names_the_light(make_shot, tmp_path, capsys, light):
    shot = make_shot(f"neg_{light}.usda", {'def RectLight "Light"': f'def {light} "Light"',
                                           "float inputs:intensity = 8":
                                           "float inputs:intensity = -8"})
    assert main(["render", shot, "--out", str(tmp_path / "n.####.exr"), *FAST,
                 "--frames", "1"]) == 0
    err = capsys.readouterr().err
    warn = [ln for ln in err.splitlines() if "negative components" in ln]
    assert len(warn) == 1 and warn[0].startswith("cmlt: warning: /World/Light: "), err
    assert "add_light" not in err
    assert np.isfinite(read_exr(str(tmp_path / "n.0001.exr"))[0]).all()


# -- a frame that fails: the frames before it stay -----------------------------------

def test19_a_bad_later_frame_keeps_the_finished_ones(make_shot, tmp_path, capsys):
    # the box's points lose a vertex at frame 3: its faces then refer to a missing point
    shot = make_shot("breaks.usda", {
        "point3f[] points = [(-0.5, 0, -0.5)": "point3f[] points.timeSamples = {1: [(-0.5, 0, -0.5)",
        "(0.5, 1, -0.5), (0.5, 1, 0.5)]":
        "(0.5, 1, -0.5), (0.5, 1, 0.5)], 3: [(-0.5, 0, -0.5), (-0.5, 0, 0.5), (-0.5, 1, -0.5), "
        "(-0.5, 1, 0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (0.5, 1, -0.5)]}"})
    pattern = str(tmp_path / "b.####.exr")
    code = _render(shot, pattern, "--frames", "1:3")
    err = capsys.readouterr().err
    assert code == 1
    _one_error(err, "/World/Box")
    for k in (1, 2):
        p = str(tmp_path / f"b.000{k}.exr")
        assert np.isfinite(read_exr(p)[0]).all() and os.path.isfile(p + ".json")
    assert not glob.glob(str(tmp_path / "b.0003*"))
    assert not [n for n in os.listdir(tmp_path) if TEMP_MARKER in n]


def test20_non_finite_output_is_never_written(tiny_shot, tmp_path, capsys, monkeypatch):
    import cmlt.shot.frame_job as frame_job

    real = frame_job.to_output

    def overflowing(image, colorspace):         # an overflow in the output colour space
        out = np.array(real(image, colorspace), dtype=np.float32, copy=True)
        out[3, 5, 1] = np.inf
        return out

    pattern = str(tmp_path / "i.####.exr")
    assert _render(tiny_shot, pattern, "--frames", "1", "--seed", "1") == 0
    good = _snapshot(tmp_path)
    monkeypatch.setattr(frame_job, "to_output", overflowing)
    assert _render(tiny_shot, pattern, "--frames", "1", "--seed", "2") == 1
    _one_error(capsys.readouterr().err, "i.0001.exr", "non-finite", "x=5, y=3")
    assert _snapshot(tmp_path) == good
