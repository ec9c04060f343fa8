"""Mean brightness of pssmlt and cmlt against bdpt and pt on a small room lit only
through a slit (after sequences/door_ajar at frame 1), and the pixel importance's
guard against a pilot that is noise.

The chains' target is f* = Y / P(pixel), P from a 1-spp pilot image. In a dark scene
whose light the pilot finds only by chance (door_ajar at frame 1: 14-27 of 4,096 pixels
lit) P is a few blobs around the hits with every other pixel at the floor, the chains
hardly visit the blobs, and a typical render comes out dark (door_ajar at 64x64, 350
evaluations per pixel: 0.84 of bdpt over five seeds; the mean over many renders is
right, the estimator heavy-tailed); such a pilot now gives the luminance target.
test_01 checks that rule; test_02 the mean brightness on the slit room (where the rule
does not apply: its pilot lights most pixels; at this size the old heavy tail did not
show, so test_02 guards the agreement rather than reproducing door_ajar).

Confidence intervals: K seeds per integrator give a mean and a standard error (MLT pixel
errors are correlated within a render, renders are independent); the reference's own
standard error (bdpt and pt: their variance AOV over independent passes) is added in
quadrature; Student's t with K - 1 dof at a two-sided false-alarm rate of 1e-3 per
comparison (four comparisons: about 4e-3 for the file). Deterministic keys: each check
either always passes or always fails.
"""
import math

import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Camera, FrameScene, Instance, Material
from cmlt.shot.bridge import SceneBridge

from support.scenes import quad
from support.stats import ACESCG_Y, lum_se, t_critical

pytestmark = pytest.mark.statistical

RES = 24
MAX_DEPTH = 6
SEEDS = 8
MLT_SPP = 384          # path evaluations per pixel of each pssmlt / cmlt render
REF_SPP = 2048         # bdpt and pt reference samples per pixel
ALPHA = 1e-3


def slit_room():
    """A closed 2 m room (white walls, grey floor) whose right wall (x = 1) has a
    vertical slit 0.12 m wide; outside it an emissive panel faces the slit, so the light
    enters only through it: a lit strip on the floor and the back wall (depth 1, the
    direct pass) and indirect light everywhere else (depths >= 2, the chains). Camera
    inside, near the left wall, looking at the slit wall."""
    mats = [Material("/white", diffuse=(0.75, 0.75, 0.75)), Material("/floor", diffuse=(0.5, 0.45, 0.4)),
            Material("/light", diffuse=(0.0, 0.0, 0.0), emission=(60.0, 52.0, 40.0))]
    w = 0.06   # half width of the slit (z)
    quads = [  # normals point into the room (u x v)
        quad("/floor", (0, 0, 0), (0, 0, 1), (1, 0, 0), 1),
        quad("/ceiling", (0, 2, 0), (1, 0, 0), (0, 0, 1), 0),
        quad("/back", (0, 1, -1), (1, 0, 0), (0, 1, 0), 0),
        quad("/front", (0, 1, 1), (0, 1, 0), (1, 0, 0), 0),
        quad("/left", (-1, 1, 0), (0, 1, 0), (0, 0, 1), 0),
        # right wall in two parts around the slit z in [-w, w]
        quad("/right_a", (1, 1, (-1 - w) / 2), (0, 0, (1 - w) / 2), (0, 1, 0), 0),
        quad("/right_b", (1, 1, (1 + w) / 2), (0, 0, (1 - w) / 2), (0, 1, 0), 0),
        # the panel outside, facing -x (towards the slit), a little above the floor
        quad("/lamp", (1.6, 1.4, 0.3), (0, 0.6, 0), (0, 0, 0.6), 2),
    ]
    cam_xf = np.eye(4)
    a = math.radians(-75)   # yaw towards +x
    cam_xf[:3, :3] = [[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]]
    cam_xf[:3, 3] = (-0.85, 1.0, 0.3)
    return FrameScene(
        time=1.0, meshes=quads, instances=[Instance(q.name, i, np.eye(4)) for i, q in enumerate(quads)],
        materials=mats, lights=[],
        camera=Camera("/cam", cam_xf, focal_length=14, horizontal_aperture=24, vertical_aperture=24),
        resolution=(RES, RES), meters_per_unit=1.0)


