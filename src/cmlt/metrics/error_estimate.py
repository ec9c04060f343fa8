"""A render's estimate of its own relMSE, without a reference.

The error measure is the one ``cmlt accuracy`` measures against a reference::

    relMSE(I) = mean over pixels p and channels of (I_p - R_p)^2 / (R_p^2 + eps),  eps = 1e-2

Independent groups
------------------
A render that is the mean of G independent, unbiased group images Y_1..Y_G (group g from
n_g of the N samples: pt/bdpt sample passes, pssmlt/cmlt chains split into G groups, or
simply G renders with different seeds) has, per pixel and channel,

    I     = sum_g n_g Y_g / N                             the image
    v     = sum_g n_g (Y_g - I)^2 / ((G - 1) N)           unbiased for Var(I) = E[(I - R)^2]
    e_p   = v / D_p                                       the pixel's relMSE estimate
    E     = mean_p e_p                                    the image's

The numerator is unbiased. The denominator D_p must stand in for R_p^2 + eps with R
unknown, and no function of the groups does that without bias; ``denominator`` chooses:

* ``plug-in``: I^2 + eps. E[I^2] = R^2 + Var(I), and positively skewed noise (most samples
  small, a few large: rendering's) makes v and I large together, so a pixel's term is
  under-estimated exactly where its error is large; a pixel whose mean is one rare bright
  sample gets v ~ I^2 and e_p ~ 1 however wrong it is;
* ``corrected``: max(I^2 - v, 0) + eps, unbiased for R^2 + eps before the clamp; but its
  inverse is over-estimated (Jensen: 1/x is convex) by about 4 relMSE_p R^2 / (R^2 + eps)
  relative, and without bound where the pixel's own relative error is of order one (the
  clamp at 0 leaves eps): a pixel that caught a light's edge once in 16 samples;
* ``geometric``: sqrt(plug-in x corrected). The two biases have opposite signs where
  rendering noise lives and meet at the truth as the noise shrinks (both denominators ->
  R^2 + eps; first-order difference v); their geometric mean was the calibrated one in
  tests/bench/error_estimate.py (64x64 cornell, pt/bdpt/pssmlt/cmlt, 168 renders at 5
  budgets: 97 % within 0.67-1.5x of the measured relMSE, plug-in 93 %, corrected 67 %;
  caustic_glass bdpt: 85 %, 75 %, 55 %);
* ``guarded`` (the default): max(R', I / 4)^2 + eps, R' the pixel's mean without its
  largest and its smallest pass, block or group (``robust``, a trimmed mean; the core's
  films keep each pixel's largest and smallest pass or block: Film::develop). What the
  three above do not see is a render whose error is dominated by rare paths -- a
  firefly, a caustic path found once -- in pixels whose true value is far below the
  sample: I^2 - v keeps a cross term 2 R X / N for a single sample X, so their
  denominators stay far above R^2 + eps and the estimate is low (3-6x in the lit pixels
  of caustic_glass that a firefly lifts). Without its largest value the pixel's mean is
  its other samples', near R whatever the firefly; the smallest goes too, so that
  symmetric noise does not bias R' low (leaving out only the largest of 8 Gaussian groups
  read 5 % high); where one value holds all of a pixel's light (a caustic pixel sampled
  once) R' is 0 and would leave eps alone, so it may not fall below a quarter of I.
  tests/bench/results/accuracy/calibration_denominator.md: with the reference's own R
  in the denominator (what the numerator alone is worth) caustic_glass's renders are in
  0.67-1.5x in 72-76 % of renders where the geometric one gave 31-56 %; the guarded one
  47-56 % for pt, 80 % for cmlt's chain groups (geometric 60 %; on a second draw of
  seeds 55 % against 45 %), door_ajar 80-100 % (geometric 68-100 %); on the Cornell
  box's default renders it reads what their numerator says, the spread of one Sobol
  sequence's passes, about 1.5x.

Still not seen: paths no pass or group found (their error is in the numerator), a bias
common to all groups (MLT's start-up and normalisation bias at small budgets), and most
of a blob of stuck chains in one group (in its numerator, but the guard reads the pixel
as light one group found and caps its term at 16: the misses of cmlt on caustic_glass).

Uncertainty
-----------
``stderr`` of :func:`estimate_from_groups` is the delete-one-group jackknife of E (each
E_{-g} is the same estimator on the other G - 1 groups, scaled to the full N): it sees the
noise of the variance estimates, heavy tails included (a group holding the only firefly
of a pixel makes the E_{-g} differ a lot). It is the uncertainty of E as an estimate of
the *expected* relMSE; the relMSE of one image scatters around its expectation too.

Per-pass variance
-----------------
pt and bdpt already return the per-pixel variance of the mean (the film's Welford
accumulators over passes, which are independent images): that is ``v`` with groups of
one pass, so :func:`estimate_from_variance` needs no groups. Its uncertainty comes from
splitting the pixels into k x k interleaved (polyphase) sub-images, whose estimates are
nearly independent (pt pixels are; bdpt's light-tracing splats couple them a little)
and see nearly the same content: stderr = sd over the k^2 sub-estimates / k.

Chain groups in one render
--------------------------
pssmlt and cmlt with ``error_groups`` G >= 3 (8; 4 for a ``cmlt render`` frame without a
target error or group images): each chain splats into its group's film layer, the chains
resampled from one bootstrap sample in one group (copies of one start path are not
independent), so one render hands over up to G images of the frame (RenderResult.group_images, each
its chains' splats normalised by their own step count plus the direct pass; weights: the
step counts), whose weighted mean is the image. The core computes the same estimate
(src/core/integrators/common/error_target.h) between chain rounds, to stop at
``target_error``; the direct pass, identical in every group, adds its own per-pass
variance (``shared_var``).

A shared scale
--------------
pssmlt and cmlt multiply the chains' image by one normalisation b shared by every chain
group, so the groups do not see b's error. With b's relative variance ``scale_rel_var``
((b_stderr / b)^2) and the part of the image it scales (the chains' part: image minus the
direct pass), ``scale_rel_var * C_p^2`` is added to v per pixel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from .flicker import REL_MSE_EPS

__all__ = ["REL_MSE_EPS", "DENOMINATORS", "DEFAULT_DENOMINATOR", "ErrorEstimate",
           "estimate_from_groups", "estimate_from_variance", "pixel_terms", "estimate_render",
           "estimate_record", "estimate_metadata", "estimate_text", "VARIANCE_INTEGRATORS",
           "chi2_lower_quantile", "upper_bound", "target_reached", "TARGET_Z",
           "TARGET_TOLERANCE"]

@dataclass
class ErrorEstimate:
    """An image's relMSE estimate (``relmse``) with its standard error, and the per-pixel
    estimate (``pixel``: (H, W), the mean over the channels of e_p)."""

    relmse: float
    stderr: float
    groups: int
    method: str                      # 'groups' | 'variance'
    pixel: Optional[np.ndarray] = field(default=None, repr=False)
    extra: Dict[str, Any] = field(default_factory=dict)

    @property
    def rel_stderr(self) -> float:
        return self.stderr / self.relmse if self.relmse > 0 else math.inf

    def as_dict(self) -> Dict[str, Any]:
        """JSON-ready (no per-pixel array): what a sidecar records."""
        d = {"relmse": float(self.relmse), "stderr": float(self.stderr),
             "groups": int(self.groups), "method": self.method, "eps": REL_MSE_EPS}
        d.update(self.extra)
        return d

    def metadata(self) -> Dict[str, Any]:
        """``cmlt:*`` EXR header attributes (without the prefix)."""
        return {"relMSEEstimate": float(self.relmse), "relMSEEstimateStderr": float(self.stderr),
                "relMSEEstimateGroups": int(self.groups), "relMSEEstimateMethod": self.method}


#: the denominators (R^2 + eps estimates) :func:`pixel_terms` knows
DENOMINATORS = ("corrected", "plug-in", "geometric", "guarded")
#: the one renders use (the module docstring says why)
DEFAULT_DENOMINATOR = "guarded"
#: ``guarded``: the share of the mean below which the trimmed mean is not taken
#: (src/core/integrators/common/error_target.h k_robust_floor)
ROBUST_FLOOR = 0.25


def pixel_terms(image: np.ndarray, var: np.ndarray, eps: float = REL_MSE_EPS,
                scale_rel_var: float = 0.0, scaled: Optional[np.ndarray] = None,
                denominator: str = DEFAULT_DENOMINATOR,
                shared_var: Optional[np.ndarray] = None,
                robust: Optional[np.ndarray] = None) -> np.ndarray:
    """Per pixel and channel: e = v / D, v the variance of the mean (plus s C^2 with
    s = scale_rel_var, C = scaled, default the image, plus ``shared_var``) and D one of
    DENOMINATORS: ``corrected`` max(I^2 - v, 0) + eps, ``plug-in`` I^2 + eps,
    ``geometric`` the geometric mean of the two, ``guarded`` max(R', I / 4)^2 + eps with
    R' = ``robust`` (the mean without the pixel's largest and smallest pass, block or
    group; where it is NaN -- fewer than three -- or None, the geometric denominator)
    (the module docstring says why)."""
    image = np.asarray(image, np.float64)
    v = np.maximum(np.asarray(var, np.float64), 0.0)
    if shared_var is not None:
        v = v + np.maximum(np.asarray(shared_var, np.float64), 0.0)
    if scale_rel_var > 0.0:
        c = image if scaled is None else np.asarray(scaled, np.float64)
        v = v + float(scale_rel_var) * c * c
    i2 = image * image

    def geometric():
        return np.sqrt((i2 + eps) * (np.maximum(i2 - v, 0.0) + eps))
    if denominator == "corrected":
        d = np.maximum(i2 - v, 0.0) + eps
    elif denominator == "plug-in":
        d = i2 + eps
    elif denominator == "geometric" or (denominator == "guarded" and robust is None):
        d = geometric()
    elif denominator == "guarded":
        # in place (a frame's arrays are large); the geometric denominator where there is
        # no trimmed mean (NaN: fewer than three passes, blocks or groups)
        d = np.maximum(robust, ROBUST_FLOOR * image)
        np.multiply(d, d, out=d)
        d += eps
        none = np.isnan(d)
        if none.any():
            d[none] = geometric()[none]
    else:
        raise ValueError(f"denominator {denominator!r}: choose one of {', '.join(DENOMINATORS)}")
    return v / d


def _check_groups(groups, weights) -> tuple:
    Y = np.asarray(groups, dtype=np.float64)
    if Y.ndim != 4 or Y.shape[-1] != 3:
        raise ValueError(f"groups: expected (G, H, W, 3), got shape {Y.shape}")
    G = Y.shape[0]
    if G < 3:
        raise ValueError(f"groups: need at least 3 groups for a variance and its jackknife, got {G}")
    if not np.isfinite(Y).all():
        raise ValueError("groups: non-finite values")
    n = np.ones(G) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if n.shape != (G,) or not (n > 0).all():
        raise ValueError(f"weights: expected {G} positive sample counts, got {weights!r}")
    return Y, n


def _extremes(Y):
    """Per element of Y's image axes, the groups of the largest, second largest, smallest
    and second smallest value, scanned in group order with strict comparisons (the first
    of equal values first): the core's order (error_target.h estimate_from_groups)."""
    shape = Y.shape[1:]
    top, top2 = np.zeros(shape, np.intp), np.ones(shape, np.intp)
    bot, bot2 = np.zeros(shape, np.intp), np.ones(shape, np.intp)
    up, down = Y[1] > Y[0], Y[1] < Y[0]
    top[up], top2[up] = 1, 0
    bot[down], bot2[down] = 1, 0

    def at(idx):
        return np.take_along_axis(Y, idx[None], 0)[0]
    for g in range(2, Y.shape[0]):
        y = Y[g]
        a1, a2 = y > at(top), y > at(top2)
        top2 = np.where(a1, top, np.where(a2, g, top2))
        top = np.where(a1, g, top)
        b1, b2 = y < at(bot), y < at(bot2)
        bot2 = np.where(b1, bot, np.where(b2, g, bot2))
        bot = np.where(b1, g, bot)
    return top, top2, bot, bot2


