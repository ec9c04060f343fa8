"""Contact sheets: a grid of display-referred thumbnails of EXR frames, each
labelled with its frame number.

Each frame is read with OpenImageIO, brought into ACEScg from the colour space
its header declares, shrunk in linear light to the thumbnail width, sent
through the OCIO display/view, and tiled. Labels are drawn with OpenImageIO's
``render_text`` when it finds a font (it ships Droid fonts); otherwise, or with
``font="builtin"``, with a tiny 5x7 bitmap font drawn in numpy.
"""
from __future__ import annotations

import glob
import math
import os
from typing import Iterable, List, Optional, Tuple, Union

import numpy as np
import OpenImageIO as oiio

from ..color import ColorConfig, get_config
from .frame_pattern import format_frame, frame_of, has_frame_token, match_pattern, number_paths
from .image import read_rgb
from .preview import display_attributes, write_display_image, _check_extension

__all__ = ["contact_sheet", "frame_paths", "frame_number", "draw_text_bitmap"]

def frame_number(path: str) -> Optional[float]:
    """The frame number in a file name (:func:`cmlt.io.frame_pattern.frame_of`:
    its last number, ``shot.1001.exr`` -> 1001), or ``None``."""
    return frame_of(path)


def frame_paths(paths_or_pattern: Union[str, os.PathLike, Iterable]) -> List[str]:
    """A list of paths as given, or the files a frame pattern (``####``,
    ``%04d``, ``$F4``; :mod:`cmlt.io.frame_pattern`) names exactly, or the
    files a glob matches, sorted by frame number."""
    if isinstance(paths_or_pattern, (str, os.PathLike)):
        pattern = os.fspath(paths_or_pattern)
        if os.path.isfile(pattern):
            return [pattern]
        if has_frame_token(pattern):
            found = [p for _, p in sorted(match_pattern(pattern).items())]
        else:
            found = [p for _, p in number_paths(sorted(glob.glob(pattern)))]
        if not found:
            raise FileNotFoundError(f"contact sheet: no files match '{pattern}'")
        return found
    paths = [os.fspath(p) for p in paths_or_pattern]
    if not paths:
        raise ValueError("contact sheet: no frames given")
    return paths


def _read_rgb(path: str, config: ColorConfig) -> np.ndarray:
    """An image file's colour (:mod:`cmlt.io.image`) -> float32 (H, W, 3) in the
    rendering space, from the colour space its header declares."""
    rgb, spec = read_rgb(path)
    src = config.colorspace_of_header(spec)
    return np.asarray(config.convert(rgb, src, config.rendering_space if src else None),
                      dtype=np.float32)


def _resize(rgb: np.ndarray, width: int) -> np.ndarray:
    """Shrink (or grow) to ``width`` pixels wide, keeping the aspect ratio,
    with OpenImageIO's filtered resize (in linear light)."""
    h, w = rgb.shape[:2]
    if w == width:
        return rgb
    height = max(1, int(round(h * width / w)))
    src = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.FLOAT))
    src.set_pixels(oiio.ROI(0, w, 0, h, 0, 1, 0, 3), np.ascontiguousarray(rgb))
    dst = oiio.ImageBufAlgo.resize(src, roi=oiio.ROI(0, width, 0, height, 0, 1, 0, 3))
    out = dst.get_pixels(oiio.FLOAT)
    return np.asarray(out, dtype=np.float32).reshape(height, width, 3)


# -- labels ---------------------------------------------------------------------

# 5x7 glyphs, one string of 7 rows of 5 bits per character.
_GLYPHS = {
    "0": ("01110", "10001", "10011", "10101", "11001", "10001", "01110"),
    "1": ("00100", "01100", "00100", "00100", "00100", "00100", "01110"),
    "2": ("01110", "10001", "00001", "00010", "00100", "01000", "11111"),
    "3": ("11111", "00010", "00100", "00010", "00001", "10001", "01110"),
    "4": ("00010", "00110", "01010", "10010", "11111", "00010", "00010"),
    "5": ("11111", "10000", "11110", "00001", "00001", "10001", "01110"),
    "6": ("00110", "01000", "10000", "11110", "10001", "10001", "01110"),
    "7": ("11111", "00001", "00010", "00100", "01000", "01000", "01000"),
    "8": ("01110", "10001", "10001", "01110", "10001", "10001", "01110"),
    "9": ("01110", "10001", "10001", "01111", "00001", "00010", "01100"),
    "-": ("00000", "00000", "00000", "11111", "00000", "00000", "00000"),
    ".": ("00000", "00000", "00000", "00000", "00000", "01100", "01100"),
    " ": ("00000",) * 7,
    "?": ("01110", "10001", "00001", "00010", "00100", "00000", "00100"),
}


def _glyph_mask(text: str, scale: int) -> np.ndarray:
    """Boolean mask (7*scale, (6*len-1)*scale) of ``text`` in the bitmap font."""
    cols = []
    for i, ch in enumerate(text):
        rows = _GLYPHS.get(ch, _GLYPHS["?"])
        glyph = np.array([[c == "1" for c in row] for row in rows], dtype=bool)
        if i:
            cols.append(np.zeros((7, 1), dtype=bool))
        cols.append(glyph)
    mask = np.concatenate(cols, axis=1) if cols else np.zeros((7, 0), dtype=bool)
    return np.kron(mask, np.ones((scale, scale), dtype=bool))


