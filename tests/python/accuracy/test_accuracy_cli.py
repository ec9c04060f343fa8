"""`cmlt accuracy`: the CSV's columns and values, the plot, the markdown on stdout, the
reference cache, and one-line errors naming the flag or file."""
from __future__ import annotations

import csv
import math
import os

import numpy as np
import pytest

from cmlt.accuracy import CSV_COLUMNS, read_csv
from cmlt.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")
#: 16x16 pixels, two short budgets, two seeds, a small reference: a few seconds
BASE = ["--res", "16x16", "--seconds", "0.1,0.3", "--seeds", "2", "--integrators", "pt,bdpt",
        "--threads", "2", "--quiet"]
FAST = BASE + ["--reference-spp", "256"]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """One run of the command; (exit code, stdout, out dir, cache dir)."""
    base = tmp_path_factory.mktemp("accuracy")
    out, cache = base / "out", base / "cache"
    import io
    import contextlib
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["accuracy", CORNELL, *FAST, "--out", str(out), "--cache", str(cache)])
    return code, buf.getvalue(), out, cache


def test_01_csv_columns_and_rows(sweep):
    code, _, out, _ = sweep
    assert code == 0
    with open(out / "accuracy.csv", newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        body = list(reader)
    assert tuple(header) == CSV_COLUMNS
    assert header[:7] == ["renderer", "integrator", "seconds", "time_s", "samples", "relmse",
                          "relmse_se"]
    assert len(body) == 2 * 2                       # integrators x budgets
    rows = read_csv(str(out / "accuracy.csv"))
    assert {(r.integrator, r.seconds) for r in rows} == {("pt", 0.1), ("pt", 0.3),
                                                          ("bdpt", 0.1), ("bdpt", 0.3)}
    for r in rows:
        assert r.renderer == "cmlt" and r.renders == 2
        assert r.samples >= 1 and r.time_s > 0
        assert 0 < r.relmse < 1 and math.isfinite(r.relmse_se) and r.relmse_se >= 0
        assert 0 < r.rmse and 0.8 < r.mean_ratio < 1.25
    # every render is in runs.csv, and the rows are their means
    with open(out / "runs.csv", newline="") as f:
        runs = list(csv.DictReader(f))
    assert len(runs) == 8
    pt1 = [float(r["relmse"]) for r in runs if r["integrator"] == "pt" and float(r["seconds"]) == 0.1]
    row = next(r for r in rows if (r.integrator, r.seconds) == ("pt", 0.1))
    assert row.relmse == pytest.approx(np.mean(pt1), rel=1e-4)
    # runs.csv holds 6 significant digits: each value is off by up to 5e-6 of itself, and
    # the standard error of two renders is half their difference, so it inherits that
    # absolute error however close the two values lie (they have come within 5e-8 of 1e-4)
    assert row.relmse_se == pytest.approx(np.std(pt1, ddof=1) / math.sqrt(2), rel=1e-3,
                                          abs=1e-5 * max(pt1))


def test_02_plot_and_markdown(sweep):
    code, stdout, out, _ = sweep
    assert code == 0
    png = out / "accuracy.png"
    assert png.stat().st_size > 2000
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(png))
    assert inp is not None
    spec = inp.spec()
    inp.close()
    assert spec.width >= 300 and spec.height >= 200
    assert "| integrator | budget s |" in stdout
    assert "time to relMSE 0.01" in stdout and "time to relMSE 0.001" in stdout
    assert stdout.count("| pt |") == 3 and stdout.count("| bdpt |") == 3
    assert (out / "accuracy.json").exists()


def test_03_reference_is_cached(sweep, tmp_path):
    code, _, _, cache = sweep
    refs = sorted(os.listdir(cache))
    assert len(refs) == 1 and refs[0].startswith("cornell_f1_16x16_bdpt_256spp")
    mtime = os.path.getmtime(cache / refs[0])
    code = main(["accuracy", CORNELL, *FAST, "--seconds", "0.1", "--integrators", "pt",
                 "--seeds", "1", "--out", str(tmp_path / "again"), "--cache", str(cache)])
    assert code == 0
    assert sorted(os.listdir(cache)) == refs and os.path.getmtime(cache / refs[0]) == mtime


def test_04_given_reference(sweep, tmp_path):
    _, _, _, cache = sweep
    ref = cache / sorted(os.listdir(cache))[0]
    code = main(["accuracy", CORNELL, *BASE, "--seconds", "0.1", "--integrators", "pt",
                 "--seeds", "1", "--reference", str(ref), "--out", str(tmp_path)])
    assert code == 0
    assert len(read_csv(str(tmp_path / "accuracy.csv"))) == 1


@pytest.mark.parametrize("args, needle", [
    (["--seconds", "1,x"], "--seconds"),
    (["--seconds", "0"], "--seconds"),
    (["--integrators", "pt,warp"], "'warp'"),
    (["--integrators", "cmlt:tries=x"], "tries"),
    (["--integrators", "pt:spp=4"], "spp"),
    (["--peers", "blender"], "--peers"),
    (["--res", "16"], "--res"),
])
def test_05_bad_flags(args, needle, tmp_path, capsys):
    code = main(["accuracy", CORNELL, *FAST, *args, "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("cmlt: error:") and needle in err and "Traceback" not in err


def test_06_reference_of_the_wrong_size(sweep, tmp_path, capsys):
    _, _, _, cache = sweep
    ref = cache / sorted(os.listdir(cache))[0]
    code = main(["accuracy", CORNELL, *BASE, "--res", "8x8", "--reference", str(ref),
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and str(ref) in err and "16x16" in err and "8x8" in err


def test_07_missing_shot(tmp_path, capsys):
    code = main(["accuracy", str(tmp_path / "nope.usda"), *FAST])
    assert code == 2 and "nope.usda: no such file" in capsys.readouterr().err