def _trimmed(Y, n, S, N, t, b, count):
    """The weighted mean (sum S, weight N) without groups t and b (per element; the mean
    where t == b (all equal); NaN with fewer than three groups or no weight left)."""
    yt = np.take_along_axis(Y, t[None], 0)[0]
    yb = np.take_along_axis(Y, b[None], 0)[0]
    rest = N - n[t] - n[b]
    ok = (count > 2) & (rest > 0)
    out = np.where(t != b, (S - n[t] * yt - n[b] * yb) / np.where(ok & (t != b), rest, 1.0), S / N)
    return np.where(ok, out, np.nan)


def _moments(S1, S2, N, G):
    """Image and unbiased Var(image) from weighted sums S1 = sum n Y, S2 = sum n Y^2."""
    I = S1 / N
    ss = np.maximum(S2 - N * I * I, 0.0)        # sum n_g (Y_g - I)^2
    return I, ss / ((G - 1) * N)


def estimate_from_groups(groups, weights: Optional[Sequence[float]] = None,
                         eps: float = REL_MSE_EPS, scale_rel_var: float = 0.0,
                         scaled: Optional[np.ndarray] = None, keep_pixels: bool = True,
                         denominator: str = DEFAULT_DENOMINATOR,
                         shared_var: Optional[np.ndarray] = None) -> ErrorEstimate:
    """relMSE estimate of the mean of ``groups`` ((G, H, W, 3) independent unbiased images,
    group g from ``weights[g]`` samples; default equal) with its jackknife standard error.
    ``shared_var``: (H, W, 3) variance of a part every group shares (pssmlt/cmlt's direct
    pass), added to the groups' own."""
    Y, n = _check_groups(groups, weights)
    G = Y.shape[0]
    N = float(n.sum())
    w = n[:, None, None, None]
    S1 = (w * Y).sum(0)
    S2 = (w * Y * Y).sum(0)
    I, v = _moments(S1, S2, N, G)
    # the mean without the largest and the smallest group, per pixel and channel (the
    # guarded denominator's R'), and for the jackknife the next ones
    top, top2, bot, bot2 = _extremes(Y)
    robust = _trimmed(Y, n, S1, N, top, bot, G)
    e = pixel_terms(I, v, eps, scale_rel_var, scaled, denominator, shared_var, robust)
    E = float(e.mean())
    # delete-one-group jackknife: E_{-g} is the estimate of an image made of the other
    # G - 1 groups (its own variance in the numerator and in the denominator's
    # correction), scaled to the full sample count N
    loo = np.empty(G)
    for g in range(G):
        Ng = N - n[g]
        S1g = S1 - n[g] * Y[g]
        Ig, vg = _moments(S1g, S2 - n[g] * Y[g] * Y[g], Ng, G - 1)
        rg = _trimmed(Y, n, S1g, Ng, np.where(top == g, top2, top), np.where(bot == g, bot2, bot), G - 1)
        loo[g] = float(pixel_terms(Ig, vg, eps, scale_rel_var, scaled, denominator,
                                   shared_var, rg).mean()) * (Ng / N)
    se = float(math.sqrt((G - 1) / G * float(((loo - loo.mean()) ** 2).sum())))
    return ErrorEstimate(E, se, G, "groups", e.mean(axis=2) if keep_pixels else None,
                         {"denominator": denominator})


