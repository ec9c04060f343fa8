#!/usr/bin/env python3
"""The README's "What accuracy costs" tables from ``cmlt accuracy`` output directories:
per sequence and integrator, the fitted log-log slope against time (and against samples
per pixel: on a shared machine the samples a second buys change during a run) and the
time to reach relMSE 0.01 and 0.001 (* when extrapolated along the fit), the relMSE at
the largest budget, and the run's conditions (reference, its own relMSE, load average).

    .venv/bin/python tests/bench/accuracy_summary.py tests/bench/results/accuracy/*/ \
        --grid tests/bench/results/accuracy/accuracy.png
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

from cmlt.accuracy.curves import TARGETS, fit, read_csv


def _t(v, extrapolated):
    if v is None:
        return "not reached"
    s = f"{v / 60:.3g} min" if v >= 60 else f"{v:.2g} s"
    if v >= 3600:
        s = f"{v / 3600:.3g} h"
    return s + (" *" if extrapolated else "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dirs", nargs="+", help="cmlt accuracy --out directories")
    ap.add_argument("--grid", metavar="PNG", help="also plot every directory's curves in one PNG")
    args = ap.parse_args(argv)
    panels = []
    out = ["| sequence | integrator | slope (time) | slope (samples) | "
           + " | ".join(f"time to {t:g}" for t in TARGETS)
           + f" | {TARGETS[-1]:g} along 1/t from the largest budget"
           + " | relMSE at the largest budget | mean/ref there |",
           "|---|---|---:|---:|" + "---:|" * len(TARGETS) + "---:|---:|---:|"]
    notes = []
    for d in args.dirs:
        meta = json.load(open(os.path.join(d, "accuracy.json")))
        rows = read_csv(os.path.join(d, "accuracy.csv"))
        name = os.path.basename(os.path.normpath(d))
        top = max(r.seconds for r in rows)
        for f in meta["fits"]:
            label = f["integrator"] if f["renderer"] == "cmlt" else f"{f['renderer']} {f['integrator']}"
            last = next(r for r in rows if r.integrator == f["integrator"] and r.renderer == f["renderer"]
                        and r.seconds == top)
            slope = f["slope"]
            se = f.get("slope_se")
            cells = [_t(f["time_to"][str(t)], f["extrapolated"][str(t)]) for t in TARGETS]
            mine = [r for r in rows if r.integrator == f["integrator"] and r.renderer == f["renderer"]]
            ks = fit([r.samples for r in mine], [r.relmse for r in mine]).slope
            out.append(f"| {name} | {label} | {slope:.2f}"
                       + (f" ± {se:.2f}" if se is not None and math.isfinite(se) else "")
                       + f" | {ks:.2f} | " + " | ".join(cells)
                       + f" | {_t(last.time_s * last.relmse / TARGETS[-1], False)}"
                       + f" | {last.relmse:.2g} ± {last.relmse_se:.1g} | {last.mean_ratio:.3f} |")
        ref = meta["references"][0]
        floor = ref.get("relmse_floor")
        panels.append((rows, name, floor))
        notes.append(f"{name}: reference {ref['integrator']} {ref['spp']} spp"
                     + (f" (its own relMSE ~{floor:.2g})" if floor is not None and math.isfinite(floor) else "")
                     + f", load average {meta['loadavg_start'][0]:.1f} -> {meta['loadavg_end'][0]:.1f}, "
                     f"{meta['elapsed_s'] / 60:.1f} min")
    print("\n".join(out))
    print()
    print("\n".join(f"- {n}" for n in notes))
    if args.grid:
        from cmlt.accuracy.plot import plot_grid
        plot_grid(panels, args.grid)
    return 0


if __name__ == "__main__":
    sys.exit(main())
