"""One frame-pattern module for every command: the names `render --out` writes are
the names `flicker`/`compare` and `contact-sheet` find, with the same frame numbers,
fractional frames and decimals included."""
from __future__ import annotations

import numpy as np
import pytest

from cmlt.io import frame_pattern as fp
from cmlt.io.contact_sheet import frame_number, frame_paths
from cmlt.io.exr import write_exr
from cmlt.metrics.sequence import find_frames
from cmlt.shot.frames import OutputPatternError, expand_outputs

FRAMES = [1.0, 1.5, 2.0, 12.25]


@pytest.mark.parametrize("token", ["####", "####.###", "$F4", "%04d"])
def test01_what_out_writes_the_metrics_and_the_contact_sheet_find(tmp_path, token):
    pattern = str(tmp_path / f"shot.{token}.exr")
    paths = expand_outputs(pattern, FRAMES)
    img = np.full((2, 3, 3), 0.5, np.float32)
    for p in paths:
        write_exr(p, img)
    (tmp_path / "shot.7.exr").write_bytes(b"")         # not a name the pattern gives
    found = dict(fp.match_pattern(pattern))
    assert found == dict(zip(FRAMES, paths))
    assert [f for f, _ in find_frames(pattern)] == FRAMES
    assert frame_paths(pattern) == paths
    assert [frame_number(p) for p in paths] == FRAMES


def test02_frame_of_reads_the_decimals_the_writer_adds():
    assert fp.frame_of("r/shot.0001.500.exr") == 1.5        # not 500
    assert fp.frame_of("r/shot.1001.exr") == 1001
    assert fp.frame_of("r/shot.exr") is None
    assert fp.number_paths(["b.2.exr", "a.10.exr"]) == [(2.0, "b.2.exr"), (10.0, "a.10.exr")]
    assert fp.number_paths(["x.exr", "y.exr"]) == [(1.0, "x.exr"), (2.0, "y.exr")]


def test03_tokens_and_what_is_not_one():
    assert fp.expand_pattern("a.####.exr", 7) == "a.0007.exr"
    assert fp.expand_pattern("a.####.##.exr", 7.25) == "a.0007.25.exr"
    assert fp.expand_pattern("a.$F.exr", 7) == "a.7.exr"
    assert fp.expand_pattern("a.%d.exr", 1.5) == "a.1.500.exr"
    # '@' is a path character, not a frame token (no command writes it)
    assert not fp.has_frame_token("user@host/a.exr")
    assert fp.is_glob("a.*.exr") and not fp.is_glob("a.####.exr")
    with pytest.raises(ValueError, match="negative frame"):
        fp.format_frame(-1.0)
    with pytest.raises(OutputPatternError, match="--out: negative frame"):
        expand_outputs("a.####.exr", [-1.0])
