"""Stage reader, opening files: a missing file, an unreadable layer, bad time metadata,
an unresolved reference, a usdz package."""
from __future__ import annotations


import pytest
from pxr import Sdf, Usd, UsdGeom

from cmlt.usd import UsdLoadError, load_frame, open_stage, stage_info


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test19_missing_file(tmp_path):
    with pytest.raises(UsdLoadError, match=r"nope\.usda: no such file"):
        open_stage(str(tmp_path / "nope.usda"))


def test20_unreadable_layer(tmp_path):
    p = write(tmp_path, "broken.usda", '#usda 1.0\ndef Xform "a" (\n')
    with pytest.raises(UsdLoadError) as e:
        open_stage(p)
    assert "broken.usda" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("meta, message", [
    ("timeCodesPerSecond = 0", "timeCodesPerSecond is 0; it must be > 0"),
    ("timeCodesPerSecond = -24", "timeCodesPerSecond is -24; it must be > 0"),
    ("startTimeCode = 10\n endTimeCode = 1", "startTimeCode 10 is after endTimeCode 1"),
])
def test21_bad_time_metadata(tmp_path, meta, message):
    p = write(tmp_path, "t.usda", f"#usda 1.0\n(\n {meta}\n)\n")
    with pytest.raises(UsdLoadError, match=message) as e:
        open_stage(p)
    assert "t.usda" in str(e.value)


def test22_unresolved_reference_warns_naming_layer(tmp_path):
    p = write(tmp_path, "refs.usda", '#usda 1.0\ndef Xform "A" (\n references = @gone.usda@\n)\n'
              '{\n}\ndef Sphere "ok"\n{\n}\n')
    stage = open_stage(p)
    info = stage_info(stage)
    assert any("gone.usda" in w and "refs.usda" in w for w in info.warnings)
    scene = load_frame(stage, 0)
    assert any("gone.usda" in w and "refs.usda" in w for w in scene.warnings)
    assert [i.name for i in scene.instances] == ["/ok"]      # the rest loads


def test27_usdz_opens(tmp_path):
    from pxr import UsdUtils
    src = tmp_path / "a.usda"
    stage = Usd.Stage.CreateNew(str(src))
    UsdGeom.Cube.Define(stage, "/box")
    stage.GetRootLayer().Save()
    z = str(tmp_path / "a.usdz")
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(src)), z)
    scene = load_frame(open_stage(z), 0)
    assert [i.name for i in scene.instances] == ["/box"]
