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
    """camera_pan with pt: the film offset moves with the pan, and the error where a
    surface point went changes less from frame to frame (motion-compensated TF) than
    with the keys kept on the screen (the driver's REPROJECT off). Deterministic: fixed
    seeds, so either always passes or always fails; measured 0.35x (bound 0.8)."""
    from cmlt.metrics.flicker import motion_compensated_tf
    from cmlt.shot.motion import screen_flow
    from cmlt.shot import RenderOptions, render_sequence
    from cmlt.temporal import driver
    pan = os.path.join(str(support.SEQUENCES), "camera_pan", "shot.usda")
    res, frames = (48, 36), "1:4"

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
    rec = [json.load(open(p + ".json"))["temporal"]["film_offset"] for p in on.written]
    assert rec[0] == [0.0, 0.0] and all(r != [0.0, 0.0] for r in rec[1:]), rec
    assert all(json.load(open(p + ".json"))["temporal"]["film_offset"] == [0.0, 0.0]
               for p in off.written)
    _, ref = run("ref", 1024, seed=7)
    flow = screen_flow(pan, frames, res)
    tf_on = motion_compensated_tf(img_on, ref, flow)
    tf_off = motion_compensated_tf(img_off, ref, flow)
    print(f"motion-compensated TF: keys with the pan {tf_on:.4f}, on the screen {tf_off:.4f}")
    assert tf_on < 0.8 * tf_off, (tf_on, tf_off)
