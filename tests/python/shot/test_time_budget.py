"""Time budgets (issue 4): `--time SECONDS` and the stage's cmlt:timeBudget render each
frame for that long instead of to a sample budget; with both budgets given at the same
precedence, whichever comes first."""
import json
import os

from pxr import Usd

import cmlt  # noqa: F401  (registers the CmltRenderSettingsAPI schema)
from cmlt.cli import main
import support

ROOT = str(support.ROOT)
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")


def _sidecar(path):
    return json.loads(open(path + ".json").read())


def test_01_time_flag_renders_for_the_time_not_the_stage_spp(tmp_path):
    out = str(tmp_path / "t.####.exr")
    for integ in ("pt", "cmlt"):
        assert main(["render", CORNELL, "--res", "24x24", "--time", "0.6", "--integrator", integ,
                     "--out", out, "--quiet", "--bootstrap-samples", "512", "--chains", "16"]) == 0
        doc = _sidecar(str(tmp_path / "t.0001.exr"))
        st = doc["stats"]
        # the stage asks 32 spp; a time budget replaces it: far more samples in 0.6 s
        # (or, for cmlt, path evaluations) than 32 per pixel, and about the time
        per_px = (st["spp"] if integ == "pt" else st["path_evaluations"] / (24 * 24))
        assert per_px > 32, (integ, per_px)
        assert 0.5 < st["time_s"] < 3.0, (integ, st["time_s"])
        assert doc["settings"]["time_budget"] == 0.6


def test_02_spp_and_time_flags_whichever_first(tmp_path):
    out = str(tmp_path / "t.####.exr")
    assert main(["render", CORNELL, "--res", "16x16", "--time", "30", "--spp", "4",
                 "--integrator", "pt", "--out", out, "--quiet"]) == 0
    st = _sidecar(str(tmp_path / "t.0001.exr"))["stats"]
    assert st["spp"] == 4 and st["time_s"] < 30


def test_03_stage_time_budget(tmp_path):
    path = str(tmp_path / "shot.usda")
    source = Usd.Stage.Open(CORNELL)          # keep the stage alive while its layer is used
    source.GetRootLayer().Export(path)
    stage = Usd.Stage.Open(path)
    prim = stage.GetPrimAtPath("/Render/Settings")
    prim.ApplyAPI("CmltRenderSettingsAPI")
    prim.GetAttribute("cmlt:timeBudget").Set(0.5)
    stage.Save()
    # the stage has both cmlt:spp = 32 and cmlt:timeBudget: whichever first (32 spp at
    # 8x8 takes far less than 0.5 s)
    assert main(["render", path, "--res", "8x8", "--out", str(tmp_path / "o.####.exr"), "--quiet"]) == 0
    st = _sidecar(str(tmp_path / "o.0001.exr"))["stats"]
    assert st["spp"] == 32
    # a negative budget is a clear error naming the flag
    assert main(["render", path, "--res", "8x8", "--time", "-1", "--out", str(tmp_path / "p.####.exr"),
                 "--quiet"]) == 2
