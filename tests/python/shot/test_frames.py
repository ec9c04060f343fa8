"""Frame specs (--frames) and output patterns (--out)."""
import pytest

from cmlt.shot.frames import (FrameSpecError, OutputPatternError, default_frames,
                              expand_outputs, expand_pattern, format_frame, parse_frames)
from cmlt.shot.errors import UsageError


# -- frame specs -----------------------------------------------------------
@pytest.mark.parametrize("spec, expected", [
    ("7", [7.0]),
    ("1.5", [1.5]),
    ("1:4", [1.0, 2.0, 3.0, 4.0]),
    ("1:24x2", [float(f) for f in range(1, 25, 2)]),
    ("1:2x0.25", [1.0, 1.25, 1.5, 1.75, 2.0]),
    ("1:2x0.1", [1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0]),
    ("1,5,9", [1.0, 5.0, 9.0]),
    (" 1, 3:5 ,9 ", [1.0, 3.0, 4.0, 5.0, 9.0]),
    ("5,1", [5.0, 1.0]),                 # order kept
    ("1:3,2", [1.0, 2.0, 3.0]),          # duplicates rendered once
    ("3:3", [3.0]),
    ("0", [0.0]),
    ("1:10x4", [1.0, 5.0, 9.0]),         # the end need not be on the stride
    ("1-4", [1.0, 2.0, 3.0, 4.0]),       # husk's spelling of a range
    ("1-5x2", [1.0, 3.0, 5.0]),
    ("2,4-6", [2.0, 4.0, 5.0, 6.0]),
])
def test_parse_frames(spec, expected):
    assert parse_frames(spec) == expected


def test_all_uses_stage_range():
    assert parse_frames("all", 1, 24, True) == [float(f) for f in range(1, 25)]
    assert parse_frames("ALL", 101, 103, True) == [101.0, 102.0, 103.0]


def test_all_without_authored_range_is_start_only():
    assert parse_frames("all", 0, 0, False) == [0.0]


def test_default_frame_is_stage_start():
    assert default_frames(1001) == [1001.0]


@pytest.mark.parametrize("spec, fragment", [
    ("", "empty"),
    ("abc", "'abc' is not a frame number"),
    ("-3", "negative frame"),
    ("1:-3", "negative frame"),
    ("5:1", "ends (1) before it starts (5)"),
    ("1:10x0", "stride must be positive"),
    ("1:10x-2", "stride must be positive"),
    ("1:10xq", "stride 'q' is not a number"),
    ("7x2", "needs a range"),
    ("1:2:3", "START:END"),
    ("1,,3", "empty item"),
    ("nan", "not a finite frame number"),
    ("inf", "not a finite frame number"),
    ("0:1e9", "limit"),
])
def test_bad_frame_specs(spec, fragment):
    with pytest.raises(FrameSpecError) as info:
        parse_frames(spec)
    msg = str(info.value)
    assert msg.startswith("--frames"), msg
    assert fragment in msg
    assert "\n" not in msg
    assert isinstance(info.value, UsageError)


# -- output patterns ----------------------------------------------------------
@pytest.mark.parametrize("pattern, frame, expected", [
    ("a.####.exr", 7, "a.0007.exr"),
    ("a.#.exr", 7, "a.7.exr"),
    ("a.##.exr", 123, "a.123.exr"),          # padding is a minimum
    ("a.$F4.exr", 7, "a.0007.exr"),
    ("a.$F.exr", 7, "a.7.exr"),
    ("a.%04d.exr", 7, "a.0007.exr"),
    ("a.%d.exr", 7, "a.7.exr"),
    ("a.####.exr", 1.5, "a.0001.500.exr"),   # fractional: three decimals
    ("a.$F4.exr", 1.25, "a.0001.250.exr"),
    ("a.####.##.exr", 1.5, "a.0001.50.exr"), # explicit decimals
    ("a.####.##.exr", 2, "a.0002.00.exr"),
    ("d_####/a.####.exr", 3, "d_0003/a.0003.exr"),
    ("plain.exr", 3, "plain.exr"),
])
def test_expand_pattern(pattern, frame, expected):
    assert expand_pattern(pattern, frame) == expected


def test_format_frame():
    assert format_frame(1.0, 4) == "0001"
    assert format_frame(1.0 + 1e-9, 4) == "0001"         # float noise is not a sub-frame
    assert format_frame(12.3456, 4) == "0012.346"
    assert format_frame(12.3456, 0, 1) == "12.3"


def test_expand_outputs_many_frames():
    assert expand_outputs("r/c.####.exr", [1, 2, 10]) == ["r/c.0001.exr", "r/c.0002.exr",
                                                          "r/c.0010.exr"]


def test_pattern_without_token_is_fine_for_one_frame():
    assert expand_outputs("still.exr", [5]) == ["still.exr"]


def test_pattern_without_token_for_many_frames_names_out():
    with pytest.raises(OutputPatternError) as info:
        expand_outputs("still.exr", [1, 2])
    assert str(info.value).startswith("--out 'still.exr'")
    assert "frame token" in str(info.value)


def test_colliding_names_are_an_error():
    with pytest.raises(OutputPatternError, match="both map to"):
        expand_outputs("c.####.exr", [1.0001, 1.0002])
    # with enough decimals they are distinct
    assert expand_outputs("c.####.####.exr", [1.0001, 1.0002]) == ["c.0001.0001.exr",
                                                                    "c.0001.0002.exr"]
