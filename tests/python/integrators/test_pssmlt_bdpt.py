"""Multiplexed PSSMLT over BDPT (pssmlt's default path sampler) against BDPT, on the
Cornell-like box of test_pssmlt.py (support/scenes.py) and on a glass caustic (smooth glass sphere on a diffuse
floor, small sphere light), both built through the Python scene API.

Confidence intervals come from K independent seeds (MLT pixel errors are correlated
within a render): per statistic the K renders give a mean and a standard error, compared
with Student's t (K-1 dof); the BDPT reference's own standard error (its variance AOV:
independent passes) is added in quadrature. False-alarm rates: mean brightness 1e-3 per
scene; block test family-wise 1e-2 per scene (Bonferroni over its 48 tests); so about
2e-2 for the file.

The 1% criterion on the mean is checked on the Cornell box. On the caustic scene the
multiplexed f* is heavy-tailed (relative std per large-step sample ~37: light seen
directly and through the glass, small light), so b alone has a relative SE of ~37/sqrt(N)
for N bootstrap + large-step samples; 1% at a false-alarm rate of 1e-3 would take ~1e8
samples, far beyond this file's budget: there the test is the t-interval only (which
does detect a bias of the size of the interval, ~4%). Deterministic keys: each check either always passes or always fails.
Also: no NaN, no stuck chain on the caustic scene (bounded longest rejection run and
fraction of steps in runs > 1000), bit-identical over thread counts, chain-state export
and import.
"""
import math

import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge

from support.scenes import MAX_DEPTH, RES, caustic_scene, cornell_scene
from support.stats import ACESCG_Y, lum_se, t_critical

pytestmark = pytest.mark.statistical

SEEDS = 10
CASES = {  # scene -> (mutations per pixel, BDPT reference spp)
    "cornell": (384, 1024),
    "caustic": (256, 1024),
}
TOL_MEAN = {"cornell": 0.01, "caustic": None}   # see the module docstring


SCENES = {"cornell": cornell_scene, "caustic": caustic_scene}


@pytest.fixture(scope="module")
def scenes():
    out = {}
    for name, make in SCENES.items():
        bridge = SceneBridge(core)
        out[name] = (bridge, bridge.update(make()))
    return out


def _settings(integrator, spp, seed, threads=2, **kw):
    st = core.RenderSettings()
    st.width = st.height = RES
    st.spp, st.seed, st.threads, st.max_depth = spp, seed, threads, MAX_DEPTH
    st.integrator = integrator
    st.chains, st.bootstrap_samples = 256, 32768
    st.mlt_paths = "all"  # the chains on every path (caustic paths only: test_mlt_paths.py)
    for k, v in kw.items():
        setattr(st, k, v)
    return st


@pytest.fixture(scope="module")
def runs(scenes):
    """name -> (reference image, reference variance, [(image, stats)] over SEEDS seeds)."""
    out = {}
    for name, (_, scene) in scenes.items():
        mpp, ref_spp = CASES[name]
        r = core.render(scene, _settings("bdpt", ref_spp, 1000))
        ref = np.asarray(r.image, np.float64), np.asarray(r.variance, np.float64)
        mlt = []
        for seed in range(SEEDS):
            r = core.render(scene, _settings("pssmlt", mpp, seed))
            mlt.append((np.asarray(r.image, np.float64), dict(r.stats)))
        out[name] = (ref[0], ref[1], mlt)
    return out


@pytest.mark.parametrize("name", list(SCENES))
def test_01_finite_and_stats(runs, name):
    _, _, mlt = runs[name]
    for img, st in mlt:
        assert np.isfinite(img).all() and (img >= 0).all()
        assert st["integrator"] == "pssmlt" and st["path_sampler"] == "bdpt"
        assert st["nan_samples"] == 0
        assert 0 < st["acceptance"]["large_step"] < st["acceptance"]["small_step"] < 1


