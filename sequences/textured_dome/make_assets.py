"""Writes the textures of textured_dome (numpy + OpenImageIO, nothing downloaded):

* ``textures/sky.exr``: a 512 x 256 float lat-long HDR environment (UsdLux DomeLight /
  OpenEXR latlong: +Y up, left edge longitude +pi, centre column +Z): a sky gradient
  (pale horizon, blue zenith), a dim brownish ground and a bright sun-like Gaussian blob
  (peak ~2000) about 35 degrees above the horizon;
* ``textures/checker.png``: an 8-bit sRGB 256 x 256 checkerboard (8 x 8, orange / cream);
* ``textures/stripes.png``: an 8-bit sRGB 256 x 256 pattern of blue / white stripes.

Run: ``.venv/bin/python sequences/textured_dome/make_assets.py``.
"""
import os

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "textures")


def latlong_dirs(w, h):
    s = (np.arange(w) + 0.5) / w
    t = 1.0 - (np.arange(h) + 0.5) / h
    phi = np.pi * (1 - 2 * s)[None, :]
    theta = np.pi * (1 - t)[:, None]
    return np.stack(np.broadcast_arrays(np.sin(theta) * np.sin(phi), np.cos(theta),
                                        np.sin(theta) * np.cos(phi)), -1)


def sky(w=512, h=256):
    d = latlong_dirs(w, h)
    up = d[..., 1]
    horizon = np.array([0.95, 0.9, 0.85])
    zenith = np.array([0.25, 0.45, 0.9])
    k = np.clip(up, 0, 1)[..., None] ** 0.5
    img = horizon * (1 - k) + zenith * k
    ground = np.array([0.12, 0.1, 0.08])
    img = np.where((up < 0)[..., None], ground, img)
    el, az = np.radians(35.0), np.radians(60.0)
    sun = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    c = np.clip(d @ sun, -1, 1)
    blob = 2000.0 * np.exp(-(1 - c) / 2e-4)
    img = img + blob[..., None] * np.array([1.0, 0.95, 0.85])
    return img.astype(np.float32)


def write(path, img, fmt):
    h, w, c = img.shape
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(w, h, c, fmt))
    out.write_image(np.ascontiguousarray(img))
    out.close()


def main():
    os.makedirs(OUT, exist_ok=True)
    write(os.path.join(OUT, "sky.exr"), sky(), oiio.HALF)
    n = 256
    y, x = np.mgrid[0:n, 0:n]
    chk = ((x // 32 + y // 32) % 2).astype(bool)
    img = np.where(chk[..., None], np.array([230, 120, 30]), np.array([240, 230, 200]))
    write(os.path.join(OUT, "checker.png"), img.astype(np.uint8), oiio.UINT8)
    st = ((x + y) // 24 % 2).astype(bool)
    img = np.where(st[..., None], np.array([30, 70, 170]), np.array([235, 235, 235]))
    write(os.path.join(OUT, "stripes.png"), img.astype(np.uint8), oiio.UINT8)


if __name__ == "__main__":
    main()
