"""pt's caustic light tracing (src/core/integrators/path/caustic_light_tracing.h): the
caustic paths (light reaching a rough surface through a Dirac bounce, the rough surface
seen directly) are made both by camera paths that hit the light and by light paths
connected to the lens, MIS-weighted. The estimator must stay the same in expectation and
lose variance.

The stage: a glass ball on a diffuse floor under a sphere light, the caustic in the ball's
shadow seen directly (sequences/hard/caustic_lsdse's layout, with a 10 cm light so that
camera paths alone find the caustic often enough to be compared with). Renders with and
without (`caustic_tracing` off) use the same camera-path random numbers (the light paths
have their own stream), so the per-seed difference of the image means is the difference
of the two estimates of the caustic paths alone: a paired test.
"""
import importlib.util
import math
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
LUM = np.array([0.2126, 0.7152, 0.0722])
SEEDS = 48


def _stages(tmp):
    spec = importlib.util.spec_from_file_location("cmlt_hard_stages_ct", os.path.join(ROOT, "sequences", "hard",
                                                                                     "make_stages.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.HERE = str(tmp)
    return mod


@pytest.fixture(scope="module")
def frame(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("caustic")
    ms = _stages(tmp)
    path = ms.glass_ball_under_light(ms.Stage("ball", "A glass ball's caustic seen directly, 10 cm light."),
                                     0.1, 2.4e3)
    import cmlt._core as core
    from cmlt.shot.bridge import SceneBridge
    from cmlt.usd import load_frame, open_stage
    fs = load_frame(open_stage(path), 1.0)
    return core, fs, SceneBridge(core).update(fs)


def _images(frame, on: bool, spp: int = 64, integrator: str = "pt", **extra):
    """Per seed: the luminance image (flat); and the stats' caster count."""
    core, fs, scene = frame
    out, casters = [], None
    for seed in range(1, SEEDS + 1):
        st = core.RenderSettings()
        st.width, st.height = fs.resolution
        st.spp, st.seed, st.threads, st.integrator = spp, seed, 2, integrator
        st.pixel_filter = "box"
        st.caustic_tracing = on
        for k, v in extra.items():
            setattr(st, k, v)
        r = core.render(scene, st)
        img = np.asarray(r.image, np.float64)
        assert np.isfinite(img).all()
        out.append(img.reshape(-1, 3) @ LUM)
        casters = dict(r.stats).get("caustic_casters", 0)
    return np.array(out), casters


def test_same_mean_and_less_variance_with_light_traced_caustics(frame):
    on_img, casters_on = _images(frame, True)
    off_img, casters_off = _images(frame, False)
    assert casters_on == 1 and casters_off == 0  # the ball is the one caster; off: none traced
    on, off = on_img.mean(axis=1), off_img.mean(axis=1)
    d = on - off
    se = d.std(ddof=1) / math.sqrt(len(d))
    # paired: the mean difference is zero within 4.5 standard errors (two-sided alpha
    # ~1e-5 for a t with 47 degrees of freedom; the estimator with camera paths alone is
    # heavy-tailed, which widens se, not the test's false-alarm rate for a biased mean)
    assert abs(d.mean()) <= 4.5 * se, f"mean difference {d.mean():.5g} ± {se:.3g} (on {on.mean():.5g}, off {off.mean():.5g})"
    # and the noise drops: the per-pixel variance over seeds relative to the pixel's
    # value (relMSE's weighting, mean over pixels of var / (mean^2 + 1e-2)) falls by far
    # more than 4x (measured 30x: 0.0175 against 0.526 over 24 seeds); the image mean's
    # spread less (2.6x), as the ball's highlight, found by camera rays in both, stays
    ref = on_img.mean(axis=0)
    rel = lambda imgs: float((imgs.var(axis=0, ddof=1) / (ref ** 2 + 1e-2)).mean())
    assert rel(on_img) < 0.25 * rel(off_img), (rel(on_img), rel(off_img))


def test_a_chainless_metropolis_frame_traces_caustics_as_pt_does(frame):
    """cmlt with --mlt-paths none: the direct pass renders every path, so it traces the
    caustics from the lights too (src/core/integrators/mlt/direct_pass.h,
    enable_light_tracing): its frame agrees with pt's (unpaired: the passes have keys of
    their own; the image mean over 48 seeds within 4.5 standard errors), with pt's noise
    (the per-pixel relative variance over seeds within 0.5-2x of pt's), far below the
    same pass without the light paths."""
    on_img, casters = _images(frame, True, integrator="cmlt", mlt_paths="none")
    assert casters == 1  # the sidecar says the pass traced the ball's caustics
    pt_img, _ = _images(frame, True)
    on, pt = on_img.mean(axis=1), pt_img.mean(axis=1)
    se = math.hypot(on.std(ddof=1), pt.std(ddof=1)) / math.sqrt(SEEDS)
    assert abs(on.mean() - pt.mean()) <= 4.5 * se, (on.mean(), pt.mean(), se)
    ref = pt_img.mean(axis=0)
    rel = lambda imgs: float((imgs.var(axis=0, ddof=1) / (ref ** 2 + 1e-2)).mean())
    assert 0.5 < rel(on_img) / rel(pt_img) < 2.0, (rel(on_img), rel(pt_img))
    off_img, _ = _images(frame, False, integrator="cmlt", mlt_paths="none")
    assert rel(on_img) < 0.25 * rel(off_img), (rel(on_img), rel(off_img))


def test_without_light_paths_the_chainless_frame_agrees_with_pt(frame):
    """The same estimator as pt's without the light paths (caustic_tracing off on both):
    the camera paths alone must give pt's mean too. (They did not: the chainless frame's
    pass left out the caustic paths as if chains rendered them — 2.3 % of this image,
    the caustic at 1.28 +- 0.17 against pt's 3.63 +- 0.49 over 32 seeds.)"""
    off_img, _ = _images(frame, False, integrator="cmlt", mlt_paths="none")
    pt_img, _ = _images(frame, False)
    a, b = off_img.mean(axis=1), pt_img.mean(axis=1)
    se = math.hypot(a.std(ddof=1), b.std(ddof=1)) / math.sqrt(SEEDS)
    assert abs(a.mean() - b.mean()) <= 4.5 * se, (a.mean(), b.mean(), se)
