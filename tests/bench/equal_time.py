#!/usr/bin/env python3
"""Accuracy against time: relMSE of each integrator at equal wall time.

For one frame of a shot, renders a converged reference once (cached under
``renders/bench/``; ``cmlt.accuracy.render_reference``), then renders with each integrator under each time budget
(the core's own time budget, RenderSettings.time_budget: every integrator stops
when the wall time is used up, fixed passes included) and measures the relative
MSE against the reference:

    relMSE = mean over pixels and channels of (I - R)^2 / (R^2 + 1e-2)

All integrators run side by side in one process on the same machine state, so
the ratios between them are what to read; absolute seconds depend on the load.
``cmlt accuracy`` does the same over seeds and frames, with error bars, fits and CSV;
this script is the one-seed version with samples/s, rays/s and the tracing share.

    python tests/bench/equal_time.py sequences/cornell/shot.usda --seconds 2,4,8 \\
        --integrators pt,bdpt --json renders/bench/cornell.json --plot renders/bench/cornell.png
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cmlt.accuracy import ShotFrame, measure, parse_integrator, render_reference


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--frame", type=float, default=None, help="time code (default: stage start)")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--integrators", default="pt,bdpt")
    ap.add_argument("--seconds", default="2,4,8", help="comma-separated time budgets per render")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reference-integrator", default="pt")
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--json", default=None)
    ap.add_argument("--plot", default=None)
    args = ap.parse_args(argv)

    w, h = (int(v) for v in args.res.lower().split("x"))
    sf = ShotFrame(args.shot, args.frame, (w, h), args.threads)
    budgets = [float(s) for s in args.seconds.split(",")]
    integrators = [s.strip() for s in args.integrators.split(",") if s.strip()]

    # -- reference (cached: cmlt.accuracy.render_reference) --------------------
    ref = render_reference(sf, args.reference_integrator, args.reference_spp, "renders/bench")
    print(f"reference: {args.reference_integrator} {args.reference_spp} spp "
          + ("(cached)" if ref.cached else f"done in {ref.time_s:.1f} s"), flush=True)

    rows = []
    for integ in integrators:
        spec = parse_integrator(integ, sf.core)         # e.g. cmlt:tries=4:inner_length=2
        for budget in budgets:
            r = sf.render(spec, seconds=budget, seed=args.seed)
            m = measure(r.image, ref.image)
            evals = r.samples * w * h
            row = {
                "integrator": integ, "budget_s": budget, "spp": r.samples,
                "time_s": r.time_s, "relmse": m["relmse"], "mean_ratio": m["mean_ratio"],
                "samples_per_s": evals / max(r.time_s, 1e-9),
                "rays_per_s": float(r.stats.get("rays", 0)) / max(r.time_s, 1e-9),
                "trace_fraction": float(r.stats.get("trace_s", 0.0)) / max(float(r.stats.get("busy_s", 0.0)), 1e-9),
            }
            rows.append(row)
            print(f"{integ:>24} budget {budget:6.1f}s  per px {row['spp']:8.1f}  time {r.time_s:6.2f}s  "
                  f"relMSE {row['relmse']:.5f}  mean/ref {row['mean_ratio']:.4f}  "
                  f"samples/s {row['samples_per_s']:.3g}  rays/s {row['rays_per_s']:.3g}  "
                  f"tracing {100 * row['trace_fraction']:.0f}%", flush=True)

    result = {"shot": args.shot, "res": [w, h], "threads": args.threads,
              "reference": {"integrator": args.reference_integrator, "spp": args.reference_spp},
              "rows": rows}
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=2))
    if args.plot:
        from cmlt.accuracy.curves import Row
        from cmlt.accuracy.plot import plot_curves
        plot_curves([Row("cmlt", r["integrator"], r["budget_s"], r["time_s"], r["spp"], r["relmse"],
                         float("nan"), float("nan"), float("nan"), r["mean_ratio"], float("nan"), 1)
                     for r in rows], args.plot, title=sf.name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
