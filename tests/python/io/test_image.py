"""Reading images (cmlt.io.image): one rule picks an image's colour for the
metrics and the contact sheet."""
from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt.io.image import ImageReadError, read_image, read_rgb, rgb_channels
from cmlt.metrics import MetricsError, load_image


def _write(path, pixels, names):
    h, w, n = pixels.shape
    spec = oiio.ImageSpec(w, h, n, oiio.FLOAT)
    spec.channelnames = tuple(names)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    assert out.write_image(np.ascontiguousarray(pixels, np.float32))
    out.close()
    return str(path)


def test01_the_colour_rule():
    assert rgb_channels(["A", "B", "G", "R"]) == [3, 2, 1]
    assert rgb_channels(["Y", "A"]) == [0, 0, 0]
    assert rgb_channels(["Z"]) == [0, 0, 0]
    assert rgb_channels(["channel0", "channel1", "channel2", "channel3"]) == [0, 1, 2]
    with pytest.raises(ValueError, match=r"no R, G, B channels \(channels: N.X, N.Y\)"):
        rgb_channels(["N.X", "N.Y"])


def test02_read_rgb_and_the_metrics_agree(tmp_path):
    rgba = np.random.default_rng(3).random((4, 5, 4)).astype(np.float32)
    path = _write(tmp_path / "a.exr", rgba, ["R", "G", "B", "A"])
    pixels, spec = read_image(path)
    assert pixels.shape == (4, 5, 4) and list(spec.channelnames) == ["R", "G", "B", "A"]
    rgb, _ = read_rgb(path)
    np.testing.assert_array_equal(rgb, rgba[..., :3])
    np.testing.assert_array_equal(load_image(path), rgba[..., :3].astype(np.float64))
    grey = _write(tmp_path / "y.exr", rgba[..., :2], ["Y", "A"])
    np.testing.assert_array_equal(read_rgb(grey)[0], np.repeat(rgba[..., :1], 3, axis=2))


def test03_errors_name_the_file(tmp_path):
    with pytest.raises(ImageReadError, match="nope.exr: no such file"):
        read_rgb(str(tmp_path / "nope.exr"))
    normals = _write(tmp_path / "n.exr", np.zeros((2, 2, 2), np.float32), ["N.X", "N.Y"])
    with pytest.raises(MetricsError, match=r"n.exr: no R, G, B channels"):
        load_image(normals)
    bad = np.zeros((2, 2, 3), np.float32)
    bad[1, 0, 2] = np.inf
    with pytest.raises(MetricsError, match=r"1 non-finite pixel values \(first at x=0, y=1, "
                                           r"channel B\)"):
        load_image(_write(tmp_path / "inf.exr", bad, ["R", "G", "B"]))