def estimate_from_variance(image, variance, eps: float = REL_MSE_EPS, passes: int = 0,
                           split: int = 4, keep_pixels: bool = True,
                           scale_rel_var: float = 0.0, scaled: Optional[np.ndarray] = None,
                           denominator: str = DEFAULT_DENOMINATOR,
                           robust: Optional[np.ndarray] = None) -> ErrorEstimate:
    """relMSE estimate of ``image`` from its per-pixel variance of the mean (pt, bdpt:
    RenderResult.variance), standard error from ``split`` x ``split`` interleaved
    sub-images. ``passes``: the sample passes behind the variance (recorded only).
    ``robust``: each pixel's mean without its largest and smallest pass or block
    (RenderResult.robust; NaN where fewer than three), the guarded denominator's R'
    (None: the geometric denominator everywhere)."""
    I = np.asarray(image, np.float64)
    V = np.asarray(variance, np.float64)
    if I.ndim != 3 or I.shape[-1] != 3 or V.shape != I.shape:
        raise ValueError(f"image and variance: expected two (H, W, 3) arrays, got {I.shape} "
                         f"and {V.shape}")
    if not (np.isfinite(I).all() and np.isfinite(V).all()):
        raise ValueError("image or variance: non-finite values")
    if robust is not None:
        robust = np.asarray(robust, np.float64)
        if robust.shape != I.shape or np.isinf(robust).any():
            raise ValueError(f"robust: expected an (H, W, 3) array like the image (finite, or NaN "
                             f"where there is no trimmed mean), got {robust.shape}")
    e = pixel_terms(I, V, eps, scale_rel_var, scaled, denominator, robust=robust)
    E = float(e.mean())
    H, W = I.shape[:2]
    k = max(1, min(int(split), H, W))
    subs = [float(e[i::k, j::k].mean()) for i in range(k) for j in range(k)]
    se = float(np.std(subs, ddof=1) / k) if len(subs) > 1 else math.nan
    return ErrorEstimate(E, se, int(passes), "variance", e.mean(axis=2) if keep_pixels else None,
                         {"denominator": denominator})


