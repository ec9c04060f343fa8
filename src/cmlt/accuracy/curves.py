"""Error against time: the rows of an accuracy sweep, their aggregation over seeds and
frames, the log-log fit per integrator, and the CSV and markdown they are written as.

Error measures of one render I against its frame's reference R (mean over pixels and
channels)::

    relMSE = mean (I - R)^2 / (R^2 + 1e-2)          (cmlt.metrics.rel_mse)
    RMSE   = sqrt(mean (I - R)^2)
    mean ratio = mean I / mean R                     (a brightness bias shows here)

A row of ``accuracy.csv`` is one (renderer, integrator, budget): the means over its
renders (seeds x frames) and the standard errors of the means (sample standard deviation
over the renders / sqrt(renders)).

The fit: log relMSE = a + k log t by least squares through an integrator's per-budget
means (t the mean measured wall time; :func:`fits` says why means). Unbiased Monte Carlo
converges as 1/t (k = -1); the time to reach a target error E is exp((log E - a) / k),
*extrapolated* when outside the range of times measured.
"""
from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass, field
from typing import Dict, Iterable, List, Optional, Sequence

import numpy as np

__all__ = ["Run", "Row", "Fit", "measure", "aggregate", "fit", "fits", "write_csv",
           "write_runs_csv", "read_csv", "markdown_table", "CSV_COLUMNS", "TARGETS"]

#: accuracy.csv's columns, in order
CSV_COLUMNS = ("renderer", "integrator", "seconds", "time_s", "samples", "relmse", "relmse_se",
               "rmse", "rmse_se", "mean_ratio", "mean_ratio_se", "renders")
#: the relMSE targets whose time the summary reports
TARGETS = (0.01, 0.001)


@dataclass
class Run:
    """One render's numbers."""

    renderer: str
    integrator: str
    seconds: float              # the budget
    seed: int
    frame: float
    time_s: float               # wall time of the render
    samples: float              # per pixel (path evaluations for pssmlt / cmlt)
    relmse: float
    rmse: float
    mean_ratio: float


@dataclass
class Row:
    renderer: str
    integrator: str
    seconds: float
    time_s: float
    samples: float
    relmse: float
    relmse_se: float
    rmse: float
    rmse_se: float
    mean_ratio: float
    mean_ratio_se: float
    renders: int

    @property
    def label(self) -> str:
        return self.integrator if self.renderer == "cmlt" else f"{self.renderer} {self.integrator}"


def measure(image: np.ndarray, reference: np.ndarray) -> Dict[str, float]:
    """relMSE, RMSE and the mean-brightness ratio of ``image`` against ``reference``."""
    from ..metrics import rel_mse

    i = np.asarray(image, np.float64)
    r = np.asarray(reference, np.float64)
    if i.shape != r.shape:
        raise ValueError(f"image {i.shape} and reference {r.shape} differ in shape")
    d = i - r
    mr = float(r.mean())
    return {"relmse": rel_mse(i, r), "rmse": float(math.sqrt(float(np.mean(d * d)))),
            "mean_ratio": float(i.mean()) / mr if mr > 0 else math.nan}


def _mean_se(values: Sequence[float]):
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=np.float64)
    if len(v) == 0:
        return math.nan, math.nan
    if len(v) == 1:
        return float(v[0]), math.nan
    return float(v.mean()), float(v.std(ddof=1) / math.sqrt(len(v)))


def aggregate(runs: Iterable[Run]) -> List[Row]:
    """Rows by (renderer, integrator, budget), in the order first seen."""
    groups: Dict[tuple, List[Run]] = {}
    for r in runs:
        groups.setdefault((r.renderer, r.integrator, r.seconds), []).append(r)
    rows = []
    for (ren, integ, sec), rs in groups.items():
        rel, rel_se = _mean_se([r.relmse for r in rs])
        rm, rm_se = _mean_se([r.rmse for r in rs])
        mr, mr_se = _mean_se([r.mean_ratio for r in rs])
        rows.append(Row(ren, integ, float(sec), float(np.mean([r.time_s for r in rs])),
                        float(np.mean([r.samples for r in rs])), rel, rel_se, rm, rm_se, mr,
                        mr_se, len(rs)))
    return rows


@dataclass
class Fit:
    """log relMSE = intercept + slope log t over one integrator's renders."""

    renderer: str
    integrator: str
    slope: float
    intercept: float
    slope_se: float
    t_min: float
    t_max: float
    n: int
    targets: Dict[float, Optional[float]] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return self.integrator if self.renderer == "cmlt" else f"{self.renderer} {self.integrator}"

    def time_to(self, target: float) -> Optional[float]:
        """Seconds to reach relMSE ``target`` along the fit; None if the error does not
        fall with time (slope >= 0)."""
        if not (self.slope < 0) or not math.isfinite(self.intercept):
            return None
        return float(math.exp((math.log(target) - self.intercept) / self.slope))

    def extrapolated(self, t: Optional[float]) -> bool:
        return t is not None and not (self.t_min <= t <= self.t_max)


