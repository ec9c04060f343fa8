"""The pixel passes' sample keys follow the film offset (film/pass_splatter.h KeyShift).

With the frame's film offset (RenderSettings.film_offset_x/y, the image's screen motion
the temporal driver follows) rounded to d pixels, source pixel p takes the random
numbers of pixel p - d. On a frame whose radiance per sample depends on its random
numbers alone — a Lambertian plane seen from straight above, lit by a sun and a uniform
sky, nothing to occlude or to hit after the first bounce — the rendered image is then
the unshifted one moved by d, for every pixel integrator (pt, bdpt, the Metropolis
direct pass) and filter, away from the image's wrap-around: bit for bit with the box
filter, to float rounding with a splatting filter. That is the
check that the numbers travel with the image (and that every pixel still gets a whole
pixel's independent stream). On camera_pan the temporal driver moves the offset with
the pan, and pt's error follows the surfaces: frame f+1's error where a surface point
went is closer to frame f's than at the same pixel.
"""
import json
import os

import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Camera, FrameScene, Instance, Light, Material
from cmlt.shot.bridge import SceneBridge

import support
from cmlt.metrics import load_image
from support.scenes import plane, rot_x

W, H = 24, 16
SHIFT = (3, 2)          # pixels


def _flat_frame():
    cam = rot_x(-90.0)
    cam[1, 3] = 2.0     # 2 units above the plane, looking straight down
    return FrameScene(
        time=1.0, meshes=[plane(size=400.0)], instances=[Instance("/plane", 0, np.eye(4))],
        materials=[Material("/white", diffuse=(0.6, 0.5, 0.4), use_specular_workflow=True)],  # Lambertian
        lights=[Light("/sun", "distant", rot_x(-60), radiance=(3.0, 3.0, 3.0), angle=5.0),
                Light("/sky", "dome", np.eye(4), radiance=(0.2, 0.25, 0.3))],
        camera=Camera("/cam", cam, focal_length=35, horizontal_aperture=36, vertical_aperture=24),
        resolution=(W, H), meters_per_unit=1.0)


@pytest.fixture(scope="module")
def scene():
    return SceneBridge(core).update(_flat_frame())


def _render(scene, integrator, pixel_filter, offset):
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.seed, st.threads, st.max_depth = W, H, 4, 11, 2, 4
    st.integrator, st.pixel_filter = integrator, pixel_filter
    if integrator == "cmlt":
        st.mlt_paths = "none"   # no specular material: the frame is the direct pass alone
    st.film_offset_x, st.film_offset_y = offset
    r = core.render(scene, st)
    return np.asarray(r.image, np.float64)


@pytest.mark.parametrize("integrator", ["pt", "bdpt", "cmlt"])
@pytest.mark.parametrize("pixel_filter", ["box", "gaussian"])
def test_shifted_keys_move_the_image(scene, integrator, pixel_filter):
    a = _render(scene, integrator, pixel_filter, (0.0, 0.0))
    b = _render(scene, integrator, pixel_filter, (SHIFT[0] / W, SHIFT[1] / H))
    assert np.isfinite(a).all() and a.std() > 0.01 * a.mean()   # noisy: the test can see a shift
    dx, dy = SHIFT
    m = 3       # the filter's reach and the wrap-around: compare away from the edges
    inner_b = b[dy + m:H - m, dx + m:W - m]
    inner_a = a[m:H - m - dy, m:W - m - dx]
    if pixel_filter == "box":
        assert np.array_equal(inner_b, inner_a)
    else:
        # the splatter sums a row's sources in SIMD lanes from the window's first column:
        # moved by d, a pixel's sums are grouped differently (float rounding, ~1e-7)
        np.testing.assert_allclose(inner_b, inner_a, rtol=1e-6, atol=0)
    assert not np.array_equal(b[m:H - m, m:W - m], a[m:H - m, m:W - m])


