"""PSSMLT against the path tracer on a small diffuse Cornell-like box built through
the Python scene API (cmlt.scene -> SceneBridge -> core).

MLT pixel errors are correlated (chains wander, b is shared by every pixel), so the
per-pixel variance of one render says little. Confidence intervals come instead from
K independent seeds: for each statistic the K renders give a mean and a standard error,
compared with a t-distribution (K-1 degrees of freedom). The PT reference has its own
standard error (its variance AOV; pixels are independent), added in quadrature.
"""
import math

import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Camera, FrameScene, Instance, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge
from support.scenes import RES, cornell_scene
from support.stats import ACESCG_Y, lum_se, t_critical
import support

pytestmark = pytest.mark.statistical

SEEDS = 12
MPP = 128          # mutations per pixel of each MLT run


@pytest.fixture(scope="module")
def scene():
    bridge = SceneBridge(core)
    s = bridge.update(cornell_scene())
    yield s


def _settings(integrator, spp, seed, **kw):
    st = core.RenderSettings()
    st.width = st.height = RES
    st.spp, st.seed, st.threads, st.max_depth = spp, seed, 2, 8
    st.integrator = integrator
    st.mlt_path_sampler = "pt"   # this file: PSSMLT over the path tracer (bdpt: test_pssmlt_bdpt.py)
    st.mlt_paths = "all"  # the chains on every path (auto: none on a diffuse scene)
    for k, v in kw.items():
        setattr(st, k, v)
    return st


@pytest.fixture(scope="module")
def reference(scene):
    r = core.render(scene, _settings("pt", 1024, 1000))
    return np.asarray(r.image, np.float64), np.asarray(r.variance, np.float64)


@pytest.fixture(scope="module")
def mlt_runs(scene):
    runs = []
    for seed in range(SEEDS):
        r = core.render(scene, _settings("pssmlt", MPP, seed, chains=128, bootstrap_samples=16384))
        runs.append((np.asarray(r.image, np.float64), dict(r.stats)))
    return runs


def test_01_t_quantile():
    # known values: t_{0.975, 5} = 2.5706, t_{0.995, 11} = 3.1058
    assert abs(t_critical(5, 0.05) - 2.5706) < 1e-3
    assert abs(t_critical(11, 0.01) - 3.1058) < 1e-3


def test_02_stats_and_finite(mlt_runs):
    for img, st in mlt_runs:
        assert np.isfinite(img).all() and (img >= 0).all()
        assert st["integrator"] == "pssmlt" and st["nan_samples"] == 0
        assert st["chains"] == 128 and st["bootstrap_samples"] == 16384
        # budget: pilot 1 spp + direct pass round(0.3 MPP) = 38 spp (depths 0, 1) +
        # bootstrap + chains
        assert st["importance"] == "pixel" and st["min_depth"] == 2
        assert st["pilot_evaluations"] == RES * RES and st["direct_evaluations"] == 38 * RES * RES
        assert st["mutations"] == RES * RES * (MPP - 39) - 16384
        assert st["path_evaluations"] == RES * RES * MPP
        assert 0 < st["acceptance"]["large_step"] < st["acceptance"]["small_step"] < 1
        assert st["max_rejection_streak"] < 500
    # every large step refines b: with ~1.4x the bootstrap's samples among the large steps
    # the merged standard error is ~0.65x the bootstrap's. Per run the sample standard
    # deviation of a heavy-tailed f* is itself noisy (one run measured 1.05x), so the
    # check is on the median over the seeds.
    ratios = [st["b_stderr"] / st["b_bootstrap_stderr"] for _, st in mlt_runs]
    assert np.median(ratios) < 0.85, ratios


def test_03_mean_brightness_within_1_percent(mlt_runs, reference):
    ref, ref_var = reference
    n = ref.shape[0] * ref.shape[1]
    ref_y = ref.reshape(-1, 3).mean(0) @ ACESCG_Y
    means = np.array([img.reshape(-1, 3).mean(0) @ ACESCG_Y for img, _ in mlt_runs])
    m, se = means.mean(), means.std(ddof=1) / math.sqrt(SEEDS)
    # SE of the luminance mean: R, G, B are correlated, so the channels-independent
    # sum underestimates it; Cauchy-Schwarz bound sum_c Y_c se_c (see _lum_se)
    ref_se = lum_se(ref_var)
    assert abs(m / ref_y - 1) < 0.01, (m, ref_y, se)
    # and within the t confidence interval (two-sided false-alarm rate 1e-3)
    t = t_critical(SEEDS - 1, 1e-3)
    assert abs(m - ref_y) < t * math.hypot(se, ref_se), (m, ref_y, se, ref_se)


