"""Every stage of sequences/hard/ with pt, bdpt, pssmlt and cmlt at a small budget,
against its converged reference (sequences/hard/make_references.py, cached in
renders/hard/refs/). Per case and integrator, K renders with independent seeds:

* finite: every pixel of every render is finite and no sample was NaN or Inf;
* bounded: no pixel's luminance exceeds 1000x the reference's brightest pixel (an
  all-black case: every pixel is exactly 0);
* mean: the mean over the K renders of the image-mean luminance lies in the
  t-interval of the reference (Welch: the two standard errors in quadrature,
  Welch-Satterthwaite degrees of freedom), two-sided alpha = 1e-4;
* no outlier render: each render's image mean lies in the prediction interval the
  other K - 1 renders give it (externally studentised residual, t with K - 2 degrees
  of freedom, alpha = 1e-4 / K per render): a frame many times too bright fails here
  even when the K-render mean hides it;
* no stuck chain (pssmlt, cmlt): the frame's statistics count no stuck chain
  (stuck_chains: a chain whose share of the chains' splat luminance exceeds 100x the
  fair share 1/chains, or that rejected 1000 proposals in a row), and no chain holds
  more than 5 % of the chains' image (max_chain_share).

False alarms: each statistical check is exact for normal means; with (14 cases x 4
integrators + 5 x 2 camera variants) x 2 checks at alpha = 1e-4 a correct renderer fails
one with probability about 1.3 % (for a given set of seeds the outcome is deterministic). Renders use fixed
seeds 1..K (references 1001..), so make test is reproducible.

The stages with glass or mirrors run pssmlt and cmlt a second time with the chains on
every path (`--mlt-paths all`) and the camera technique at q = 0.5 (`--camera-technique
0.5`, ids "pssmlt+camera", "cmlt+camera"; src/core/integrators/mlt/technique.h; auto
leaves it off with the chains on every path): the same checks, and the sidecar must say
the technique was on. The plain ids run the defaults: the chains render the caustic paths
of the stages with glass or mirrors and none elsewhere (`--mlt-paths auto`), with the
camera technique on auto (q = 0.7 where a material can be near-specular).

Cases that fail today are marked xfail(strict=True) with the reason (XFAIL below):
they pass only when the cure lands, and then the marker must go.
"""
import importlib.util
import math
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))


def _load_refs():
    name = "cmlt_hard_references"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "sequences", "hard",
                                                                     "make_references.py"))
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


refs = _load_refs()
CASES = list(refs.CASES)
INTEGRATORS = ("pt", "bdpt", "pssmlt", "cmlt")
#: the chains on every path with the camera technique at 0.5: "<integrator>+camera" on the
#: stages with glass or mirrors
CAMERA = "+camera"
CAMERA_CASES = ("caustic_lsdse", "caustic_sds", "specular_only", "light_behind_glass", "bulb_room")
METROPOLIS = ("pssmlt", "cmlt", "pssmlt" + CAMERA, "cmlt" + CAMERA)
ALPHA = 1e-4
BOUND = 1000.0
MAX_CHAIN_SHARE = 0.05

#: (check, case, integrator) -> why it fails today; "*" matches every case / integrator
XFAIL = {
    ("outlier", "caustic_lsdse", "pt"):
        "the 2 cm light's sub-pixel image in the glass ball (E S S L: two refractions, "
        "kept at max_depth 2) is found only by camera rays: one sample of ~6e4 in one pixel "
        "(seed 7: image mean 3.50 against 2.34). 9 of seeds 1..400 (2.2 %) have such a "
        "render with the Sobol scrambles seeded by their hash; 3 of 1..144 when Philox "
        "seeded them (seed 6 among the test's), 1 of 144 with independent numbers. The cure "
        "is a connection to the light through the specular chain.",
    ("outlier", "caustic_lsdse", "bdpt"):
        "the same highlight, which bdpt too finds only by its camera subpaths hitting the "
        "light (s = 0: no light subpath or connection reaches the camera through the ball): "
        "seed 2, image mean 3.50 against 2.34; 4 of seeds 1..600 (0.7 %: seeds 2 and 471 as "
        "high as pt's, 177 and 281 with about twice the excess, not looked into) with the "
        "hashed scramble seeds; none of 1..8 when Philox seeded them.",
}
# Passing since pt traces caustics from the lights too (caustic_light_tracing.h): bulb_room's
# mean (0.7101 ± 0.0003 against 0.7113 ± 0.0006 at seeds 1..10; before, every render 2.8 %
# dark: pt could not find the bulb's caustics from the mirror and the slab) and
# caustic_lsdse's outlier render (seed 7: the caustic found by BSDF sampling into the 2 cm
# light through the ball, mean 3.45).
# Not marked, and close to the bound: pssmlt on bulb_room (the defaults) puts at most
# 3.7 % of the chains' image in one chain at seeds 1..10, but above 5 % in 2 of seeds
# 1..40 (seed 15 9.0 %, seed 20 5.2 %; cmlt at most 3.6 % over the 40;
# tests/bench/chain_share.py bulb_room --seeds 1:40): a small, peaked target for 1000
# chains, no stuck chain.


