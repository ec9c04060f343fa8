"""Converged references of the hard-case stages, and the table of cases the tests use.

    .venv/bin/python sequences/hard/make_references.py [case ...]   # build / refresh the cache

A reference is K independent renders (seeds 1001..1000+K) of a case with its
reference integrator at a high budget: their mean image, the mean of each render's
image mean, and the standard error of that mean over the K seeds (independent
renders, so a t-interval with K - 1 degrees of freedom is exact for normal
means). References are cached in ``renders/hard/refs/`` (never committed), keyed by
a hash of the stage file, the reference settings, the core module's binary and this
file, so a changed stage, core or way of making them renders them again.
``tests/python/hard/`` builds what is missing on first use.

Pixels that hold a sub-millimetre sphere light seen directly are integrated apart
(:func:`refine_tiny_lights`): no integrator here finds a 0.4 mm bulb that covers
2e-5 of a pixel at a few thousand samples per pixel, so such a pixel is
split into 16 x 16 strata, the strata around the bulb's projected disk are rendered
as a window of their own at 64 x 64 sub-pixels (where the bulb covers dozens of
them), and the pixel is the area-weighted sum of both (stratified sampling of the
pixel integral: exact, and converged at a few hundred thousand camera rays).

Every render here (references, refinements, the tests' renders) uses the one-pixel box
filter: a refined pixel is the integral over its own square, which is what a box pixel
is; under a wider filter the bulb's pixel would be a weighted sum over its neighbours'
squares too.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import sys
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
CACHE = os.path.join(ROOT, "renders", "hard", "refs")

#: ACEScg luminance weights (the renderer's f* and image statistics)
Y = np.array([0.2722287, 0.6740818, 0.0536895])


@dataclass(frozen=True)
class Case:
    """One hard case: its stage folder, how its reference is made, how the tests
    render it, and what it must show."""

    name: str
    expect: str                                  # one line: what a correct render shows
    ref_integrator: str = "pt"
    ref_spp: int = 256
    ref_seeds: int = 12
    test_spp: int = 64
    test_seeds: int = 8
    #: the reference of another case (the same scene: scale, degenerate input)
    same_as: Optional[str] = None
    #: the image is exactly black (every pixel 0, b = 0)
    black: bool = False
    #: extra core settings of every render (reference and tests)
    settings: Tuple[Tuple[str, object], ...] = ()

    @property
    def stage(self) -> str:
        return os.path.join(HERE, self.name, "shot.usda")


CASES: Dict[str, Case] = {c.name: c for c in [
    Case("scale_unit", "a room lit by a rect light: the reference of the scale and degenerate cases"),
    Case("scale_1e-4", "the scale_unit room scaled by 1e-4: the same image", same_as="scale_unit"),
    Case("scale_1e5", "the scale_unit room scaled by 1e5: the same image", same_as="scale_unit"),
    Case("degenerate", "scale_unit plus zero-area faces, coincident vertices, a NaN point and NaN "
         "normals: the same image, no NaN sample", same_as="scale_unit"),
    Case("tiny_sphere_light", "a room lit by a 0.5 mm sphere light hidden behind a crate"),
    Case("point_light", "a room lit by a point light: sharp shadows"),
    Case("caustic_lsdse", "a glass ball's caustic on the floor, seen directly (L S S D E)",
         ref_integrator="pt", ref_spp=512, ref_seeds=16),
    Case("caustic_sds", "the caustic seen through a glass slab (L S S D S S E)",
         ref_integrator="pt", ref_spp=256),
    Case("slit", "a closed room lit through a 2 cm slit", ref_spp=512),
    Case("grazing", "floor seen 1 cm above it, sun 0.5 degrees above the horizon"),
    Case("specular_only", "mirrors and glass only: the light seen through specular chains"),
    Case("all_black", "the only light sealed in a box: exactly black", black=True,
         ref_spp=16, ref_seeds=2),
    Case("light_behind_glass", "a small light inside a closed glass box (next-event estimation "
         "blocked)", ref_integrator="bdpt", ref_spp=128),
    Case("bulb_room", "a room lit by a 0.4 mm bulb of radiance 2e7 that the camera sees directly "
         "(one pixel of about 450), part of it in a mirror and through a glass slab; the "
         "mirror and the slab throw the bulb's caustics on the floor, which only bdpt and "
         "the Metropolis integrators find (the reference is bdpt)",
         ref_integrator="bdpt", ref_spp=256, ref_seeds=8, test_spp=256, test_seeds=10),
]}


# --- rendering ---------------------------------------------------------------------------

def load(case: Case):
    """(core, FrameScene) of a case's stage at time 1."""
    import cmlt._core as core
    from cmlt.usd import load_frame, open_stage
    return core, load_frame(open_stage(case.stage), 1.0)


