"""`cmlt render` records the frame's relMSE estimate (no reference needed): in the
sidecar, the EXR header (cmlt:relMSEEstimate, ...), the per-frame line, and per pixel
as the `--aov error` channel (relMSE). pssmlt/cmlt from their chain groups (none with --error-groups 0)."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from cmlt.cli import main
from cmlt.io.exr import read_exr, read_header
from cmlt.shot.core_settings import PLAIN_ERROR_GROUPS

FAST = ["--spp", "8", "--threads", "2", "--res", "24x16", "--mlt-paths", "all"]  # the chains on every path (auto: none on a diffuse scene)


@pytest.mark.parametrize("integrator", ["pt", "bdpt"])
def test_estimate_in_sidecar_header_and_aov(tiny_shot, tmp_path, capsys, integrator):
    out = tmp_path / "f.####.exr"
    assert main(["render", tiny_shot, *FAST, "--integrator", integrator, "--aov", "error",
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    path = str(tmp_path / "f.0001.exr")
    rec = json.load(open(path + ".json"))["stats"]["error_estimate"]
    assert rec["available"] and rec["method"] == "variance" and rec["groups"] == 8
    assert rec["relmse"] > 0 and 0 < rec["stderr"] < rec["relmse"]
    meta = read_header(path)["cmlt"]
    assert meta["relMSEEstimate"] == pytest.approx(rec["relmse"], rel=1e-6)
    assert meta["relMSEEstimateStderr"] == pytest.approx(rec["stderr"], rel=1e-6)
    assert meta["relMSEEstimateMethod"] == f"variance/{rec['denominator']}"
    pixels, header = read_exr(path)
    names = list(header["channelnames"])
    assert "relMSE" in names
    per_pixel = pixels[..., names.index("relMSE")].astype(np.float64)
    assert (per_pixel >= 0).all() and np.isfinite(per_pixel).all()
    assert per_pixel.mean() == pytest.approx(rec["relmse"], rel=1e-4)   # the image's = mean
    assert "relMSE ~" in err


def test_mlt_estimate_from_chain_groups(tiny_shot, tmp_path, capsys):
    out = tmp_path / "m.####.exr"
    assert main(["render", tiny_shot, *FAST, "--integrator", "pssmlt", "--aov", "error",
                 "--out", str(out)]) == 0
    path = str(tmp_path / "m.0001.exr")
    rec = json.load(open(path + ".json"))["stats"]["error_estimate"]
    # without a target error or group images, the default error_groups is the compact one
    assert rec["available"] and rec["method"] == "groups" and rec["groups"] == PLAIN_ERROR_GROUPS
    assert json.load(open(path + ".json"))["settings"]["error_groups"] == PLAIN_ERROR_GROUPS
    assert rec["relmse"] > 0 and rec["stderr"] > 0
    assert read_header(path)["cmlt"]["relMSEEstimate"] == pytest.approx(rec["relmse"], rel=1e-6)
    capsys.readouterr()
    # without groups: no estimate, and --aov error says what it needs
    assert main(["render", tiny_shot, *FAST, "--integrator", "cmlt", "--error-groups", "0",
                 "--out", str(tmp_path / "k.####.exr")]) == 0
    rec = json.load(open(str(tmp_path / "k.0001.exr") + ".json"))["stats"]["error_estimate"]
    assert rec["available"] is False and "error_groups" in rec["reason"]
    assert "relMSEEstimate" not in read_header(str(tmp_path / "k.0001.exr"))["cmlt"]
    capsys.readouterr()
    code = main(["render", tiny_shot, *FAST, "--integrator", "cmlt", "--error-groups", "0",
                 "--aov", "error", "--out", str(tmp_path / "n.####.exr")])
    err = capsys.readouterr().err
    assert code == 2 and "--aov error" in err and "--error-groups" in err
    assert not os.path.exists(tmp_path / "n.0001.exr")


def test_error_groups_given_or_needed_are_kept(tiny_shot, tmp_path, capsys):
    """--error-groups given, a target error or --group-images keep their groups (the
    compact default applies only to a frame that needs none of them), and the image is
    the same with either count (the film's layers add up exactly)."""
    from cmlt.io.exr import read_exr as read
    runs = {"plain": [], "given": ["--error-groups", "8"], "images": ["--group-images"]}
    groups, images = {}, {}
    for name, extra in runs.items():
        out = tmp_path / f"{name}.####.exr"
        assert main(["render", tiny_shot, *FAST, "--integrator", "cmlt", "--chains", "32",
                     "--bootstrap-samples", "1000", "--out", str(out), *extra]) == 0
        path = str(tmp_path / f"{name}.0001.exr")
        groups[name] = json.load(open(path + ".json"))["stats"]["error_estimate"]["groups"]
        images[name] = read(path)[0][..., :3]
    capsys.readouterr()
    assert groups["plain"] == PLAIN_ERROR_GROUPS
    assert groups["given"] == 8 and groups["images"] == 8
    assert np.array_equal(images["plain"], images["given"])
    assert np.array_equal(images["plain"], images["images"])
