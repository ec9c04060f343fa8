"""A stage setting the renderer cannot honour is an error, never silently ignored."""
import os

from pxr import Usd

import cmlt  # noqa: F401  (registers the CmltRenderSettingsAPI schema)
from cmlt.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")


def test_time_budget_in_stage_is_a_clear_error(tmp_path, capsys):
    path = str(tmp_path / "shot.usda")
    source = Usd.Stage.Open(CORNELL)          # keep the stage alive while its layer is used
    source.GetRootLayer().Export(path)
    stage = Usd.Stage.Open(path)
    prim = stage.GetPrimAtPath("/Render/Settings")
    prim.ApplyAPI("CmltRenderSettingsAPI")
    prim.GetAttribute("cmlt:timeBudget").Set(5.0)
    stage.Save()

    rc = main(["render", path, "--res", "8x8", "--out", str(tmp_path / "o.####.exr")])
    err = capsys.readouterr().err
    assert rc == 2
    assert "cmlt:timeBudget" in err and "not implemented" in err
    assert not list(tmp_path.glob("o.*.exr"))
