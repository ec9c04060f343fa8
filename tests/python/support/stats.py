"""Statistics the integrator tests compare with (no scipy)."""
import math

import numpy as np

#: luminance weights of the rendering space (ACEScg)
ACESCG_Y = np.array([0.2722287, 0.6740818, 0.0536895])


def lum_se(var):
    """Standard error of the image-mean luminance from a variance AOV (H, W, 3) with
    independent pixels. The channels of one pixel are strongly correlated (the
    channels-independent sum_c Y_c^2 var_c underestimated the variance of the mean 1.5-2.5x,
    measured over 64 seeds), and only per-channel variances are known, so this is the
    Cauchy-Schwarz bound sqrt(Var(sum_c Y_c X_c)) <= sum_c Y_c sd_c (exact for fully
    correlated channels, conservative otherwise)."""
    n = var.shape[0] * var.shape[1]
    return float(np.sqrt(np.asarray(var).reshape(-1, 3).sum(0)) @ ACESCG_Y) / n


def t_critical(dof, two_sided_alpha):
    """Quantile of Student's t by bisection on the regularised incomplete beta (no scipy)."""
    def sf(t):  # P(T > t), t >= 0
        x = dof / (dof + t * t)
        return 0.5 * _betainc(dof / 2, 0.5, x)
    lo, hi = 0.0, 1e3
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if sf(mid) > two_sided_alpha / 2 else (lo, mid)
    return hi


def _betainc(a, b, x):
    """Regularised incomplete beta I_x(a, b) (continued fraction, Numerical Recipes)."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    lbeta = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
    front = math.exp(lbeta + a * math.log(x) + b * math.log(1 - x))
    if x > (a + 1) / (a + b + 2):
        return 1.0 - _betainc(b, a, 1 - x)
    f, c, d = 1.0, 1.0, 0.0
    for i in range(400):
        m = i // 2
        if i == 0:
            num = 1.0
        elif i % 2 == 0:
            num = m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m))
        else:
            num = -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))
        d = 1.0 + num * d
        d = 1.0 / (d if abs(d) > 1e-300 else 1e-300)
        c = 1.0 + num / c if abs(c) > 1e-300 else 1e-300
        f *= c * d
        if abs(c * d - 1.0) < 1e-14:
            break
    return front * (f - 1.0) / a


def block_means(a, b):
    """Means of b x b pixel blocks of an (H, W, ...) image."""
    h, w = a.shape[:2]
    return a.reshape(h // b, b, w // b, b, *a.shape[2:]).mean(axis=(1, 3))


def agree_over_seeds(runs_a, runs_b, block, what, alpha=1e-3):
    """Block means of two estimators over their seeds: Welch t with K - 1 dof,
    Bonferroni over blocks and channels; black blocks in both count as agreeing.
    Returns the largest |t| and the critical value."""
    a = np.stack([block_means(img, block) for img in runs_a])
    b = np.stack([block_means(img, block) for img in runs_b])
    k = min(len(a), len(b))
    se = np.sqrt(a.var(0, ddof=1) / len(a) + b.var(0, ddof=1) / len(b))
    diff = np.abs(a.mean(0) - b.mean(0))
    black = (se == 0) & (diff == 0)
    t = np.where(black, 0.0, diff / np.where(se > 0, se, 1e-300))
    crit = t_critical(k - 1, alpha / t.size)
    print(f"[{what}] means {a.mean():.5f} vs {b.mean():.5f}, max |t| {t.max():.2f} "
          f"(critical {crit:.2f}, {t.size} blocks x channels)")
    assert (t < crit).all(), (what, t.max(), crit, np.unravel_index(t.argmax(), t.shape))
    return t.max(), crit