def core_settings(core, fs, integrator: str, spp: int, seed: int, threads: int = 2,
                  extra=()) -> "core.RenderSettings":
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.seed, st.threads, st.integrator = int(spp), int(seed), int(threads), integrator
    st.pixel_filter = "box"  # the refined pixels are box pixels (file comment)
    for key, value in extra:
        setattr(st, key, value)
    return st


def render(case: Case, integrator: str, spp: int, seed: int, threads: int = 2,
           fs=None, scene=None, **extra):
    """One render: (image float64 (H, W, 3), stats dict, direct-pass image or None)."""
    from cmlt.shot.bridge import SceneBridge
    core, fs0 = load(case) if fs is None else (_core(), fs)
    if scene is None:
        scene = SceneBridge(core).update(fs0)
    st = core_settings(core, fs0, integrator, spp, seed, threads,
                       tuple(case.settings) + tuple(extra.items()))
    r = core.render(scene, st)
    img = np.asarray(r.image, np.float64)
    direct = getattr(r, "direct", None)
    direct = np.asarray(direct, np.float64).reshape(img.shape) if direct is not None and len(direct) else None
    return img, dict(r.stats), direct


def _core():
    import cmlt._core as core
    return core


# --- tiny lights seen directly -----------------------------------------------------------

def tiny_light_pixels(fs, max_radius: float = 1e-3) -> List[Tuple[int, int, float, float, float]]:
    """Pixels holding the projected disk of a sphere light of radius <= ``max_radius`` in
    front of a perspective camera: (px, py, x, y, r) with (x, y) the disk's raster
    centre and r its raster radius (occlusion is not tested: a hidden light's window
    simply renders what hides it)."""
    cam = fs.camera
    W, H = fs.resolution
    inv = np.linalg.inv(np.asarray(cam.transform, np.float64))
    ha, hoff, voff, f = cam.horizontal_aperture, cam.horizontal_aperture_offset, \
        cam.vertical_aperture_offset, cam.focal_length
    out = []
    for light in fs.lights:
        if light.kind != "sphere" or light.treat_as_point or not (0 < light.radius <= max_radius):
            continue
        p = inv @ np.append(np.asarray(light.transform, np.float64)[:3, 3], 1.0)
        depth = -p[2]
        if depth <= light.radius:
            continue
        wx, wy = p[0] / depth * f, p[1] / depth * f            # image-plane window position
        x = ((wx - hoff) / ha + 0.5) * W
        y = (0.5 - (wy - voff) / (ha * H / W)) * H
        r = light.radius / depth * f / ha * W
        for py in range(int(math.floor(y - 2 * r)), int(math.floor(y + 2 * r)) + 1):
            for px in range(int(math.floor(x - 2 * r)), int(math.floor(x + 2 * r)) + 1):
                if 0 <= px < W and 0 <= py < H:
                    out.append((px, py, x, y, r))
    return out


def _window(fs, x0: float, y0: float, side: float, res: int):
    """A copy of the frame whose camera sees only the square raster window
    [x0, x0 + side) x [y0, y0 + side) of the original image, at res x res pixels."""
    W, H = fs.resolution
    cam = dataclasses.replace(fs.camera)
    ha = cam.horizontal_aperture
    cx, cy = x0 + side / 2, y0 + side / 2
    cam.horizontal_aperture = ha * side / W
    cam.horizontal_aperture_offset = fs.camera.horizontal_aperture_offset + ha * (cx / W - 0.5)
    cam.vertical_aperture_offset = fs.camera.vertical_aperture_offset + ha * H / W * (0.5 - cy / H)
    cam.vertical_aperture = cam.horizontal_aperture
    return dataclasses.replace(fs, camera=cam, resolution=(res, res))


def refine_tiny_lights(case: Case, fs, seeds: int, strata: int = 16, sub: int = 64,
                       spp: int = 8, max_radius: float = 1e-3) -> List[dict]:
    """Stratified estimates of the pixels :func:`tiny_light_pixels` finds (see the file
    comment): per pixel its value (3,) and the standard error of its luminance over
    ``seeds`` independent estimates."""
    from cmlt.shot.bridge import SceneBridge
    core = _core()
    done = {}
    for px, py, x, y, r in tiny_light_pixels(fs, max_radius):
        if (px, py) in done:
            continue
        # strata block around the disk (margin: twice its radius), clipped to the pixel
        s = 1.0 / strata
        i0 = max(0, int(math.floor((x - 2 * r - px) / s)))
        i1 = min(strata - 1, int(math.floor((x + 2 * r - px) / s)))
        j0 = max(0, int(math.floor((y - 2 * r - py) / s)))
        j1 = min(strata - 1, int(math.floor((y + 2 * r - py) / s)))
        k = max(i1 - i0, j1 - j0) + 1
        i0, j0 = min(i0, strata - k), min(j0, strata - k)
        grid = _window(fs, px, py, 1.0, strata)
        block = _window(fs, px + i0 * s, py + j0 * s, k * s, k * sub)
        sg, sb = SceneBridge(core).update(grid), SceneBridge(core).update(block)
        vals = []
        for seed in range(1, seeds + 1):
            g = np.asarray(core.render(sg, core_settings(core, grid, "pt", spp * 4, 7000 + seed)).image,
                           np.float64)
            b = np.asarray(core.render(sb, core_settings(core, block, "pt", spp, 8000 + seed)).image,
                           np.float64)
            g[j0:j0 + k, i0:i0 + k] = 0.0
            vals.append((g.sum((0, 1)) + b.mean((0, 1)) * k * k) / (strata * strata))
        vals = np.asarray(vals)
        lum = vals @ Y
        done[(px, py)] = {"pixel": [px, py], "value": vals.mean(0).tolist(),
                          "lum_se": float(lum.std(ddof=1) / math.sqrt(len(lum))),
                          "centre": [x, y], "radius": r}
    return list(done.values())