def _xfail(check, case, integrator):
    for key in ((check, case, integrator), (check, case, "*"), (check, "*", integrator)):
        if key in XFAIL:
            return pytest.mark.xfail(strict=True, reason=XFAIL[key])
    return None


def _params(check, integrators=INTEGRATORS + ("pssmlt" + CAMERA, "cmlt" + CAMERA)):
    out = []
    for case in CASES:
        for integ in integrators:
            if integ.endswith(CAMERA) and case not in CAMERA_CASES:
                continue
            mark = _xfail(check, case, integ)
            out.append(pytest.param(case, integ, id=f"{case}-{integ}",
                                    marks=[mark] if mark else []))
    return out


# --- statistics ----------------------------------------------------------------------

def _betacf_inc(a, b, x):
    """Regularised incomplete beta I_x(a, b) by Lentz's continued fraction."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    if x > (a + 1.0) / (a + b + 2.0):
        return 1.0 - _betacf_inc(b, a, 1.0 - x)
    log_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                 + a * math.log(x) + b * math.log1p(-x))
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 500):
        m2 = 2 * m
        for num in (m * (b - m) * x / ((a + m2 - 1.0) * (a + m2)),
                    -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return math.exp(log_front) * h / a


def t_quantile(p: float, dof: float) -> float:
    """The p-quantile (p > 0.5) of Student's t with ``dof`` degrees of freedom."""
    def upper(t):  # P(T > t) for t >= 0
        return 0.5 * _betacf_inc(dof / 2.0, 0.5, dof / (dof + t * t))
    lo, hi = 0.0, 1.0
    while upper(hi) > 1.0 - p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if upper(mid) > 1.0 - p else (lo, mid)
    return 0.5 * (lo + hi)


# --- renders -------------------------------------------------------------------------

_RENDERS = {}


def runs(case_name, integ):
    """The K test renders of a case: list of (luminance image, stats)."""
    key = (case_name, integ)
    if key not in _RENDERS:
        from cmlt.shot.bridge import SceneBridge
        case = refs.CASES[case_name]
        core, fs = refs.load(case)
        scene = SceneBridge(core).update(fs)
        out = []
        for seed in range(1, case.test_seeds + 1):
            if integ.endswith(CAMERA):
                img, stats, _ = refs.render(case, integ[:-len(CAMERA)], case.test_spp, seed, fs=fs,
                                            scene=scene, mlt_camera_technique=0.5, mlt_paths="all")
                assert stats["camera_technique"] == 0.5, f"{case_name}/{integ}: the technique is off"
            else:
                img, stats, _ = refs.render(case, integ, case.test_spp, seed, fs=fs, scene=scene)
            out.append((img @ refs.Y, img, stats))
        _RENDERS[key] = out
    return _RENDERS[key]


@pytest.fixture(scope="session")
def reference():
    cache = {}

    def get(case_name):
        if case_name not in cache:
            cache[case_name] = refs.make_reference(refs.CASES[case_name])
        return cache[case_name]
    return get


# --- checks --------------------------------------------------------------------------

pytestmark = pytest.mark.statistical


