"""The stopping rule of a render with a target error (an upper confidence bound on the
expected relMSE, cmlt.metrics.error_estimate.upper_bound and its core twin), the chain
groups made of disjoint start samples, and the live estimate (core.render's
on_estimate, render_sequence's, the progress log's frame_estimate events)."""
from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

from cmlt.accuracy import ShotFrame, estimate_from_groups, parse_integrator
from cmlt.cli import main
from cmlt.metrics.error_estimate import chi2_lower_quantile, target_reached, upper_bound

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")


@pytest.fixture(scope="module")
def cornell():
    return ShotFrame(CORNELL, resolution=(24, 24), threads=2)


@pytest.mark.parametrize("nu,exact", [(7, 2.16735), (15, 7.26094), (31, 19.2806), (100, 77.9295)])
def test_chi2_quantile_matches_the_table(nu, exact):
    """Wilson-Hilferty's 5 % quantile against the tabulated chi-square quantiles."""
    assert chi2_lower_quantile(nu) == pytest.approx(exact, rel=0.01)


def test_bound_edges():
    assert upper_bound(0.01, 0.0) == 0.01
    assert math.isinf(upper_bound(0.01, math.nan))
    assert math.isinf(upper_bound(0.01, 0.02))           # nu = 0.5: no bound
    assert 0.01 < upper_bound(0.01, 0.001) < upper_bound(0.01, 0.002)


def test_bound_false_alarm_rate_on_gaussian_groups():
    """Synthetic renders whose expected relMSE is the target: the bound falls below the
    target (a false stop) in about 5 % of them. 400 trials of 8 Gaussian groups on a
    16x16 image with a few bright pixels (so the estimate has few degrees of freedom);
    asserted <= 10 %: with a true rate of 5 % that fails with probability ~1e-5
    (binomial tail), with a true rate of 20 % it passes with ~1e-11."""
    rng = np.random.default_rng(3)
    R = np.exp(rng.normal(-1.0, 1.0, (16, 16, 3)))
    sd = 0.05 * R + 0.01
    sd[:2, :2] *= 12.0                                     # a handful of noisy pixels
    G = 8
    expected = float(np.mean(sd ** 2 / G / (R ** 2 + 1e-2)))
    stops = 0
    for _ in range(400):
        Y = R + sd * rng.standard_normal((G,) + R.shape)
        e = estimate_from_groups(Y, keep_pixels=False)
        stops += upper_bound(e.relmse, e.stderr) <= expected
    assert stops / 400 <= 0.10, stops


@pytest.mark.parametrize("integrator", ["pt", "cmlt:bootstrap_samples=4000:chains=96"])
def test_core_stops_at_the_bound_and_reports_each_estimate(cornell, integrator):
    """The core stops at the first check past the minimum that target_reached accepts
    (the Python twin says the same of every check), and on_estimate saw every check."""
    spec = parse_integrator(integrator, cornell.core)
    st = cornell.settings(spec, None, 1 << 16, 0)
    target = 0.02 if integrator == "pt" else 0.05
    st.target_error = target
    seen = []
    r = cornell.core.render(cornell.scene, st, on_estimate=lambda *a: seen.append(a))
    s = dict(r.stats)
    hist = s["error_history"]
    assert s["stop_reason"] == "target"
    assert [tuple(h[:3]) for h in hist] == [tuple(a) for a in seen]
    assert target_reached(hist[-1][2], hist[-1][3], target)
    minimum = 32 if integrator == "pt" else None    # cmlt's minimum is in rounds
    for h in hist[:-1]:
        if minimum is not None and h[0] >= minimum:
            assert not target_reached(h[2], h[3], target), h


def test_on_estimate_must_be_callable(cornell):
    st = cornell.settings(parse_integrator("pt", cornell.core), None, 16, 0)
    with pytest.raises(TypeError, match="on_estimate"):
        cornell.core.render(cornell.scene, st, on_estimate=3)


def test_an_error_in_on_estimate_reaches_the_caller(cornell):
    st = cornell.settings(parse_integrator("pt", cornell.core), None, 1 << 12, 0)
    st.target_error = 1e-6

    def boom(*_):
        raise RuntimeError("estimate callback failed")
    with pytest.raises(RuntimeError, match="estimate callback failed"):
        cornell.core.render(cornell.scene, st, on_estimate=boom)


def test_groups_are_disjoint_start_samples(cornell):
    """Chains resampled from the same bootstrap sample share a group: each start sample's
    chains carry one group (the chains' start states say which sample they came from:
    equal start states), the groups' weights are their steps, and the image is the
    same as with the default grouping would give (the layers add up exactly)."""
    core = cornell.core
    st = cornell.settings(parse_integrator("cmlt:bootstrap_samples=2000:chains=64:mlt_paths=all", core), None, 32, 1)
    r = core.render(cornell.scene, st)
    groups = np.asarray(r.group_images)
    assert groups.shape[0] >= 3 and len(r.group_weights) == groups.shape[0]
    w = np.asarray(r.group_weights, np.float64)
    direct = np.asarray(r.direct, np.float64)
    # the weighted mean of the groups is the image (every group holds the direct pass)
    mean = (w[:, None, None, None] * (groups - direct)).sum(0) / w.sum() + direct
    np.testing.assert_allclose(mean, np.asarray(r.image), rtol=2e-4, atol=1e-6)


def test_render_sequence_on_estimate_and_the_log(tiny_shot, tmp_path, capsys):
    from cmlt.shot.options import RenderOptions
    from cmlt.shot.sequence import render_sequence

    seen = []
    opts = RenderOptions(integrator="pt", spp=4096, threads=2, resolution=(24, 16),
                         target_error=0.05)
    res = render_sequence(tiny_shot, "1", str(tmp_path / "s.####.exr"), opts, quiet=True,
                          on_estimate=lambda *a: seen.append(a))
    assert res.written and seen
    side = json.load(open(str(tmp_path / "s.0001.exr") + ".json"))
    hist = side["stats"]["error_history"]
    assert [tuple(h[:3]) for h in hist] == [tuple(a) for a in seen]
    # the progress log (--log-json): one frame_estimate event per estimate
    out = tmp_path / "l.####.exr"
    assert main(["render", tiny_shot, "--spp", "4096", "--threads", "2", "--res", "24x16",
                 "--integrator", "pt", "--target-error", "0.05", "--log-json",
                 "--out", str(out), "--frames", "1"]) == 0
    events = [json.loads(l) for l in capsys.readouterr().out.splitlines() if l.startswith("{")]
    est = [e for e in events if e.get("event") == "frame_estimate"]
    side = json.load(open(str(tmp_path / "l.0001.exr") + ".json"))
    assert len(est) == len(side["stats"]["error_history"]) >= 1
    assert est[-1]["relmse"] == pytest.approx(side["stats"]["error_history"][-1][2])
