"""`cmlt contact-sheet PATTERN --out SHEET [--columns N]` end to end."""
from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt.cli import main
from cmlt.color import load_config, set_config

FAST = ["--spp", "2", "--res", "32x24", "--threads", "2"]


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


@pytest.fixture
def frames(tiny_shot, tmp_path):
    pattern = str(tmp_path / "r" / "t.####.exr")
    assert main(["render", tiny_shot, "--frames", "1:3", "--out", pattern, *FAST, "-q"]) == 0
    return pattern


def _size(path):
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    inp.close()
    return spec.width, spec.height, spec.nchannels


@pytest.mark.parametrize("columns,grid", [(None, (2, 2)), ("3", (3, 1)), ("1", (1, 3))])
def test01_sheet_size_follows_columns(frames, tmp_path, capsys, columns, grid):
    out = tmp_path / "sheet.png"
    args = ["contact-sheet", frames, "--out", str(out), "--thumb-width", "64"]
    if columns:
        args += ["--columns", columns]
    assert main(args) == 0, capsys.readouterr().err
    cols, rows = grid
    w, h, c = _size(out)
    cell_h = 48       # 32x24 frames at 64 px wide
    assert (w, h, c) == (cols * 64 + (cols + 1) * 4, rows * cell_h + (rows + 1) * 4, 3)
    assert "contact sheet ->" in capsys.readouterr().err


def test02_sheet_pixels_are_the_display_referred_frames(frames, tmp_path):
    out = tmp_path / "sheet.png"
    assert main(["contact-sheet", frames, "--out", str(out), "--columns", "3",
                 "--thumb-width", "32"]) == 0
    buf = oiio.ImageBuf(str(out))
    sheet = np.asarray(buf.get_pixels(oiio.UINT8)).reshape(buf.spec().height,
                                                           buf.spec().width, 3)
    assert sheet.max() > 100                      # the lit scene is visible
    gap = sheet[:, 32 + 4:32 + 8]                 # the gutter between the first two cells
    assert (np.abs(gap.astype(int) - gap[0, 0].astype(int)) <= 1).all()


def test03_jpeg_and_a_list_of_files(frames, tmp_path):
    import glob
    files = sorted(glob.glob(str(tmp_path / "r" / "*.exr")))
    out = tmp_path / "sheet.jpg"
    assert main(["contact-sheet", *files[:2], "--out", str(out), "--thumb-width", "32"]) == 0
    w, h, _ = _size(out)
    assert (w, h) == (2 * 32 + 3 * 4, 24 + 2 * 4)


@pytest.mark.parametrize("args,needle", [
    (["contact-sheet", "missing.####.exr", "--out", "s.png"], "no files match"),
    (["contact-sheet", "{frames}", "--out", "s.tif"], "--out s.tif"),
    (["contact-sheet", "{frames}", "--out", "s.png", "--display", "Nope"], "--display"),
    (["contact-sheet", "{frames}", "--out", "s.png", "--view", "Nope"], "--view"),
    (["contact-sheet", "{frames}"], "--out"),
])
def test04_errors_are_one_line(frames, tmp_path, capsys, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    args = [a.replace("{frames}", frames) for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cmlt: error:") and needle in err[0], err