def fit(times: Sequence[float], errors: Sequence[float], renderer: str = "cmlt",
        integrator: str = "") -> Fit:
    """Least-squares line through (log t, log relMSE); slope_se from the residuals."""
    t = np.asarray(times, np.float64)
    e = np.asarray(errors, np.float64)
    ok = (t > 0) & (e > 0) & np.isfinite(t) & np.isfinite(e)
    t, e = t[ok], e[ok]
    n = len(t)
    if n < 2 or np.ptp(np.log(t)) == 0:
        return Fit(renderer, integrator, math.nan, math.nan, math.nan,
                   float(t.min()) if n else math.nan, float(t.max()) if n else math.nan, n)
    x, y = np.log(t), np.log(e)
    A = np.stack([np.ones(n), x], 1)
    (a, k), *_ = np.linalg.lstsq(A, y, rcond=None)
    se = math.nan
    if n > 2:
        res = y - (a + k * x)
        s2 = float(res @ res) / (n - 2)
        se = math.sqrt(s2 / float(((x - x.mean()) ** 2).sum()))
    f = Fit(renderer, integrator, float(k), float(a), se, float(t.min()), float(t.max()), n)
    f.targets = {target: f.time_to(target) for target in TARGETS}
    return f


def _fit_means(rs: Sequence[Run], renderer: str, integrator: str) -> Fit:
    by_budget: Dict[float, List[Run]] = {}
    for r in rs:
        by_budget.setdefault(r.seconds, []).append(r)
    t = [float(np.mean([r.time_s for r in b])) for b in by_budget.values()]
    e = [float(np.mean([r.relmse for r in b])) for b in by_budget.values()]
    return fit(t, e, renderer, integrator)


def fits(runs: Iterable[Run]) -> List[Fit]:
    """One fit per (renderer, integrator) through its per-budget means (mean time, mean
    relMSE over seeds and frames): a render's error is heavy-tailed (a few rare paths
    decide it), so the line through the means follows the expected error, which falls as
    1/t, where a line through every render's log error would follow its typical value and
    come out flatter. ``slope_se``: the delete-one-seed jackknife when there are >= 3
    seeds (each seed's renders left out in turn), else from the residuals."""
    groups: Dict[tuple, List[Run]] = {}
    for r in runs:
        groups.setdefault((r.renderer, r.integrator), []).append(r)
    out = []
    for (ren, integ), rs in groups.items():
        f = _fit_means(rs, ren, integ)
        seeds = sorted({r.seed for r in rs})
        if len(seeds) >= 3 and math.isfinite(f.slope):
            loo = np.array([_fit_means([r for r in rs if r.seed != s], ren, integ).slope
                            for s in seeds])
            if np.isfinite(loo).all():
                k = len(seeds)
                f.slope_se = float(math.sqrt((k - 1) / k * float(((loo - loo.mean()) ** 2).sum())))
        out.append(f)
    return out


def _fmt(v: float, spec: str = ".4g") -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def write_csv(path: str, rows: Sequence[Row]) -> str:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(CSV_COLUMNS)
        for r in rows:
            d = asdict(r)
            w.writerow([d[c] if isinstance(d[c], str) else _fmt(d[c], ".6g") for c in CSV_COLUMNS])
    return path


def write_runs_csv(path: str, runs: Sequence[Run]) -> str:
    cols = list(Run.__dataclass_fields__)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in runs:
            d = asdict(r)
            w.writerow([d[c] if isinstance(d[c], str) else _fmt(float(d[c]), ".6g") for c in cols])
    return path


def read_csv(path: str) -> List[Row]:
    """accuracy.csv back into rows (empty cells: NaN)."""
    rows = []
    with open(path, newline="") as f:
        for d in csv.DictReader(f):
            num = {k: (float(d[k]) if d[k] != "" else math.nan) for k in CSV_COLUMNS[2:]}
            num["renders"] = int(num["renders"])
            rows.append(Row(d["renderer"], d["integrator"], **num))
    return rows


def _seconds(t: Optional[float]) -> str:
    if t is None:
        return "not reached"
    if t >= 3600:
        return f"{t / 3600:.3g} h"
    if t >= 60:
        return f"{t / 60:.3g} min"
    return f"{t:.3g} s"


def markdown_table(rows: Sequence[Row], fit_list: Sequence[Fit], title: str = "") -> str:
    """The rows and the fits as two markdown tables (the command's stdout)."""
    out = []
    if title:
        out += [title, ""]
    out += ["| integrator | budget s | time s | samples/px | relMSE | ± se | RMSE | mean/ref |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r.label} | {r.seconds:g} | {_fmt(r.time_s, '.2f')} | {_fmt(r.samples, '.1f')} | "
                   f"{_fmt(r.relmse)} | {_fmt(r.relmse_se, '.2g')} | {_fmt(r.rmse)} | "
                   f"{_fmt(r.mean_ratio, '.4f')} |")
    out += ["", "| integrator | slope (log-log) | " +
            " | ".join(f"time to relMSE {t:g}" for t in TARGETS) + " |",
            "|---|---:|" + "---:|" * len(TARGETS)]
    for f in fit_list:
        cells = []
        for t in TARGETS:
            v = f.targets.get(t)
            if not math.isfinite(f.slope):          # fewer than two budgets: no fit
                cells.append("-")
                continue
            cells.append(_seconds(v) + (" (extrapolated)" if f.extrapolated(v) else ""))
        slope = (_fmt(f.slope, ".2f") + (f" ± {_fmt(f.slope_se, '.2f')}" if math.isfinite(f.slope_se) else "")
                 if math.isfinite(f.slope) else "-")
        out.append(f"| {f.label} | {slope} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"
