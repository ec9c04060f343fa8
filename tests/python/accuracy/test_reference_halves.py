"""References made of two independent halves (cmlt.accuracy.render_reference): the
floor from the halves' difference (halves_floor) agrees with the per-pixel variance's
where the image is well behaved, and the reference warns when a few pixels' rare bright
paths make the halves differ by far more than their variance says.

halves_floor is checked on synthetic Gaussian noise (its expectation is the mean's
relMSE; over 3 x 64 x 64 terms its spread is a few percent: the bound 10 % is > 5
standard errors). On the Cornell box (pt, 16x16, 256 spp) the two floors of one
reference are of one size, 0.25-2x (measured: halves 0.41x the variance's — the default
Sobol points, whose per-pixel spread reads the error of independent samples, 1.4-1.7x
too high, README "Pixel samples"); a cached reference keeps both."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

from cmlt.accuracy import ShotFrame
from cmlt.accuracy.render import HALVES_WARN_RATIO, Reference, halves_floor, render_reference

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
CORNELL = os.path.join(ROOT, "sequences", "cornell", "shot.usda")


def test_halves_floor_is_the_means_relmse():
    rng = np.random.default_rng(3)
    r = rng.uniform(0.2, 2.0, (64, 64, 3))
    sigma = 0.01 * r
    a = r + rng.normal(0.0, 1.0, r.shape) * sigma
    b = r + rng.normal(0.0, 1.0, r.shape) * sigma
    want = float(np.mean((sigma * sigma / 2.0) / (r * r + 1e-2)))   # Var((A + B) / 2) / (R² + ε)
    assert halves_floor(a, b) == pytest.approx(want, rel=0.10)
    # five pixels one half caught a bright path in (8x the other half's value): far above
    # what the rest of the image says
    b2 = b.copy()
    b2[5, 7:12] *= 8.0
    assert halves_floor(a, b2) > 10 * want


def test_reference_warns_only_when_the_halves_disagree():
    ref = Reference(np.zeros((2, 2, 3)), "", relmse_floor_variance=1e-4, relmse_floor_halves=2e-4)
    assert ref.warning() is None
    ref.relmse_floor_halves = (HALVES_WARN_RATIO + 1.0) * 1e-4
    w = ref.warning()
    assert w and "halves differ" in w and "--reference-spp" in w and "\n" not in w
    assert Reference(np.zeros((2, 2, 3)), "").warning() is None   # no floors: nothing to say


def test_cornell_reference_floors_agree_and_are_cached(tmp_path):
    sf = ShotFrame(CORNELL, resolution=(16, 16), threads=2)
    ref = render_reference(sf, "pt", 256, cache_dir=str(tmp_path), seed=5)
    v, h = ref.relmse_floor_variance, ref.relmse_floor_halves
    assert math.isfinite(v) and math.isfinite(h) and v > 0
    assert 0.25 < h / v < 2.0, (v, h)
    assert ref.relmse_floor == max(v, h) and ref.warning() is None
    again = render_reference(sf, "pt", 256, cache_dir=str(tmp_path), seed=5)
    assert again.cached and np.array_equal(again.image.astype(np.float32), ref.image.astype(np.float32))
    assert again.relmse_floor_halves == pytest.approx(h) and again.relmse_floor_variance == pytest.approx(v)
    # the mean of the two halves (seeds 5 and 6 of 128 passes each)
    from cmlt.accuracy import parse_integrator
    spec = parse_integrator("pt", sf.core)
    a = sf.render(spec, spp=128, seed=5).image
    b = sf.render(spec, spp=128, seed=6).image
    np.testing.assert_allclose(ref.image, 0.5 * (a + b), rtol=1e-12)
