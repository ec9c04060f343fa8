"""Previews (PNG/JPEG through an OCIO display/view) and contact sheets."""
from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import PyOpenColorIO as ocio
import pytest

import cmlt  # noqa: F401
from cmlt.color import ColorError, load_config
from cmlt.io.contact_sheet import (contact_sheet, draw_text_bitmap, frame_number,
                                   frame_paths)
from cmlt.io.preview import write_preview


@pytest.fixture(scope="module")
def cfg():
    saved = os.environ.pop("OCIO", None)
    try:
        yield load_config()
    finally:
        if saved is not None:
            os.environ["OCIO"] = saved


def read_u8(path):
    buf = oiio.ImageBuf(path)
    assert not buf.has_error, buf.geterror()
    assert buf.spec().format == oiio.TypeDesc(oiio.UINT8)
    return np.asarray(buf.get_pixels(oiio.UINT8))


def expected_display(cfg, rgb, display="sRGB - Display", view=None):
    """The display value of an ACEScg colour, computed with OCIO directly."""
    view = view or cfg.ocio.getDefaultView(display)
    dvt = ocio.DisplayViewTransform(src="ACEScg", display=display, view=view)
    cpu = cfg.ocio.getProcessor(dvt).getDefaultCPUProcessor()
    v = np.array([rgb], dtype=np.float32)
    cpu.applyRGB(v)
    return v[0]


def write_exr(path, image, cfg):
    h, w, _ = image.shape
    spec = oiio.ImageSpec(w, h, 3, oiio.FLOAT)
    cfg.set_header_attributes(spec)
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec), out.geterror()
    out.write_image(np.ascontiguousarray(image, dtype=np.float32))
    out.close()


# -- 1. previews ---------------------------------------------------------------------

def test01_png_mid_grey(cfg, tmp_path):
    path = str(tmp_path / "grey.png")
    img = np.full((6, 10, 3), 0.18, dtype=np.float32)
    img[0, 0] = (100.0, 100.0, 100.0)      # very bright: clips to 255
    img[0, 1] = (0.0, 0.0, 0.0)
    assert write_preview(img, path, config=cfg) == path
    pix = read_u8(path)
    assert pix.shape == (6, 10, 3)
    assert pix.min() >= 0 and pix.max() <= 255
    want = int(np.rint(expected_display(cfg, (0.18, 0.18, 0.18))[0] * 255))
    assert abs(int(pix[3, 5, 0]) - want) <= 1
    assert 60 <= want <= 120              # ACES SDR view puts mid-grey well below sRGB's 118
    assert (pix[0, 0] == 255).all() and (pix[0, 1] == 0).all()
    assert not [f for f in os.listdir(tmp_path) if ".tmp-" in f]     # no temporary left


def test02_jpeg_and_other_views(cfg, tmp_path):
    views = list(cfg.ocio.getViews("sRGB - Display"))
    assert len(views) > 1
    other = [v for v in views if v != cfg.default_view()][0]
    img = np.full((8, 8, 4), 0.18, dtype=np.float32)          # RGBA: alpha dropped in JPEG
    path = write_preview(img, str(tmp_path / "grey.jpg"), "sRGB - Display", other, config=cfg)
    pix = read_u8(path)
    assert pix.shape == (8, 8, 3)
    want = np.rint(np.clip(expected_display(cfg, (0.18,) * 3, view=other), 0, 1) * 255)
    assert abs(int(pix[4, 4, 1]) - int(want[1])) <= 2       # JPEG is lossy


def test03_preview_errors(cfg, tmp_path):
    with pytest.raises(ValueError, match=r"\.png"):
        write_preview(np.zeros((2, 2, 3)), str(tmp_path / "x.tif"), config=cfg)
    with pytest.raises(ColorError, match="unknown display"):
        write_preview(np.zeros((2, 2, 3)), str(tmp_path / "x.png"), "CRT", config=cfg)
    assert not os.path.exists(tmp_path / "x.png")


# -- 2. contact sheets -------------------------------------------------------------

@pytest.fixture()
def frames(cfg, tmp_path):
    paths = []
    for f in (1001, 1002, 1003):
        img = np.zeros((32, 64, 3), dtype=np.float32)
        img[..., (f - 1001)] = 0.5                       # R, G, B frames
        p = str(tmp_path / f"shot.{f:04d}.exr")
        write_exr(p, img, cfg)
        paths.append(p)
    return paths


@pytest.mark.parametrize("font", [None, "builtin"])
def test04_contact_sheet_size_content_and_labels(cfg, tmp_path, frames, font):
    out = str(tmp_path / f"sheet_{font}.png")
    thumb, gap = 48, 4
    assert contact_sheet(str(tmp_path / "shot.####.exr"), out, thumb_width=thumb,
                         gap=gap, font=font, config=cfg) == out
    pix = read_u8(out).astype(int)
    # 3 frames -> 2 columns x 2 rows of 48x24 cells
    assert pix.shape == (2 * 24 + 3 * gap, 2 * thumb + 3 * gap, 3)
    # thumbnails carry their frame's colour (away from the label in the top-left)
    cells = [(gap, gap), (gap, 2 * gap + thumb), (2 * gap + 24, gap)]
    for channel, (y, x) in enumerate(cells):
        centre = pix[y + 18, x + 40]
        assert centre[channel] > 100 and centre[channel] == centre.max()
    # the empty fourth cell is background only
    empty = pix[2 * gap + 24:, 2 * gap + thumb:]
    assert empty.max() < 40
    # labels: bright text pixels in each cell's top-left corner
    for (y, x) in cells:
        corner = pix[y:y + 18, x:x + 40]
        assert (corner.min(axis=2) > 150).sum() >= 10, "no label text"
    # and no white in the same place without labels
    plain = read_u8(contact_sheet(frames, str(tmp_path / "plain.png"), thumb_width=thumb,
                                  gap=gap, label=False, config=cfg)).astype(int)
    assert (plain[gap:gap + 18, gap:gap + 40].min(axis=2) > 150).sum() == 0


def test05_contact_sheet_columns_and_patterns(cfg, tmp_path, frames):
    out = contact_sheet(frames, str(tmp_path / "row.png"), columns=3, thumb_width=20, gap=0,
                        config=cfg)
    assert read_u8(out).shape == (10, 60, 3)
    assert frame_paths(str(tmp_path / "shot.%04d.exr")) == frames
    assert frame_paths(str(tmp_path / "shot.$F4.exr")) == frames
    assert frame_paths(str(tmp_path / "shot.*.exr")) == frames
    assert [frame_number(p) for p in frames] == [1001, 1002, 1003]
    with pytest.raises(FileNotFoundError, match="nothing"):
        contact_sheet(str(tmp_path / "nothing.####.exr"), str(tmp_path / "n.png"), config=cfg)


def test06_bitmap_font_draws_digits():
    canvas = np.zeros((10, 40, 3), dtype=np.float32)
    w, h = draw_text_bitmap(canvas, 1, 1, "1008", scale=1)
    assert (w, h) == (4 * 5 + 3, 7)
    lit = canvas[..., 0] > 0
    assert lit[1:8, 1:24].any() and not lit[8:].any() and not lit[:, 24:].any()
    # "1" and "8" differ
    a = np.zeros((7, 5, 3), np.float32)
    b = np.zeros((7, 5, 3), np.float32)
    draw_text_bitmap(a, 0, 0, "1", scale=1)
    draw_text_bitmap(b, 0, 0, "8", scale=1)
    assert not np.array_equal(a, b)