# ------------------------------------------------------------------ stopping at a target

#: the standard normal's 95 % quantile: the level of the target error's test
TARGET_Z = 1.6448536269514722
#: the bound's limit, in targets: a frame stops when its estimate is at most the target
#: and the 95 % upper bound at most this many targets (:func:`target_reached`)
TARGET_TOLERANCE = 1.5


def chi2_lower_quantile(nu: float, z: float = TARGET_Z) -> float:
    """The chi-square quantile with ``nu`` degrees of freedom at the standard normal
    quantile -z (Wilson-Hilferty: (chi2_nu / nu)^(1/3) is close to normal with mean
    1 - 2/(9 nu) and variance 2/(9 nu)); 0 where that leaves the positive axis."""
    if not nu > 0:
        return 0.0
    a = 2.0 / (9.0 * nu)
    c = 1.0 - a - z * math.sqrt(a)
    return nu * c ** 3 if c > 0 else 0.0


def upper_bound(relmse: float, stderr: float, z: float = TARGET_Z) -> float:
    """One-sided upper confidence bound (95 % at the default z) on the expected relMSE
    from an estimate and its standard error: the estimate modelled as a scaled
    chi-square variable, relMSE * chi2_nu / nu, with nu = 2 (relmse / stderr)^2
    (Satterthwaite: the same mean and variance). ``upper_bound(E, se) <= x`` is the
    test of "expected relMSE >= x" at level 5 % (:func:`target_reached`)."""
    if not (math.isfinite(relmse) and math.isfinite(stderr)):
        return math.inf
    if stderr <= 0:
        return relmse
    if relmse <= 0:
        return math.inf
    nu = 2.0 * (relmse / stderr) ** 2
    q = chi2_lower_quantile(nu, z)
    return relmse * nu / q if q > 0 else math.inf


