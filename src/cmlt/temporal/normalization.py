"""The normalisation b of a frame, estimated twice and smoothed over time.

Per frame f+1 (DESIGN.md §4):

* ``b_fresh`` — the core's own estimate (bootstrap + every large step of the
  frame; independent of the carried chains), with its standard error;
* ``b_ratio = b_f · m`` with ``m`` the ratio estimate of ``b_{f+1}/b_f``: with
  carried states (the driver) ``m = Σ_i f*_{f+1}(v_i) / Σ_i f*_f(v_i)`` over the
  bootstrap points v_i, the same points in both frames (common random numbers),
  its variance by the delta method; ``σ²_ratio = (σ_f m)² + b_f² var(m)``
  (b_f's own error propagated, plus m's). (Given the mean of f*_{f+1}/f*_f over
  states carried ∝ f*_f it estimates the same ratio on the support of f*_f.)
* change detection, two signals, either one resets:

  - paired (without a ratio estimate): with stored seeds the bootstrap
    samples are the same points in both frames, so ``Δ = mean_i(f*_{f+1}(u_i)
    − f*_f(u_i))`` estimates ``b_{f+1} − b_f`` with common random numbers: its
    standard error ``σ_Δ`` is far below either frame's (0 in a static shot).
    A change is *real* if ``|Δ| > z·σ_Δ`` and *matters* if ``|Δ| > σ_fresh``
    (smaller steps are below the frame's own noise: smoothing across them
    removes more error than the lag adds). With carried states the ratio is
    taken over these same points (``Σ f*_{f+1} / Σ f*_f``, which also sees
    light where f*_f = 0) and transports the smoothed b, so the change is
    followed instead;
  - ``|b_fresh − b_ratio| > z·sqrt(σ²_fresh + σ²_ratio)`` (the ratio
    estimator cannot see paths that were black in frame f — a light switched
    on — the fresh estimate can; their disagreement is the signal). Without
    carried states: ``|b_fresh − b_f| > z·sqrt(σ²_fresh + σ²_f)``.
  - drift (CUSUM): the standardised residual ``r = (b_fresh − b_pred) /
    σ_fresh`` of each frame against the smoothed prediction is accumulated,
    ``S± = max(0, S± ± r − k)``, and ``S± > h`` is a change. The ratio
    estimator is blind to mass moving into regions the carried chains never
    reached (a light sweeping the room), so its small per-frame deficit would
    otherwise compound through the smoothing into a lasting bias (measured on
    moving_light: −26 % after 8 frames); CUSUM bounds it to a few frames of
    about one standard error.
  A change resets: ``b_combined = b_smoothed = b_fresh`` (no lag) and S± = 0;
* otherwise ``b_combined`` = the inverse-variance combination of the two, and
  ``b_smoothed`` = a causal exponential filter in log space over the
  combined values, the previous smoothed value first transported to this
  frame by the ratio mean m (so a smooth change the ratio sees is followed
  without lag): ``log b_s = α log b_combined + (1 − α) log(b_{s,f} · m)``.
  Its standard error is kept from collapsing (frames rendered with stored
  seeds are correlated, so treating them as independent would make the
  filter ever more confident) by a floor ``σ_fresh / sqrt(window)``.

The image of the frame is rescaled to ``b_smoothed`` (``histogram · b /
mutations`` is linear in b).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Optional

__all__ = ["NormRecord", "update_normalization", "Z_CHANGE", "ALPHA", "WINDOW"]

#: change threshold in standard errors
Z_CHANGE = 4.0
#: weight of the new frame in the exponential smoothing (log space)
ALPHA = 0.25
#: the smoothed b is never more certain than this many fresh frames
WINDOW = 8
#: CUSUM drift detection: allowance k and threshold h (in standard errors); with
#: unbiased residuals a false reset every ~100 frames, a 1σ drift found in ~7
CUSUM_K = 0.5
CUSUM_H = 3.0


@dataclass
class NormRecord:
    """One frame's normalisation (all b in the core's units)."""
    frame: float
    b_fresh: float
    s_fresh: float
    b_ratio: float = math.nan          # NaN: no carried states
    s_ratio: float = math.nan
    b_combined: float = math.nan
    s_combined: float = math.nan
    b_smoothed: float = math.nan
    s_smoothed: float = math.nan
    change: bool = True
    #: the b the image was normalised with (b_smoothed with smoothing, else b_fresh)
    b_used: float = math.nan
    s_used: float = math.nan
    #: paired bootstrap difference b_{f+1} − b_f and its standard error (NaN: none)
    delta: float = math.nan
    s_delta: float = math.nan
    #: CUSUM sums of the standardised residuals b_fresh − prediction (upper, lower)
    cusum_up: float = 0.0
    cusum_down: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)


def _ok(x) -> bool:
    return x is not None and math.isfinite(x) and x > 0.0


def paired_difference(f_old, f_new) -> Optional[dict]:
    """Mean and standard error of f_new − f_old over paired samples (the same
    bootstrap points in two frames); None if they do not pair up."""
    import numpy as np
    a = np.asarray(f_old, dtype=np.float64)
    b = np.asarray(f_new, dtype=np.float64)
    if a.size < 2 or a.shape != b.shape:
        return None
    d = b - a
    return {"mean": float(d.mean()), "stderr": float(d.std(ddof=1) / math.sqrt(d.size)),
            "count": int(d.size)}


def update_normalization(frame: float, b_fresh: float, s_fresh: float,
                         prev: Optional[NormRecord] = None, ratio: Optional[dict] = None,
                         smooth: bool = True, z: float = Z_CHANGE, alpha: float = ALPHA,
                         window: int = WINDOW, paired: Optional[dict] = None) -> NormRecord:
    """This frame's record from the previous one. ``ratio``: the core's
    ``temporal_ratio_statistics`` over the carried states (``mean``,
    ``variance``, ``count``), or None. ``paired``: :func:`paired_difference`
    of the two frames' bootstrap f*, or None."""
    s_fresh = float(s_fresh) if math.isfinite(s_fresh) and s_fresh >= 0 else 0.0
    r = NormRecord(frame=float(frame), b_fresh=float(b_fresh), s_fresh=s_fresh)
    have_prev = prev is not None and _ok(prev.b_used)
    m = None
    if have_prev and ratio is not None and int(ratio.get("count", 0)) > 0:
        m = float(ratio["mean"])
        n = int(ratio["count"])
        var_w = max(float(ratio.get("variance", 0.0)), 0.0)
        s_prev = prev.s_used if math.isfinite(prev.s_used) else 0.0
        r.b_ratio = prev.b_used * m
        r.s_ratio = math.sqrt((s_prev * m) ** 2 + prev.b_used ** 2 * var_w / n)
        # the ratio estimator is blind to mass that appears outside the old support
        # (a light moving into new areas) and its chains are correlated: never trust it
        # more than the fresh estimate, or its small per-frame deficits accumulate
        r.s_ratio = max(r.s_ratio, s_fresh)

    paired_change = False
    if paired is not None and have_prev:
        r.delta, r.s_delta = float(paired["mean"]), float(paired["stderr"])
        # with a ratio over the same points the smoothed b is transported by it, so a
        # change the pairs see (a fade, a light switched on) is followed, not a reset
        paired_change = (m is None and abs(r.delta) > z * r.s_delta and abs(r.delta) > s_fresh)
    drift_change = False
    if have_prev and smooth and _ok(b_fresh) and s_fresh > 0 and _ok(prev.b_smoothed):
        pred = prev.b_smoothed * (m if m is not None and m > 0 else 1.0)
        res = (b_fresh - pred) / s_fresh
        r.cusum_up = max(0.0, prev.cusum_up + res - CUSUM_K)
        r.cusum_down = max(0.0, prev.cusum_down - res - CUSUM_K)
        drift_change = r.cusum_up > CUSUM_H or r.cusum_down > CUSUM_H
    if not _ok(b_fresh):
        r.change = True
    elif paired_change or drift_change:
        r.change = True
    elif m is not None:
        r.change = abs(b_fresh - r.b_ratio) > z * math.sqrt(s_fresh ** 2 + r.s_ratio ** 2)
    elif have_prev:
        s_prev = prev.s_used if math.isfinite(prev.s_used) else 0.0
        r.change = abs(b_fresh - prev.b_used) > z * math.sqrt(s_fresh ** 2 + s_prev ** 2)
    else:
        r.change = True                      # first frame: nothing to smooth with

    if r.change:
        r.cusum_up = r.cusum_down = 0.0
    if r.change or not smooth:
        r.b_combined, r.s_combined = r.b_fresh, s_fresh
        r.b_smoothed, r.s_smoothed = r.b_fresh, s_fresh
    else:
        if m is not None and _ok(r.b_ratio):
            vf, vr = s_fresh ** 2, r.s_ratio ** 2
            if vf > 0 and vr > 0:
                r.b_combined = (b_fresh / vf + r.b_ratio / vr) / (1 / vf + 1 / vr)
                r.s_combined = math.sqrt(1 / (1 / vf + 1 / vr))
            elif vr == 0 and vf > 0:           # an exact ratio (e.g. a static scene)
                r.b_combined, r.s_combined = r.b_ratio, 0.0
            else:
                r.b_combined, r.s_combined = b_fresh, s_fresh
            pred = prev.b_smoothed * m if _ok(prev.b_smoothed) and m > 0 else r.b_combined
        else:
            r.b_combined, r.s_combined = b_fresh, s_fresh
            pred = prev.b_smoothed if _ok(prev.b_smoothed) else b_fresh
        if _ok(r.b_combined) and _ok(pred):
            r.b_smoothed = math.exp(alpha * math.log(r.b_combined) + (1 - alpha) * math.log(pred))
        else:
            r.b_smoothed = b_fresh
        s_prev = prev.s_smoothed if math.isfinite(prev.s_smoothed) else s_fresh
        s = math.sqrt((alpha * r.s_combined) ** 2 + ((1 - alpha) * s_prev * (m or 1.0)) ** 2)
        r.s_smoothed = max(s, s_fresh / math.sqrt(window))
    if smooth:
        r.b_used, r.s_used = r.b_smoothed, r.s_smoothed
    else:
        r.b_used, r.s_used = r.b_fresh, s_fresh
    return r
