"""Previews are tagged display-referred (issue 6): ``oiio:ColorSpace`` is the
display's colour space — ACES configs give their shared views the colour space
``<USE_DISPLAY_NAME>``, i.e. the one named like the display — so the files
carry the display's encoding and OpenImageIO reads it back."""
from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import pytest

from cmlt.color import load_config
from cmlt.io.preview import (USE_DISPLAY_NAME, display_attributes, display_colorspace,
                             write_preview)


@pytest.fixture(scope="module")
def cfg():
    saved = os.environ.pop("OCIO", None)
    try:
        yield load_config()
    finally:
        if saved is not None:
            os.environ["OCIO"] = saved


def _png_chunks(path):
    data = open(path, "rb").read()
    i, out = 8, []
    while i < len(data):
        n = int.from_bytes(data[i:i + 4], "big")
        out.append(data[i + 4:i + 8].decode("latin-1"))
        i += 12 + n
    return out


def _spec(path):
    inp = oiio.ImageInput.open(path)
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    inp.close()
    return spec


def test01_display_colour_space_resolves_use_display_name(cfg):
    view = cfg.default_view("sRGB - Display")
    assert cfg.ocio.getDisplayViewColorSpaceName("sRGB - Display", view) == USE_DISPLAY_NAME
    cs = display_colorspace(cfg, "sRGB - Display", view)
    assert cs is not None and cs.getName() == "sRGB - Display"
    attrs = display_attributes(cfg, "sRGB - Display", view)
    assert attrs["oiio:ColorSpace"] == "srgb_rec709_display"
    p3 = display_attributes(cfg, "Display P3 - Display", cfg.default_view("Display P3 - Display"))
    assert p3["oiio:ColorSpace"] == "srgb_p3d65_display"


@pytest.mark.parametrize("ext", ["png", "jpg"])
def test02_srgb_preview_is_tagged_srgb(cfg, tmp_path, ext):
    path = str(tmp_path / f"p.{ext}")
    write_preview(np.full((4, 6, 3), 0.18, np.float32), path, config=cfg)
    spec = _spec(path)
    assert str(spec.getattribute("oiio:ColorSpace")).startswith("srgb_rec709")
    if ext == "png":
        assert "sRGB" in _png_chunks(path)            # the PNG sRGB rendering-intent chunk
    else:
        assert spec.getattribute("Exif:ColorSpace") == 1    # Exif: sRGB


def test03_p3_preview_is_read_back_as_p3(cfg, tmp_path):
    """Untagged, a P3 preview would read back as sRGB Rec.709; tagged, OIIO
    writes a cICP chunk (P3-D65 primaries, sRGB transfer) and reads P3 back."""
    path = str(tmp_path / "p3.png")
    write_preview(np.full((4, 6, 3), 0.18, np.float32), path, "Display P3 - Display",
                  config=cfg)
    spec = _spec(path)
    assert str(spec.getattribute("oiio:ColorSpace")).startswith("srgb_p3d65")
    assert tuple(spec.getattribute("CICP")) == (12, 13, 0, 1)
    assert "cICP" in _png_chunks(path)