def test_pt_error_follows_the_pan(tmp_path):
    """camera_pan with pt: the film offset moves with the pan and each pixel's key with
    its own motion (the key map), and the error where a surface point went changes less
    from frame to frame (motion-compensated TF) than with the keys kept on the screen
    (the driver's REPROJECT off), and less than with every key following the film offset
    alone (PIXEL_KEYS off: the dolly's parallax not followed). Deterministic: fixed
    seeds, so either always passes or always fails; at 48x48, measured 0.19x against the
    screen and 0.44x against the film offset's keys (bounds 0.8; at 48x36, where the
    pan's median motion rounds well, the key map gains only 0.87x)."""
    from cmlt.metrics.flicker import motion_compensated_tf
    from cmlt.shot.motion import screen_flow
    from cmlt.shot import RenderOptions, render_sequence
    from cmlt.temporal import driver
    pan = os.path.join(str(support.SEQUENCES), "camera_pan", "shot.usda")
    res, frames = (48, 48), "1:4"

    def run(name, spp, seed=0):
        out = str(tmp_path / name / "f.####.exr")
        opts = RenderOptions(integrator="pt", resolution=res, spp=spp, threads=0, seed=seed)
        r = render_sequence(pan, frames, out, opts, progress=False, quiet=True)
        return r, np.stack([load_image(p) for p in r.written])

    on, img_on = run("on", 16)
    try:
        driver.REPROJECT = False
        off, img_off = run("off", 16)
    finally:
        driver.REPROJECT = True
    try:
        driver.PIXEL_KEYS = False
        offset, img_offset = run("offset", 16)
    finally:
        driver.PIXEL_KEYS = True
    moved = [json.load(open(p + ".json"))["temporal"].get("pixel_keys_moved", 0) for p in on.written]
    assert moved[0] == 0 and all(m > 0 for m in moved[1:]), moved
    assert all("pixel_keys_moved" not in json.load(open(p + ".json"))["temporal"] for p in offset.written)
    rec = [json.load(open(p + ".json"))["temporal"]["film_offset"] for p in on.written]
    assert rec[0] == [0.0, 0.0] and all(r != [0.0, 0.0] for r in rec[1:]), rec
    assert all(json.load(open(p + ".json"))["temporal"]["film_offset"] == [0.0, 0.0]
               for p in off.written)
    _, ref = run("ref", 1024, seed=7)
    flow = screen_flow(pan, frames, res)
    tf_on = motion_compensated_tf(img_on, ref, flow)
    tf_off = motion_compensated_tf(img_off, ref, flow)
    tf_offset = motion_compensated_tf(img_offset, ref, flow)
    print(f"motion-compensated TF: key map {tf_on:.4f}, keys by the film offset {tf_offset:.4f}, "
          f"on the screen {tf_off:.4f}")
    assert tf_on < 0.8 * tf_off, (tf_on, tf_off)
    assert tf_on < 0.8 * tf_offset, (tf_on, tf_offset)


# ---- per-pixel key maps (RenderSettings.pixel_keys, driver.key_map) -----------------

def _render_keys(scene, integrator, keys):
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.seed, st.threads, st.max_depth = W, H, 4, 11, 2, 4
    st.integrator, st.pixel_filter = integrator, "box"
    if integrator == "cmlt":
        st.mlt_paths = "none"
    st.pixel_keys = keys
    return np.asarray(core.render(scene, st).image, np.float64)


@pytest.mark.parametrize("integrator", ["pt", "bdpt", "cmlt"])
def test_key_map_gives_each_pixel_its_keys_numbers(scene, integrator):
    """With a key map, pixel p renders what the unmapped frame renders at the pixel
    whose key it took (the flat frame: a sample's radiance depends on its numbers
    alone), bit for bit, for any permutation; the film offset is then ignored."""
    rng = np.random.default_rng(5)
    keys = rng.permutation(W * H).astype(np.uint32)
    a = _render_keys(scene, integrator, None)
    b = _render_keys(scene, integrator, keys)
    assert a.std() > 0.01 * a.mean()
    flat_a = a.reshape(W * H, 3)
    assert np.array_equal(b.reshape(W * H, 3), flat_a[keys])
    # the identity map is the unmapped frame
    assert np.array_equal(_render_keys(scene, integrator, np.arange(W * H, dtype=np.uint32)), a)


@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
def test_key_map_moves_the_chains_with_their_keys(scene, integrator):
    """The chains' film position follows the key map too (pssmlt_tracer.h FilmMap): with
    the chains on every path and no direct pass, on the flat frame, pixel p gets what the
    unmapped frame's chains put in the pixel whose key it took, bit for bit (the
    luminance target: the pixel importance's blur of its pilot is not permutation-
    equivariant, so with it the chains differ, still exact)."""
    keys = np.random.default_rng(5).permutation(W * H).astype(np.uint32)
    out = []
    for k in (None, keys):
        st = core.RenderSettings()
        st.width, st.height, st.spp, st.seed, st.threads, st.max_depth = W, H, 8, 11, 2, 4
        st.integrator, st.pixel_filter, st.importance = integrator, "box", "luminance"
        st.mlt_paths, st.direct_fraction, st.chains, st.bootstrap_samples = "all", 0.0, 64, 1024
        st.pixel_keys = k
        r = core.render(scene, st)
        assert dict(r.stats)["chains"] == 64 and dict(r.stats)["b"] > 0
        out.append(np.asarray(r.image, np.float64).reshape(W * H, 3))
    a, b = out
    assert a.std() > 0.1 * a.mean()
    assert np.array_equal(b, a[keys])