@pytest.mark.parametrize("name", list(SCENES))
def test_02_mean_brightness_within_1_percent(runs, name):
    ref, ref_var, mlt = runs[name]
    n = ref.shape[0] * ref.shape[1]
    ref_y = ref.reshape(-1, 3).mean(0) @ ACESCG_Y
    # SE of the luminance mean: R, G, B are correlated, so the channels-independent
    # sum underestimates it; Cauchy-Schwarz bound sum_c Y_c se_c (see _lum_se)
    ref_se = lum_se(ref_var)
    means = np.array([img.reshape(-1, 3).mean(0) @ ACESCG_Y for img, _ in mlt])
    m, se = means.mean(), means.std(ddof=1) / math.sqrt(SEEDS)
    print(f"{name}: mean Y {m:.5f} +- {se:.5f}, BDPT {ref_y:.5f} +- {ref_se:.5f}, "
          f"ratio {m / ref_y:.4f}")
    if TOL_MEAN[name] is not None:
        assert abs(m / ref_y - 1) < TOL_MEAN[name], (m, ref_y, se)
    t = t_critical(SEEDS - 1, 1e-3)
    assert abs(m - ref_y) < t * math.hypot(se, ref_se), (m, ref_y, se, ref_se)


@pytest.mark.parametrize("name", list(SCENES))
def test_03_pixel_blocks_within_confidence_intervals(runs, name):
    """4x4 blocks of 8x8 pixels per channel: mean over seeds vs BDPT, t-test with K-1
    dof, Bonferroni over the 48 tests: family-wise false-alarm rate 1e-2. Black blocks
    (nothing visible: both means and SEs 0) count as agreeing."""
    ref, ref_var, mlt = runs[name]
    B = 8
    nb = RES // B

    def blocks(a):
        return a.reshape(nb, B, nb, B, 3).mean((1, 3))

    runs_b = np.stack([blocks(img) for img, _ in mlt])
    m = runs_b.mean(0)
    se = runs_b.std(0, ddof=1) / math.sqrt(SEEDS)
    ref_b = blocks(ref)
    ref_se = np.sqrt(ref_var.reshape(nb, B, nb, B, 3).sum((1, 3))) / (B * B)
    t = t_critical(SEEDS - 1, 1e-2 / runs_b[0].size)
    den = np.hypot(se, ref_se)
    black = (den == 0) & (m == ref_b)
    z = np.where(black, 0.0, np.abs(m - ref_b) / np.where(den > 0, den, 1e-300))
    bright = ref_b > 0.1 * ref_b.mean()
    print(f"{name}: max z {z.max():.2f} (critical {t:.2f}), median rel. SE "
          f"{np.median(se[bright] / m[bright]):.4f}")
    assert (z < t).all(), (z.max(), t, np.unravel_index(z.argmax(), z.shape))
    # not vacuous (Cornell box; on the caustic scene the block SEs are ~11% at this
    # budget, for the reason given in the module docstring): a 30% error in a block is
    # flagged in most bright blocks
    if name != "cornell":
        return
    z_wrong = np.abs(m - 1.3 * ref_b) / np.where(den > 0, den, 1e-300)
    assert (z_wrong[bright] > t).mean() > 0.5, (z_wrong[bright] > t).mean()


def test_04_no_stuck_chain_on_the_caustic(runs):
    """Longest rejection run of any chain and the fraction of all steps that were
    rejections inside runs longer than 1000 (MltStats.long_streak_rejections)."""
    _, _, mlt = runs["caustic"]
    streak = max(st["max_rejection_streak"] for _, st in mlt)
    frac = sum(st["long_streak_rejections"] for _, st in mlt) / sum(st["mutations"] for _, st in mlt)
    print(f"caustic: max rejection streak {streak}, fraction in runs > 1000: {frac:.2e}")
    assert streak < 2000, streak
    assert frac < 1e-2, frac
    # issue 4's measure: the share of all steps spent in the most-occupied 0.1% of the
    # states visited (a state is occupied for 1 + its rejections). Healthy chains give
    # ~1-2% here (geometric run lengths); a tenth of the chains stuck for their whole
    # budget would put ~9% of the steps there.
    top = [st["top_occupancy"] for _, st in mlt]
    print(f"caustic: steps in the most-occupied 0.1% of states: max {max(top):.4f}")
    assert all(st["states_visited"] > 1000 for _, st in mlt)
    assert max(top) < 0.05, top