def test_04_pixel_blocks_within_confidence_intervals(mlt_runs, reference):
    """4x4 blocks of 8x8 pixels, per channel: mean over seeds vs PT, t-test with 11 dof,
    Bonferroni over the 48 tests: family-wise false-alarm rate 1e-2."""
    ref, ref_var = reference
    B = 8
    nb = RES // B

    def blocks(a):
        return a.reshape(nb, B, nb, B, 3).mean((1, 3))

    runs = np.stack([blocks(img) for img, _ in mlt_runs])          # (K, nb, nb, 3)
    m = runs.mean(0)
    se = runs.std(0, ddof=1) / math.sqrt(SEEDS)
    ref_b = blocks(ref)
    ref_se = np.sqrt(ref_var.reshape(nb, B, nb, B, 3).sum((1, 3))) / (B * B)
    t = t_critical(SEEDS - 1, 1e-2 / runs[0].size)
    z = np.abs(m - ref_b) / np.hypot(se, ref_se)
    assert (z < t).all(), (z.max(), t, np.unravel_index(z.argmax(), z.shape))
    # the intervals are not vacuous: the block means are tight (median relative SE
    # < 3% on blocks brighter than a tenth of the mean) and a 20% error in a block is
    # flagged in most blocks
    bright = ref_b > 0.1 * ref_b.mean()
    rel = se[bright] / m[bright]
    assert np.median(rel) < 0.03 and rel.max() < 0.25, (np.median(rel), rel.max())
    z_wrong = np.abs(m - 1.2 * ref_b) / np.hypot(se, ref_se)
    assert (z_wrong > t).mean() > 0.5, (z_wrong > t).mean()


def test_05_bootstrap_b_is_the_mean_of_f_star(scene, reference):
    """With the luminance target and no direct pass, b = E[f*] over primary sample space
    = the mean pixel luminance of the PT image."""
    ref, ref_var = reference
    n = ref.shape[0] * ref.shape[1]
    ref_y = ref.reshape(-1, 3).mean(0) @ ACESCG_Y
    # SE of the luminance mean: R, G, B are correlated, so the channels-independent
    # sum underestimates it; Cauchy-Schwarz bound sum_c Y_c se_c (see _lum_se)
    ref_se = lum_se(ref_var)
    for seed in range(4):
        st = dict(core.render(scene, _settings("pssmlt", MPP, seed, chains=128, bootstrap_samples=16384,
                                               importance="luminance", direct_fraction=0)).stats)
        # 4.5 combined standard errors: false-alarm rate ~7e-6 per check
        assert abs(st["b_bootstrap"] - ref_y) < 4.5 * math.hypot(st["b_bootstrap_stderr"], ref_se)
        assert abs(st["b"] - ref_y) < 4.5 * math.hypot(st["b_stderr"], ref_se)
        assert st["b_stderr"] < 0.03 * st["b"]   # the check is not vacuous


def test_06_deterministic_with_1_and_2_threads(scene):
    a = core.render(scene, _settings("pssmlt", 8, 5, chains=64, bootstrap_samples=2048, threads=1))
    b = core.render(scene, _settings("pssmlt", 8, 5, chains=64, bootstrap_samples=2048, threads=2))
    assert np.array_equal(np.asarray(a.image), np.asarray(b.image))


def test_07_settings_reach_the_core(scene):
    st = _settings("pssmlt", 4, 1, sigma=0.05, large_step_probability=0.5, chains=16,
                   bootstrap_samples=1000)
    r = core.render(scene, st)
    assert r.stats["sigma"] == 0.05 and r.stats["large_step_probability"] == 0.5
    assert r.stats["chains"] == 16 and r.stats["bootstrap_samples"] == 1000
    with pytest.raises(core.SettingsError, match="large_step_probability"):
        core.render(scene, _settings("pssmlt", 4, 1, large_step_probability=2.0))


def test_08_cli_render_pssmlt(tmp_path):
    """`cmlt render --integrator pssmlt` with the Metropolis flags: the sidecar records
    the settings and the MLT stats; a bad flag value is a one-line usage error."""
    import json
    import os

    from cmlt.cli import main

    shot = str(support.SEQUENCES / "cornell" / "shot.usda")
    out = tmp_path / "mlt.####.exr"
    code = main(["render", shot, "--frames", "1", "--out", str(out), "--res", "16x12", "--spp", "8",
                 "--integrator", "pssmlt", "--sigma", "0.02", "--large-step-probability", "0.4",
                 "--chains", "16", "--bootstrap-samples", "256", "--threads", "2", "--quiet",
                 "--mlt-paths", "all"])
    assert code == 0
    doc = json.loads((tmp_path / "mlt.0001.exr.json").read_text())
    assert doc["settings"]["integrator"] == "pssmlt"
    assert doc["settings"]["sigma"] == 0.02 and doc["settings"]["chains"] == 16
    st = doc["stats"]
    assert st["integrator"] == "pssmlt" and st["chains"] == 16 and st["bootstrap_samples"] == 256
    assert st["large_step_probability"] == 0.4 and st["sigma"] == 0.02
    # 8 evaluations per pixel: pilot 1, direct pass round(0.3 x 8) = 2, bootstrap 256
    assert st["mutations"] == 16 * 12 * (8 - 1 - 2) - 256
    assert set(st["acceptance"]) == {"small_step", "large_step"}
    assert "max_rejection_streak" in st and st["b"] > 0
    assert main(["render", shot, "--out", str(out), "--integrator", "pssmlt",
                 "--large-step-probability", "1.5", "--quiet"]) == 2
