#!/usr/bin/env python3
"""Pixel filters: equal-time relMSE of gaussian vs box, and the cost of the filter.

Equal time: for each integrator and each filter, renders of ``--seconds`` wall time
(the core's time budget) over ``--seeds`` seeds, each measured against a converged
reference rendered with the *same* filter (pt at ``--reference-spp``, cached under
renders/bench/); reported: the median relMSE over the seeds and the standard error of
the mean. The filters run interleaved (box, gaussian, box, gaussian, ...) so that the
machine's load hits both alike.

Cost (``--cost-spp N``): whole-frame wall time of cmlt at N path evaluations per pixel
(a sample budget: the same work), box vs gaussian interleaved A B A B, ``--repeats``
times each; the median of each and their ratio.

    python tests/bench/filters.py sequences/cornell/shot.usda --res 96x96 --seconds 2 \\
        --seeds 3 --integrators pt,cmlt --cost-spp 64
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

from cmlt.accuracy import ShotFrame, measure, parse_integrator, render_reference

FILTERS = ("box", "gaussian")


def equal_time(sf, args, integrators):
    refs = {f: render_reference(sf, f"pt:pixel_filter={f}", args.reference_spp, "renders/bench")
            for f in FILTERS}
    rows = []
    for integ in integrators:
        err = {f: [] for f in FILTERS}
        spp = {f: [] for f in FILTERS}
        for seed in range(1, args.seeds + 1):
            for f in FILTERS:
                spec = parse_integrator(f"{integ}:pixel_filter={f}", sf.core)
                r = sf.render(spec, seconds=args.seconds, seed=seed)
                err[f].append(measure(r.image, refs[f].image)["relmse"])
                spp[f].append(r.samples)
        for f in FILTERS:
            v = np.asarray(err[f])
            se = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
            rows.append({"integrator": integ, "filter": f, "median_relmse": float(np.median(v)),
                         "mean_relmse": float(v.mean()), "stderr": se, "relmse": v.tolist(),
                         "evaluations_per_pixel": float(np.median(spp[f]))})
            print(f"{integ:>8} {f:>9}: relMSE median {np.median(v):.5f}  mean {v.mean():.5f} "
                  f"+- {se:.5f}  per px {np.median(spp[f]):.1f}", flush=True)
    return rows


def cost(sf, args):
    times = {f: [] for f in FILTERS}
    for _ in range(args.repeats):
        for f in FILTERS:  # A B A B
            spec = parse_integrator(f"cmlt:pixel_filter={f}", sf.core)
            times[f].append(sf.render(spec, spp=args.cost_spp, seed=1).time_s)
    med = {f: statistics.median(times[f]) for f in FILTERS}
    out = {"spp": args.cost_spp, "times_s": times, "median_s": med,
           "gaussian_over_box": med["gaussian"] / med["box"]}
    print(f"cmlt {args.cost_spp} spp: box {med['box']:.3f} s, gaussian {med['gaussian']:.3f} s "
          f"(median of {args.repeats}; ratio {out['gaussian_over_box']:.3f}); all: {times}", flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--res", default="96x96")
    ap.add_argument("--integrators", default="pt,cmlt")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--cost-spp", type=int, default=0, help="also time cmlt at this sample budget")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-equal-time", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    sf = ShotFrame(args.shot, None, (w, h), args.threads)
    result = {"shot": args.shot, "res": [w, h], "threads": args.threads, "seconds": args.seconds,
              "reference_spp": args.reference_spp}
    if args.cost_spp:
        result["cost"] = cost(sf, args)
    if not args.no_equal_time:
        result["rows"] = equal_time(sf, args, [s for s in args.integrators.split(",") if s])
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