# --- references --------------------------------------------------------------------------

def _core_hash() -> str:
    core = _core()
    h = hashlib.sha256()
    with open(core.__file__, "rb") as fh:
        h.update(fh.read())
    return h.hexdigest()[:16]


def cache_key(case: Case) -> str:
    h = hashlib.sha256()
    with open(case.stage, "rb") as fh:
        h.update(fh.read())
    spec = {k: v for k, v in dataclasses.asdict(case).items() if k.startswith("ref_") or k == "settings"}
    h.update(json.dumps(spec, sort_keys=True, default=str).encode())
    h.update(_core_hash().encode())
    with open(__file__, "rb") as fh:   # how references are made (settings, refinement)
        h.update(fh.read())
    return h.hexdigest()[:20]


@dataclass
class Reference:
    case: str
    image: np.ndarray               # mean image (H, W, 3)
    seed_means: np.ndarray          # (K,) luminance mean of each render (refined pixels excluded)
    mean: float                     # luminance image mean (refined pixels included)
    se: float                       # its standard error
    dof: int                        # degrees of freedom of se
    refined: List[dict] = field(default_factory=list)

    @property
    def max(self) -> float:
        return float((self.image @ Y).max())


def make_reference(case: Case, force: bool = False) -> Reference:
    """The (cached) reference of ``case`` (or of the case it is the same scene as)."""
    if case.same_as:
        return make_reference(CASES[case.same_as], force)
    os.makedirs(CACHE, exist_ok=True)
    path = os.path.join(CACHE, f"{case.name}-{cache_key(case)}.npz")
    if os.path.exists(path) and not force:
        z = np.load(path, allow_pickle=False)
        return Reference(case.name, z["image"], z["seed_means"], float(z["mean"]), float(z["se"]),
                         int(z["dof"]), json.loads(str(z["refined"])))
    from cmlt.shot.bridge import SceneBridge
    core, fs = load(case)
    scene = SceneBridge(core).update(fs)
    W, H = fs.resolution
    refined = refine_tiny_lights(case, fs, seeds=4)
    mask = np.ones((H, W), bool)
    for r in refined:
        mask[r["pixel"][1], r["pixel"][0]] = False
    images, means = [], []
    for k in range(case.ref_seeds):
        img, _, _ = render(case, case.ref_integrator, case.ref_spp, 1001 + k, fs=fs, scene=scene)
        images.append(img)
        means.append(float(((img @ Y) * mask).sum() / (W * H)))
    image = np.mean(images, axis=0)
    means = np.asarray(means)
    extra = sum(np.asarray(r["value"]) @ Y for r in refined) / (W * H)
    extra_var = sum(r["lum_se"] ** 2 for r in refined) / (W * H) ** 2
    for r in refined:
        image[r["pixel"][1], r["pixel"][0]] = r["value"]
    se = math.sqrt(means.var(ddof=1) / len(means) + extra_var) if len(means) > 1 else 0.0
    ref = Reference(case.name, image, means, float(means.mean() + extra), se, len(means) - 1, refined)
    tmp = path + f".tmp{os.getpid()}.npz"
    np.savez(tmp, image=ref.image, seed_means=ref.seed_means, mean=ref.mean, se=ref.se,
             dof=ref.dof, refined=json.dumps(refined))
    os.replace(tmp, path)
    return ref


def main(argv):
    names = argv or list(CASES)
    for name in names:
        case = CASES[name]
        ref = make_reference(case, force=True)
        print(f"{name:20s} mean {ref.mean:.6g} ± {ref.se:.3g} (dof {ref.dof})  max {ref.max:.4g}  "
              f"refined {[(r['pixel'], round(float(np.asarray(r['value']) @ Y), 2)) for r in ref.refined]}")


if __name__ == "__main__":
    main(sys.argv[1:])
