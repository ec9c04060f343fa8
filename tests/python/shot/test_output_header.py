"""The EXR header says which b the image was normalised with (issue 6): the
temporal driver rescales MLT frames to ``b_used``, so ``cmlt:b`` is that value,
the core's own estimate is ``cmlt:bCore``, and the normalisation record is in
the header too; sidecars write a missing estimate (NaN) as JSON null."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import pytest

from cmlt.cli import main
from cmlt.io.exr import read_header
from cmlt.settings import RenderSettings
from cmlt.shot.output import header_metadata as _header_metadata

MLT = ["--integrator", "pssmlt", "--spp", "8", "--res", "16x12", "--threads", "2",
       "--chains", "32", "--bootstrap-samples", "256"]


def test01_header_b_is_the_b_used_and_the_record_is_there():
    fs = SimpleNamespace(time=2.0)
    stats = {"time_s": 1.0, "b": 0.25, "b_stderr": 0.01, "mutations": 100}
    rec = {"b_used": 0.2, "b_boot": 0.25, "b_ratio": math.nan, "b_combined": 0.25,
           "b_smoothed": 0.2, "change_detected": False}
    md = _header_metadata(2.0, fs, "/s.usda", "/cam", RenderSettings(integrator="pssmlt"),
                          stats, temporal=rec)
    assert md["b"] == 0.2                         # what the image was normalised with
    assert md["bCore"] == 0.25                    # the core's own estimate, kept
    assert md["bUsed"] == 0.2 and md["bFresh"] == 0.25 and md["bSmoothed"] == 0.2
    assert md["bCombined"] == 0.25 and md["changeDetected"] == 0
    assert "bRatio" not in md                     # NaN: no carried states, left out
    # pt / bdpt: no normalisation, nothing added
    md = _header_metadata(2.0, fs, "/s.usda", "/cam", RenderSettings(), {"time_s": 1.0},
                          temporal={"seed": 0})
    assert not any(k.startswith("b") for k in md)


def test02_pssmlt_sequence_headers_match_the_sidecar_record(tiny_shot, tmp_path):
    pattern = str(tmp_path / "m.####.exr")
    assert main(["render", tiny_shot, "--frames", "1:2", "--out", pattern, *MLT, "-q"]) == 0
    for f in (1, 2):
        path = str(tmp_path / f"m.{f:04d}.exr")
        md = read_header(path)["cmlt"]
        doc = json.load(open(path + ".json"))
        rec, stats = doc["temporal"], doc["stats"]
        assert md["b"] == pytest.approx(rec["b_used"], rel=1e-6)
        assert md["bCore"] == pytest.approx(stats["b"], rel=1e-6)
        assert md["bUsed"] == pytest.approx(rec["b_used"], rel=1e-6)
        assert md["bFresh"] == pytest.approx(rec["b_boot"], rel=1e-6)
        assert md["bSmoothed"] == pytest.approx(rec["b_smoothed"], rel=1e-6)
        assert md["bCombined"] == pytest.approx(rec["b_combined"], rel=1e-6)
        assert md["changeDetected"] == int(rec["change_detected"])
        if rec["b_ratio"] is None:
            assert "bRatio" not in md
        else:
            assert md["bRatio"] == pytest.approx(rec["b_ratio"], rel=1e-6)
    first = json.load(open(str(tmp_path / "m.0001.exr.json")))
    # frame 1 has no carried states: b_ratio does not exist -> JSON null, not "nan"
    assert first["temporal"]["b_ratio"] is None
    assert "b_ratio_stderr" not in first["temporal"] or \
        first["temporal"]["b_ratio_stderr"] is None
    text = open(str(tmp_path / "m.0001.exr.json")).read()
    assert '"nan"' not in text and "NaN" not in text