def target_reached(relmse: float, stderr: float, target: float) -> bool:
    """The stopping rule of a render with a target error (past its minimum of work;
    src/core/integrators/common/error_target.h decides the same): the estimate at most
    the target and its 95 % upper bound at most TARGET_TOLERANCE targets, so a check
    stops a frame whose expected relMSE is beyond the tolerance with probability at
    most 5 % under the bound's model."""
    return relmse <= target and upper_bound(relmse, stderr) <= TARGET_TOLERANCE * target


# ------------------------------------------------------------------ a render's estimate

#: integrators whose RenderResult.variance is the per-pixel variance of the mean over
#: independent sample passes (estimate_from_variance applies)
VARIANCE_INTEGRATORS = ("pt", "bdpt")


def estimate_render(result, stats: Optional[Dict[str, Any]] = None,
                    keep_pixels: bool = False,
                    denominator: str = DEFAULT_DENOMINATOR) -> Tuple[Optional[ErrorEstimate], str]:
    """The relMSE estimate a finished ``core.render`` result allows, and how it was made
    (or why there is none).

    * ``result.group_images`` ((G, H, W, 3), each an unbiased image of the frame from a
      G-th of the work; ``result.group_weights`` their path evaluations): estimate_from_groups,
      with the shared-normalisation term of pssmlt/cmlt (b_stderr / b, on the chains'
      part: image minus ``result.direct``);
    * pt, bdpt, and pssmlt/cmlt without chains (``paths`` none, or ``direct_alone``: no
      chain started, the direct pass rendered the frame): estimate_from_variance
      on ``result.variance`` (the variance of the mean from independent passes, or from
      independent blocks of passes with ``sampler`` sobol-blocks; with one Sobol sequence,
      ``sobol``, it reads about what independent samples would have: conservative);
    * otherwise (pssmlt, cmlt without groups): None.
    """
    stats = dict(result.stats) if stats is None else stats
    integ = str(stats.get("integrator", ""))
    image = np.asarray(result.image, dtype=np.float64)
    groups = getattr(result, "group_images", None)
    if groups is not None:
        weights = getattr(result, "group_weights", None)
        b, b_se = stats.get("b"), stats.get("b_stderr")
        s = float(b_se) ** 2 / float(b) ** 2 if b and b_se else 0.0
        direct = getattr(result, "direct", None)
        chains = image if direct is None else image - np.asarray(direct, np.float64)
        # the direct pass is in every group image alike: its variance (RenderResult.variance)
        # is added to the groups' spread
        shared = None if direct is None else np.asarray(result.variance, np.float64)
        est = estimate_from_groups(np.asarray(groups), weights=weights, scale_rel_var=s,
                                   scaled=chains, keep_pixels=keep_pixels,
                                   denominator=denominator, shared_var=shared)
        return est, "groups"
    if integ in VARIANCE_INTEGRATORS or stats.get("paths") == "none" or stats.get("direct_alone"):
        # pt, bdpt, and pssmlt/cmlt without chains (mlt_paths none, or none started: the
        # direct pass's independent passes are the frame)
        passes = int(stats.get("spp", 0) or 0)
        if integ not in VARIANCE_INTEGRATORS and stats.get("direct_evaluations"):
            passes = int(stats["direct_evaluations"]) // max(1, image.shape[0] * image.shape[1])
        robust = getattr(result, "robust", None)
        est = estimate_from_variance(image, np.asarray(result.variance, dtype=np.float64),
                                     passes=passes,
                                     keep_pixels=keep_pixels, denominator=denominator,
                                     robust=None if robust is None else np.asarray(robust, np.float64))
        return est, "variance"
    return None, (f"{integ or 'this integrator'}: no estimate (the chains' samples are "
                  "correlated; the estimate needs error_groups >= 3)")


def estimate_record(result, stats: Optional[Dict[str, Any]] = None) -> Dict[str, Any]:
    """The sidecar record of a render's estimate: ErrorEstimate.as_dict(), or
    ``{"available": False, "reason": ...}``."""
    est, how = estimate_render(result, stats)
    if est is None:
        return {"available": False, "reason": how}
    return dict(est.as_dict(), available=True)


def estimate_metadata(record: Optional[Dict[str, Any]]) -> Dict[str, Any]:
    """``cmlt:*`` header attributes (without the prefix) of an :func:`estimate_record`."""
    if not record or not record.get("available"):
        return {}
    return {"relMSEEstimate": float(record["relmse"]),
            "relMSEEstimateStderr": float(record["stderr"]),
            "relMSEEstimateGroups": int(record["groups"]),
            "relMSEEstimateMethod": f"{record['method']}/{record.get('denominator', '')}"}


def estimate_text(record: Optional[Dict[str, Any]]) -> str:
    """``relMSE ~0.0031 ± 0.0002`` for the progress line; '' without an estimate."""
    if not record or not record.get("available"):
        return ""
    return f"relMSE ~{record['relmse']:.2g} ± {record['stderr']:.1g}"
