"""relMSE of pt on the Cornell box falls as 1/samples: the log-log slope of error against
budget is within [-1.2, -0.8].

Sample budgets, not time budgets, so nothing depends on the machine's speed (a time
budget buys samples in proportion, so the slope against time is the same up to the
cost per sample). The line goes through the mean relMSE of 6 seeds at each of 4 budgets
(8-64 spp, 64x64): a render's relMSE is heavy-tailed (the pixels at the light's edge
decide it), so the mean follows the expected error, c/n, while the typical (median)
error comes out flatter. Its standard error is the delete-one-seed jackknife of the
slope; the test requires it below 0.08 (then the band's edges are > 2.5 standard errors
from -1, a false-alarm rate < 1.2 % for an estimator that converges as 1/n under the
normal approximation). With these seeds: -0.99 +- 0.04 (edges at 5 standard errors). The
reference (pt, 1024 spp, 16x the largest budget) adds its own error c/1024 to every
measurement, which tilts the slope by +0.025 (c/n + c/1024 from n = 8 to 64).
"""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

from cmlt.accuracy import ShotFrame, fit, measure, parse_integrator, render_reference

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")
BUDGETS = (8, 16, 32, 64)
SEEDS = 6


def _slope(E):
    return fit(BUDGETS, E.mean(axis=0)).slope


@pytest.mark.slow
def test_pt_relmse_slope_on_the_cornell_box():
    sf = ShotFrame(CORNELL, resolution=(64, 64), threads=2)
    ref = render_reference(sf, "pt", 16 * BUDGETS[-1], cache_dir=None, seed=777)
    pt = parse_integrator("pt", sf.core)
    E = np.empty((SEEDS, len(BUDGETS)))
    for s in range(SEEDS):
        for j, n in enumerate(BUDGETS):
            run = sf.render(pt, spp=n, seed=s)
            # n passes; the paths traced also cover the gaussian's one-pixel ring
            assert run.stats["spp"] == n and run.samples == pytest.approx(n * 66 * 66 / 64 ** 2)
            E[s, j] = measure(run.image, ref.image)["relmse"]
    means = E.mean(axis=0)
    assert all(a > b for a, b in zip(means, means[1:])), means          # falls at every step
    k = _slope(E)
    loo = np.array([_slope(np.delete(E, i, axis=0)) for i in range(SEEDS)])
    se = math.sqrt((SEEDS - 1) / SEEDS * float(((loo - loo.mean()) ** 2).sum()))
    assert se < 0.08, (k, se, means)
    assert -1.2 <= k <= -0.8, (k, se, means)