@pytest.mark.parametrize("case,integ", _params("finite"))
def test01_finite(case, integ):
    for lum, img, stats in runs(case, integ):
        bad = ~np.isfinite(img)
        assert not bad.any(), f"{case}/{integ}: {int(bad.sum())} non-finite values, first at " \
                              f"{np.argwhere(bad)[0].tolist()}"
        assert stats["nan_samples"] == 0, f"{case}/{integ}: {stats['nan_samples']} NaN/Inf samples"


@pytest.mark.parametrize("case,integ", _params("bounded"))
def test02_no_pixel_above_the_bound(case, integ, reference):
    ref = reference(case)
    c = refs.CASES[case]
    for seed, (lum, img, stats) in enumerate(runs(case, integ), start=1):
        if c.black:
            assert np.count_nonzero(img) == 0, f"{case}/{integ} seed {seed}: not black " \
                                               f"(max {img.max():.3g})"
            if "b" in stats:
                assert stats["b"] == 0.0
            continue
        top = float(lum.max())
        y, x = np.unravel_index(int(np.argmax(lum)), lum.shape)
        assert top <= BOUND * ref.max, (f"{case}/{integ} seed {seed}: pixel ({x}, {y}) = {top:.4g}, "
                                        f"above {BOUND:g} x the reference's max {ref.max:.4g}")


def _means(case, integ):
    return np.array([float(lum.mean()) for lum, _, _ in runs(case, integ)])


@pytest.mark.parametrize("case,integ", _params("mean"))
def test03_mean_within_the_reference_interval(case, integ, reference):
    ref = reference(case)
    m = _means(case, integ)
    k = len(m)
    if refs.CASES[case].black:
        assert np.all(m == 0.0)
        return
    v_test, v_ref = m.var(ddof=1) / k, ref.se ** 2
    se = math.sqrt(v_test + v_ref)
    assert se > 0, f"{case}/{integ}: no spread at all over {k} seeds and in the reference"
    dof = se ** 4 / ((v_test ** 2 / (k - 1) if v_test > 0 else 0.0)
                     + (v_ref ** 2 / ref.dof if v_ref > 0 else 0.0))
    t = t_quantile(1.0 - ALPHA / 2.0, dof)
    d = float(m.mean()) - ref.mean
    assert abs(d) <= t * se, (f"{case}/{integ}: mean {m.mean():.5g} over {k} seeds vs reference "
                              f"{ref.mean:.5g} ± {ref.se:.3g}: off by {d / se:+.2f} standard errors "
                              f"(bound {t:.2f}); seeds {np.round(m, 5).tolist()}")


@pytest.mark.parametrize("case,integ", _params("outlier"))
def test04_no_render_is_an_outlier(case, integ):
    m = _means(case, integ)
    k = len(m)
    if refs.CASES[case].black:
        assert np.all(m == 0.0)
        return
    t = t_quantile(1.0 - ALPHA / (2.0 * k), k - 2)
    for i in range(k):
        rest = np.delete(m, i)
        s = float(rest.std(ddof=1))
        scale = s * math.sqrt(1.0 + 1.0 / (k - 1))
        d = float(m[i] - rest.mean())
        floor = 1e-9 * max(abs(float(rest.mean())), 1e-30)
        assert abs(d) <= t * max(scale, floor), (
            f"{case}/{integ} seed {i + 1}: image mean {m[i]:.5g}, the other {k - 1} renders "
            f"{rest.mean():.5g} ± {s:.3g} (sd): {d / max(scale, floor):+.1f} prediction sd, bound {t:.1f}")


@pytest.mark.parametrize("case,integ", _params("stuck", METROPOLIS))
def test05_no_stuck_chain(case, integ):
    for seed, (lum, img, stats) in enumerate(runs(case, integ), start=1):
        assert "max_chain_share" in stats and "stuck_chains" in stats, \
            f"{case}/{integ}: the frame statistics report no stuck_chains / max_chain_share"
        assert stats["stuck_chains"] == 0 and stats["max_chain_share"] <= MAX_CHAIN_SHARE, (
            f"{case}/{integ} seed {seed}: {stats['stuck_chains']} stuck chains of {stats['chains']}, "
            f"one chain holds {stats['max_chain_share']:.2%} of the chains' image "
            f"({stats['max_chain_share'] * stats['chains']:.0f}x the fair share), longest "
            f"rejection run {stats['max_rejection_streak']}")