def lit_floor():
    """A grey floor under an emissive panel (black and without a specular layer: it
    reflects nothing) and nothing else: every path that carries light has depth 0 or 1."""
    mats = [Material("/floor", diffuse=(0.6, 0.6, 0.6)),
            Material("/light", diffuse=(0.0, 0.0, 0.0), emission=(10.0, 10.0, 10.0), ior=1.0)]
    quads = [quad("/floor", (0, 0, 0), (0, 0, 2), (2, 0, 0), 0),
             quad("/lamp", (0, 1.5, 0), (0.4, 0, 0), (0, 0, -0.4), 1)]   # facing down
    cam_xf = np.eye(4)
    a = math.radians(-35)
    cam_xf[:3, :3] = [[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]]
    cam_xf[:3, 3] = (0, 1.2, 2.4)
    return FrameScene(
        time=1.0, meshes=quads, instances=[Instance(q.name, i, np.eye(4)) for i, q in enumerate(quads)],
        materials=mats, lights=[],
        camera=Camera("/cam", cam_xf, focal_length=20, horizontal_aperture=24, vertical_aperture=24),
        resolution=(RES, RES), meters_per_unit=1.0)


def _settings(integrator, spp, seed, **kw):
    st = core.RenderSettings()
    st.width = st.height = RES
    st.spp, st.seed, st.threads, st.max_depth = spp, seed, 2, MAX_DEPTH
    st.integrator = integrator
    for k, v in kw.items():
        setattr(st, k, v)
    return st


def _mean_y(img):
    return float(np.asarray(img, np.float64).reshape(-1, 3).mean(0) @ ACESCG_Y)


@pytest.fixture(scope="module")
def slit_runs():
    bridge = SceneBridge(core)
    scene = bridge.update(slit_room())
    refs = {}
    for name in ("bdpt", "pt"):
        r = core.render(scene, _settings(name, REF_SPP, 1000))
        refs[name] = (_mean_y(r.image), lum_se(np.asarray(r.variance, np.float64)))
    mlt = {}
    for name in ("pssmlt", "cmlt"):
        means = []
        for seed in range(SEEDS):
            r = core.render(scene, _settings(name, MLT_SPP, seed))
            img = np.asarray(r.image, np.float64)
            assert np.isfinite(img).all()
            means.append(_mean_y(img))
        mlt[name] = np.array(means)
    return refs, mlt


@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
@pytest.mark.parametrize("reference", ["bdpt", "pt"])
def test_02_mean_brightness_agrees_with_the_unbiased_integrators(slit_runs, integrator, reference):
    refs, mlt = slit_runs
    ref, ref_se = refs[reference]
    means = mlt[integrator]
    m, se = float(means.mean()), float(means.std(ddof=1) / math.sqrt(SEEDS))
    t = t_critical(SEEDS - 1, ALPHA)
    print(f"{integrator}: mean Y {m:.5f} +- {se:.5f} over {SEEDS} seeds; {reference} {ref:.5f} +- "
          f"{ref_se:.5f}; ratio {m / ref:.3f}, interval +-{t * math.hypot(se, ref_se) / ref:.3f}")
    assert ref > 0
    assert abs(m - ref) < t * math.hypot(se, ref_se), (m, se, ref, ref_se)


def test_01_a_pilot_that_lights_few_pixels_gives_the_luminance_target():
    # door_ajar's 1-spp pilot lights 14-27 of 4,096 pixels: blobs around chance hits
    # that would divide f* by up to the floor's 20x; below a tenth of the pixels lit the
    # pilot is taken for noise and the chains follow the luminance (pixel_importance.h)
    bridge = SceneBridge(core)
    scene = bridge.update(lit_floor())
    rng = np.random.default_rng(7)

    def render(pilot=None, **kw):
        st = _settings("pssmlt", 64, 5, direct_fraction=0.0, **kw)
        if pilot is not None:
            st.pilot = pilot
        return np.asarray(core.render(scene, st).image)

    # a black pilot gives the luminance target at the same budget (the pilot's cost counts)
    luminance = render(pilot=np.zeros((RES, RES, 3), np.float32))
    assert np.array_equal(luminance, render(pilot=np.zeros((RES, RES, 3), np.float32)))
    sparse = np.zeros((RES, RES, 3), np.float32)
    hits = rng.choice(RES * RES, size=RES * RES // 20, replace=False)   # 5 % of the pixels
    sparse.reshape(-1, 3)[hits] = 50.0
    assert np.array_equal(render(pilot=sparse), luminance)
    # a pilot that lights most pixels is used (a different target, a different image)
    dense = np.full((RES, RES, 3), 0.2, np.float32)
    dense[:, : RES // 2] = 2.0
    assert not np.array_equal(render(pilot=dense), luminance)
