"""The error-time plot of an accuracy sweep: relMSE against wall time on log-log axes,
one line per integrator (peers dashed) with the standard error over seeds as error bars,
a dotted 1/t line for the slope of unbiased Monte Carlo, and the reference's own
estimated relMSE (the floor below which measured errors mean nothing) when known."""
from __future__ import annotations

import math
from typing import Optional, Sequence

__all__ = ["plot_curves", "plot_grid", "draw_curves"]


def plot_curves(rows: Sequence, path: str, title: str = "",
                floor: Optional[float] = None, dpi: int = 100) -> str:
    """Write the plot of ``rows`` (:class:`cmlt.accuracy.curves.Row`) to ``path`` (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    draw_curves(ax, rows, title, floor)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plot_grid(panels: Sequence, path: str, columns: int = 3, dpi: int = 80) -> str:
    """Several shots in one PNG: ``panels`` is a list of (rows, title, floor)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(panels)
    cols = min(columns, n)
    nrows = (n + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.3 * nrows), squeeze=False)
    for ax, (rows, title, floor) in zip(axes.flat, panels):
        draw_curves(ax, rows, title, floor, legend=ax is axes.flat[0])
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def draw_curves(ax, rows: Sequence, title: str = "", floor: Optional[float] = None,
                legend: bool = True) -> None:
    """The curves of ``rows`` on a matplotlib axis."""
    labels = []
    for r in rows:
        if r.label not in labels:
            labels.append(r.label)
    pts_all = []
    for i, label in enumerate(labels):
        rs = sorted((r for r in rows if r.label == label and r.relmse > 0 and r.time_s > 0),
                    key=lambda r: r.time_s)
        if not rs:
            continue
        t = [r.time_s for r in rs]
        e = [r.relmse for r in rs]
        se = [r.relmse_se if r.relmse_se is not None and math.isfinite(r.relmse_se) else 0.0
              for r in rs]
        lo = [min(s, 0.95 * v) for s, v in zip(se, e)]          # keep bars above 0 on log axes
        peer = rs[0].renderer != "cmlt"
        ax.errorbar(t, e, yerr=[lo, se], fmt="s--" if peer else "o-", ms=4, lw=1.3, capsize=2,
                    label=label, color=f"C{i % 10}")
        pts_all += list(zip(t, e))
    if pts_all:
        # 1/t through the geometric centre of the first budget's points
        t0 = min(p[0] for p in pts_all)
        first = [p for p in pts_all if p[0] <= t0 * 1.5]
        tc = math.exp(sum(math.log(p[0]) for p in first) / len(first))
        ec = math.exp(sum(math.log(p[1]) for p in first) / len(first))
        tmax = max(p[0] for p in pts_all)
        ax.plot([tc, tmax], [ec, ec * tc / tmax], ":", color="0.4", lw=1.2, label="1/t")
    if floor is not None and math.isfinite(floor) and floor > 0:
        ax.axhline(floor, color="0.6", lw=0.8, ls="-.", label="reference's own relMSE")
    ax.set_xscale("log")
    ax.set_yscale("log")
    budgets = sorted({float(r.seconds) for r in rows if r.seconds > 0})
    if budgets:                         # ticks at the budgets, plain numbers
        from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter
        ax.xaxis.set_major_locator(FixedLocator(budgets))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("wall time per render (s)")
    ax.set_ylabel("relMSE")
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.25)
    if legend:
        ax.legend(fontsize=7, loc="best")