def test_05_deterministic_over_thread_counts(scenes):
    _, scene = scenes["caustic"]
    a = core.render(scene, _settings("pssmlt", 16, 7, threads=1))
    b = core.render(scene, _settings("pssmlt", 16, 7, threads=2))
    assert np.array_equal(np.asarray(a.image), np.asarray(b.image))
    assert a.stats["b"] == b.stats["b"]
    assert a.mlt_states.to_bytes() == b.mlt_states.to_bytes()


def test_06_chain_states_export_import(scenes):
    _, scene = scenes["cornell"]
    # luminance target: f* is the luminance of the chain's colour (pixel importance: times
    # the pixel's weight)
    a = core.render(scene, _settings("pssmlt", 16, 3, importance="luminance"))
    states = a.mlt_states
    assert len(states) == 256 and states.path_sampler == "bdpt"
    c = states.chain(5)
    assert c["chain_id"] == 5 and len(c["u"]) == 3
    assert c["s"] + c["t"] == c["depth"] + 2 and 0 <= c["depth"] <= MAX_DEPTH
    assert c["f_star"] == pytest.approx(np.dot(c["colour"], ACESCG_Y), rel=1e-5)
    blob = states.to_bytes()
    back = core.MltStates.from_bytes(blob)
    assert back.to_bytes() == blob
    with pytest.raises(ValueError):
        core.MltStates.from_bytes(blob[:-3])
    # start a render from the states: one chain per state, ids carried over
    st = _settings("pssmlt", 16, 4, mlt_initial_states=back)
    r = core.render(scene, st)
    assert r.stats["imported_chains"] == 256 and r.stats["chains"] == 256
    assert np.isfinite(np.asarray(r.image)).all()
    assert r.mlt_states.chain(5)["chain_id"] == 5
    # the wrong layout is refused
    with pytest.raises(Exception, match="path sampler"):
        core.render(scene, _settings("pssmlt", 16, 4, mlt_initial_states=back, mlt_path_sampler="pt"))
    # settings field round trip
    assert st.mlt_initial_states is not None
    st.mlt_initial_states = None
    assert st.mlt_initial_states is None


def test_07_imported_states_reproduce_their_f_star(scenes):
    """Import with no mutation budget beyond the starts: the re-evaluated states in the
    same scene have exactly the exported f* (u is the whole state)."""
    _, scene = scenes["caustic"]
    # one pilot for both renders (it is keyed by the seed, and f* depends on it)
    pilot = core.render_pilot(scene, _settings("pssmlt", 16, 5))
    a = core.render(scene, _settings("pssmlt", 16, 5, chains=64, pilot=pilot))
    st = _settings("pssmlt", 16, 6, mlt_initial_states=a.mlt_states, large_step_probability=0.0,
                   sigma=1e-9, pilot=pilot)
    r = core.render(scene, st)
    # sigma ~ 0 small steps keep every path (up to 1e-9 moves): f* unchanged per chain
    for i in range(64):
        ca, cb = a.mlt_states.chain(i), r.mlt_states.chain(i)
        assert (ca["depth"], ca["s"], ca["t"]) == (cb["depth"], cb["s"], cb["t"])
        assert cb["f_star"] == pytest.approx(ca["f_star"], rel=1e-3, abs=1e-9)


def test_08_pt_sampler_still_available(scenes):
    _, scene = scenes["cornell"]
    r = core.render(scene, _settings("pssmlt", 8, 1, mlt_path_sampler="pt"))
    assert r.stats["path_sampler"] == "pt" and np.isfinite(np.asarray(r.image)).all()
    with pytest.raises(Exception, match="mlt_path_sampler"):
        core.render(scene, _settings("pssmlt", 8, 1, mlt_path_sampler="mmlt"))
