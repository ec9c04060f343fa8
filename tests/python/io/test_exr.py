"""EXR writer and stats sidecars: round trips, metadata, atomic writes."""
import json
import os

import numpy as np
import pytest

from cmlt.io import atomic, exr, sidecar
from cmlt.io.exr import NonFiniteImageError, read_exr, write_exr


def _image(rng, h=19, w=23):
    # a wide dynamic range, as a render has
    return (rng.random((h, w, 3)) * 10.0 ** rng.uniform(-3, 3, (h, w, 1))).astype(np.float32)


def _temps(directory):
    return [n for n in os.listdir(directory) if atomic.TEMP_MARKER in n]


@pytest.mark.parametrize("compression", ["zip", "piz", "none"])
def test_float_round_trip_is_exact(tmp_path, rng, compression):
    img = _image(rng)
    path = str(tmp_path / f"f.{compression}.exr")
    write_exr(path, img, compression=compression)
    back, meta = read_exr(path)
    assert back.shape == img.shape
    assert np.array_equal(back, img)
    assert meta["compression"] == compression
    assert meta["channelnames"] == ("R", "G", "B")
    assert meta["format"] == "float"


def test_half_round_trip_within_1e3(tmp_path, rng):
    img = _image(rng)
    path = str(tmp_path / "h.exr")
    write_exr(path, img, half=True)
    back, meta = read_exr(path)
    assert meta["format"] == "half"
    rel = np.abs(back - img) / np.maximum(np.abs(img), 1e-4)
    assert rel.max() < 1e-3
    assert not np.array_equal(back, img)      # it really is half


def test_dwaa_is_written_and_close(tmp_path, rng):
    img = np.full((32, 32, 3), 0.5, np.float32)
    path = str(tmp_path / "d.exr")
    write_exr(path, img, compression="dwaa")
    back, meta = read_exr(path)
    assert meta["compression"].startswith("dwaa")
    assert np.allclose(back, img, rtol=1e-2)


def test_metadata_round_trip(tmp_path, rng):
    path = str(tmp_path / "m.exr")
    md = {"frame": 12.5, "timeCode": 12.5, "shot": "/shots/cornell.usda", "camera": "/Cam",
          "integrator": "pt", "samples": 16, "seed": 7, "renderTime": 1.25, "version": "0.1.0",
          "settings": {"spp": 16}}
    write_exr(path, _image(rng), metadata=md, colorspace="ACEScg")
    _, meta = read_exr(path)
    for key, value in md.items():
        got = meta["cmlt:" + key]
        if key == "settings":
            assert json.loads(got) == value
        else:
            assert got == value, key
    # OIIO stores ACEScg by its interop name
    assert meta["oiio:ColorSpace"] in ("ACEScg", "lin_ap1_scene")
    assert meta.get("colorInteropID") == "lin_ap1_scene"


def test_atomic_write_leaves_no_temp(tmp_path, rng):
    path = str(tmp_path / "sub" / "a.0001.exr")           # directory is created
    write_exr(path, _image(rng))
    assert os.path.isfile(path)
    assert _temps(tmp_path / "sub") == []


def test_temp_name_is_hidden_sibling_with_extension():
    t = atomic.temp_name("/r/cornell.0001.exr")
    assert os.path.dirname(t) == "/r"
    assert os.path.basename(t).startswith(".cornell.0001.tmp-")
    assert t.endswith(f"{os.getpid()}.exr")