def draw_text_bitmap(canvas: np.ndarray, x: int, y: int, text: str, scale: int = 2,
                     color=(1.0, 1.0, 1.0)) -> Tuple[int, int]:
    """Draw ``text`` (digits, ``-``, ``.``) into a float (H, W, 3) canvas with the
    5x7 bitmap font, top-left corner at (x, y); clipped at the edges. Returns
    the text's (width, height) in pixels."""
    mask = _glyph_mask(text, scale)
    h, w = mask.shape
    H, W = canvas.shape[:2]
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + w, W), min(y + h, H)
    if x1 > x0 and y1 > y0:
        sub = mask[y0 - y:y1 - y, x0 - x:x1 - x]
        canvas[y0:y1, x0:x1][sub] = np.asarray(color, dtype=canvas.dtype)
    return w, h


def _label(canvas: np.ndarray, x: int, y: int, text: str, size: int, font: Optional[str]) -> None:
    """Label with a dark backing box at the top-left corner (x, y) of a cell."""
    scale = max(1, size // 8)
    tw, th = _glyph_mask(text, scale).shape[::-1]
    pad = max(1, scale)
    if font != "builtin":
        # OIIO font text: size in pixels; box sized for roughly 0.62 em digits
        tw = int(math.ceil(0.62 * size * len(text)))
        th = size
    box = (slice(y, y + th + 2 * pad), slice(x, x + tw + 2 * pad))
    canvas[box] *= 0.25
    if font != "builtin":
        buf = oiio.ImageBuf(oiio.ImageSpec(canvas.shape[1], canvas.shape[0], 3, oiio.FLOAT))
        buf.set_pixels(oiio.ROI(0, canvas.shape[1], 0, canvas.shape[0], 0, 1, 0, 3),
                       np.ascontiguousarray(canvas))
        ok = oiio.ImageBufAlgo.render_text(buf, x + pad, y + pad + size, text, size,
                                           font or "", (1.0, 1.0, 1.0))
        if ok:
            out = np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float32)
            canvas[...] = out.reshape(canvas.shape)
            return
        oiio.geterror()   # clear the "no font" error; fall back to the bitmap font
    draw_text_bitmap(canvas, x + pad, y + pad, text, scale)


# -- the sheet --------------------------------------------------------------------

def contact_sheet(paths_or_pattern, out_path: str, columns: Optional[int] = None,
                  label: bool = True, display: Optional[str] = None,
                  view: Optional[str] = None, *, thumb_width: int = 256, gap: int = 4,
                  background: float = 0.08, font: Optional[str] = None,
                  config: Optional[ColorConfig] = None) -> str:
    """Tile EXR frames into one display-referred PNG/JPEG; return ``out_path``.

    ``paths_or_pattern``: a list of files, a glob, or a frame pattern
    (``renders/shot.####.exr``, ``%04d``, ``$F4``). ``columns`` defaults to
    ceil(sqrt(n)). Every thumbnail is ``thumb_width`` pixels wide; cells are
    as tall as the tallest thumbnail, with ``gap`` pixels between and around
    them, so the sheet is ``columns*thumb_width + (columns+1)*gap`` wide and
    ``rows*cell_height + (rows+1)*gap`` high. ``label`` burns the frame
    number (the last digits of the file name, else the index) into each
    cell's top-left corner. ``font``: an OpenImageIO font name or path,
    ``None`` for OpenImageIO's default, ``"builtin"`` for the bitmap font.
    """
    _check_extension(out_path)
    if thumb_width < 1:
        raise ValueError(f"contact sheet: thumb_width must be >= 1, got {thumb_width}")
    cfg = config or get_config()
    display, view = cfg.check_display_view(display, view)
    paths = frame_paths(paths_or_pattern)
    n = len(paths)
    cols = int(columns) if columns else int(math.ceil(math.sqrt(n)))
    if cols < 1:
        raise ValueError(f"contact sheet: columns must be >= 1, got {columns}")
    rows = int(math.ceil(n / cols))

    thumbs = []
    for p in paths:
        rgb = _resize(_read_rgb(p, cfg), thumb_width)
        thumbs.append(np.clip(np.nan_to_num(cfg.display_transform(rgb, display, view),
                                            nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0))
    cell_h = max(t.shape[0] for t in thumbs)
    W = cols * thumb_width + (cols + 1) * gap
    H = rows * cell_h + (rows + 1) * gap
    sheet = np.full((H, W, 3), background, dtype=np.float32)
    size = int(np.clip(thumb_width // 10, 12, 32))   # label height in pixels
    for i, (p, thumb) in enumerate(zip(paths, thumbs)):
        r, c = divmod(i, cols)
        x = gap + c * (thumb_width + gap)
        y = gap + r * (cell_h + gap)
        sheet[y:y + thumb.shape[0], x:x + thumb_width] = thumb
        if label:
            num = frame_number(p)
            _label(sheet, x, y, format_frame(num) if num is not None else str(i), size, font)
    pixels = np.rint(np.clip(sheet, 0.0, 1.0) * 255.0).astype(np.uint8)
    attrs = display_attributes(cfg, display, view)
    attrs["ImageDescription"] = f"cmlt contact sheet of {n} frames; " + attrs["ImageDescription"]
    return write_display_image(pixels, out_path, attrs)