def test_key_map_must_be_a_permutation():
    st = core.RenderSettings()
    st.width, st.height = 4, 2
    st.pixel_keys = [0, 1, 2, 3, 4, 5, 6, 6]
    with pytest.raises(core.SettingsError, match="pixel_keys: not a permutation"):
        st.validate()
    st.pixel_keys = [0, 1, 2]
    with pytest.raises(core.SettingsError, match="pixel_keys: 3 keys for 4 x 2"):
        st.validate()
    st.pixel_keys = list(range(7, -1, -1))
    st.validate()


def _grid(w, h):
    from cmlt.temporal.driver import anchor_grid
    n_x, n_y = anchor_grid(w, h)
    gx, gy = np.meshgrid((np.arange(n_x) + 0.5) * w / n_x, (np.arange(n_y) + 0.5) * h / n_y)
    a = np.zeros((n_y, n_x, 6))
    a[..., 4], a[..., 5] = gx, gy
    return a, gx, gy


def test_key_map_of_a_pan_is_the_film_offsets_shift():
    """A pure whole-pixel pan moves every key by the pan, wrapping on the image's torus:
    the film offset's KeyShift exactly (its keys computed by the core)."""
    from cmlt.temporal.driver import key_map
    w, h = 20, 12
    a, gx, gy = _grid(w, h)
    for d in [(2.3, -1.1), (-0.7, 0.0), (0.0, 3.49)]:
        p = np.stack([gx + d[0], gy + d[1]], -1)
        keys = key_map(None, a.ravel(), p.ravel(), w, h)
        dx, dy = round(d[0]), round(d[1])
        x, y = np.meshgrid(np.arange(w), np.arange(h))
        want = ((y - dy) % h) * w + (x - dx) % w
        assert np.array_equal(keys.reshape(h, w), want), d


def test_key_map_stays_a_permutation_and_follows_each_pixel():
    """Composed over frames under zooms and shears (each pixel its own motion), the
    map stays a permutation; a pixel whose source is the only one landing on it has
    the source's key; too few valid anchors give no map; a key pushed off a taken
    pixel by a nearer-centred one goes to a pixel nobody reached."""
    from cmlt.temporal.driver import key_map
    w, h = 30, 20
    a, gx, gy = _grid(w, h)
    rng = np.random.default_rng(1)
    keys = None
    for f in range(6):
        s, t = rng.uniform(0.9, 1.1), rng.uniform(-0.2, 0.2)
        p = np.stack([(gx - w / 2) * s + t * (gy - h / 2) + w / 2 + rng.uniform(-2, 2),
                      (gy - h / 2) * s + h / 2 + rng.uniform(-2, 2)], -1)
        new = key_map(keys, a.ravel(), p.ravel(), w, h)
        assert new.dtype == np.uint32 and np.array_equal(np.sort(new), np.arange(w * h))
        old = np.arange(w * h) if keys is None else keys
        # the sources that reached a pixel alone keep their key there
        tx = np.floor(p[..., 0]).astype(int).ravel()
        ty = np.floor(p[..., 1]).astype(int).ravel()
        inside = (tx >= 0) & (tx < w) & (ty >= 0) & (ty < h)
        tgt = np.where(inside, ty * w + tx, -1)
        counts = np.bincount(tgt[inside], minlength=w * h)
        alone = np.flatnonzero(inside & (counts[np.maximum(tgt, 0)] == 1))
        assert alone.size > w * h // 2
        assert np.array_equal(new[tgt[alone]], old[alone])
        keys = new
    # an invalid anchor is nothing hit (instance -1); under a quarter valid: no map
    bad = a.copy()
    bad[..., 0] = -1
    bad.reshape(-1, 6)[: (w * h) // 5, 0] = 0
    assert key_map(None, bad.ravel(), np.stack([gx, gy], -1).ravel(), w, h) is None
    # two sources onto one pixel: the one nearer its centre keeps it
    a1, gx1, gy1 = _grid(3, 1)
    p = np.stack([np.array([[1.45, 1.9, 2.5]]), gy1], -1)   # pixels 0 and 1 land in pixel 1
    keys = key_map(None, a1.ravel(), p.ravel(), 3, 1)
    assert list(keys) == [1, 0, 2]     # pixel 1 takes key 0 (0.05 from the centre); key 1 fills pixel 0