def test_failure_mid_write_keeps_old_frame(tmp_path, rng, monkeypatch):
    path = str(tmp_path / "a.exr")
    old = _image(rng)
    write_exr(path, old)
    before = open(path, "rb").read()

    import OpenImageIO as oiio
    real_create = oiio.ImageOutput.create
    seen = {}

    class Exploding:
        """Writes half the file, then fails like an interrupted render."""
        def __init__(self, inner):
            self.inner = inner
        def open(self, name, spec):
            seen["tmp"] = name
            return self.inner.open(name, spec)
        def write_image(self, pixels):
            self.inner.write_scanlines(0, pixels.shape[0] // 2, 0, pixels[: pixels.shape[0] // 2])
            assert os.path.exists(seen["tmp"])          # a partial file exists...
            raise KeyboardInterrupt
        def close(self):
            return self.inner.close()
        def geterror(self):
            return self.inner.geterror()

    monkeypatch.setattr(oiio.ImageOutput, "create", lambda name: Exploding(real_create(name)))
    with pytest.raises(KeyboardInterrupt):
        write_exr(path, _image(rng))
    monkeypatch.undo()
    assert open(path, "rb").read() == before           # ...but the old frame is untouched
    assert not os.path.exists(seen["tmp"])
    assert _temps(tmp_path) == []
    back, _ = read_exr(path)
    assert np.array_equal(back, old)


def test_non_finite_pixels_raise_and_write_nothing(tmp_path, rng):
    for bad in (np.nan, np.inf, -np.inf):
        img = _image(rng)
        img[3, 4, 1] = bad
        path = str(tmp_path / "bad.exr")
        with pytest.raises(NonFiniteImageError, match=r"x=4, y=3, channel 1"):
            write_exr(path, img)
        assert not os.path.exists(path)
        assert _temps(tmp_path) == []


def test_bad_shape_and_compression(tmp_path):
    with pytest.raises(ValueError, match="shape"):
        write_exr(str(tmp_path / "x.exr"), np.zeros((4, 4, 2), np.float32))
    with pytest.raises(ValueError, match="--compression"):
        write_exr(str(tmp_path / "x.exr"), np.zeros((4, 4, 3), np.float32), compression="lzma")


def test_sidecar_round_trip_and_strict_json(tmp_path):
    image = str(tmp_path / "c.0001.exr")
    rec = {"frame": 1.0, "stats": {"rays": np.int64(12), "time_s": np.float32(0.5),
                                   "odd": float("nan"), "per_thread": np.arange(3)},
           "temporal": {"b_ratio": np.float64("nan"), "b_used": 0.5,
                        "history": [float("inf"), -float("inf"), 1.0]},
           "warnings": ["w1"]}
    path = sidecar.write_sidecar(image, rec)
    assert path == image + ".json"
    text = open(path).read()
    assert "NaN" not in text                       # strict JSON
    doc = sidecar.read_sidecar(image)
    assert doc["format"] == "cmlt-frame-stats" and doc["version"] == 1
    assert doc["stats"]["rays"] == 12 and doc["stats"]["per_thread"] == [0, 1, 2]
    # a NaN (an estimate that does not exist for the frame) is JSON null, never "nan"
    assert doc["stats"]["odd"] is None
    assert doc["temporal"]["b_ratio"] is None and doc["temporal"]["b_used"] == 0.5
    assert doc["temporal"]["history"] == [None, None, 1.0]
    assert '"nan"' not in text and "Infinity" not in text and '"inf"' not in text
    assert _temps(tmp_path) == []


def test_atomic_text_failure_keeps_old(tmp_path, monkeypatch):
    path = str(tmp_path / "s.json")
    atomic.atomic_write_text(path, "old")

    def boom(fd):
        raise OSError("disk full")
    monkeypatch.setattr(os, "fsync", boom)
    with pytest.raises(OSError, match="disk full"):
        atomic.atomic_write_text(path, "new")
    assert open(path).read() == "old"
    assert _temps(tmp_path) == []


def test_raw_attributes_from_color_module(tmp_path, rng):
    """cmlt.color.header_attributes() output goes straight into the header."""
    from cmlt.color import header_attributes
    attrs = header_attributes("ACEScg")
    path = str(tmp_path / "c.exr")
    write_exr(path, _image(rng), colorspace=None, attributes=attrs)
    _, meta = read_exr(path)
    assert meta.get("colorInteropID") == "lin_ap1_scene"
    if "chromaticities" in attrs:
        assert np.allclose(meta["chromaticities"], attrs["chromaticities"], atol=1e-6)
