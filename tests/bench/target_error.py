#!/usr/bin/env python3
"""Renders that stop at a target error (RenderSettings.target_error, `cmlt render
--target-error E`), measured against a reference.

For each shot, integrator and target E, renders with seeds 0..S-1 run with a generous
sample budget (so the target, not the budget, stops them) and the target; each render's
relMSE is then measured against a converged reference (bdpt, cached by
cmlt.accuracy.render_reference; its own relMSE, the floor, is printed). The criterion:
the measured relMSE lies within 0.5-1.5x of E. Writes OUT/target_error.csv (every render)
and OUT/target_error.md (per shot and integrator: renders stopped by the target, median
measured / E, the share in 0.5-1.5x, median time and work).

cmlt runs with 250 chains and 10,000 bootstrap samples at 32x32: the chains and
bootstrap per pixel of the defaults (1000, 100,000) at 64x64 and above; at 32x32 the
defaults would spend ~100 evaluations per pixel on the bootstrap alone, and a targeted
frame's minimum (2G = 16 chain rounds of at least one block of 1 + m k paths per chain)
would pass the easier targets.

    .venv/bin/python tests/bench/target_error.py --res 32x32 --seeds 6 \\
        --out tests/bench/results/accuracy
"""
from __future__ import annotations

import argparse
import csv
import os
import sys
import time

import numpy as np

from cmlt.accuracy import ShotFrame, measure, parse_integrator, render_reference

#: targets per shot: reachable in seconds at 32x32 by both integrators, and below the
#: relMSE both reach at their minimum of work (16 passes; 2G chain rounds, ~110 path
#: evaluations per pixel here) -- a target above it is met by the minimum, and the ratio
#: then says how far the minimum overshoots, not how the rule stops (caustic_glass pt
#: measures ~0.018 after 16 passes, door_ajar cmlt 0.015-0.17 after its minimum)
TARGETS = {"cornell": (0.02, 0.005), "caustic_glass": (0.01, 0.004), "door_ajar": (0.02, 0.008)}
LO, HI = 0.5, 1.5


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shots", default="cornell,caustic_glass,door_ajar")
    ap.add_argument("--res", default="32x32")
    ap.add_argument("--integrators", default="pt,cmlt:bootstrap_samples=10000:chains=250")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--spp", type=int, default=1 << 20, help="the sample budget (a ceiling)")
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cache", default="renders/cache/accuracy")
    ap.add_argument("--out", default="renders/bench/target_error")
    ap.add_argument("--target-scale", type=float, default=1.0, dest="target_scale",
                    help="multiply every target (the gaussian film's error after the minimum "
                         "work is ~0.4x the box's, for which TARGETS were chosen)")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    os.makedirs(args.out, exist_ok=True)
    rows, summary = [], []
    t_start = time.perf_counter()
    for shot in [s for s in args.shots.split(",") if s]:
        sf = ShotFrame(f"sequences/{shot}/shot.usda", None, (w, h), args.threads)
        ref = render_reference(sf, "bdpt", args.reference_spp, args.cache)
        print(f"# {shot} {w}x{h}: reference bdpt {args.reference_spp} spp, its own relMSE "
              f"{ref.relmse_floor:.3g}", flush=True)
        for integ in [s for s in args.integrators.split(",") if s]:
            spec = parse_integrator(integ, sf.core)
            for target in (t * args.target_scale for t in TARGETS[shot]):
                group = []
                for seed in range(args.seeds):
                    st = sf.settings(spec, None, args.spp, seed)
                    st.target_error = target
                    t0 = time.perf_counter()
                    r = sf.core.render(sf.scene, st)
                    secs = time.perf_counter() - t0
                    s = dict(r.stats)
                    m = measure(np.asarray(r.image, np.float64), ref.image)
                    hist = s.get("error_history") or []
                    row = {"shot": shot, "integrator": integ, "target": target, "seed": seed,
                           "stop_reason": s["stop_reason"], "estimate": s.get("error_estimate"),
                           "estimate_stderr": s.get("error_stderr"), "measured": m["relmse"],
                           "floor": ref.relmse_floor, "ratio": m["relmse"] / target,
                           "mean_ratio": m["mean_ratio"], "seconds": secs,
                           "work_per_pixel": hist[-1][0] if hist else float("nan"),
                           "checks": len(hist)}
                    rows.append(row)
                    group.append(row)
                    print(f"{shot} {integ} E={target:g} seed {seed}: {row['stop_reason']}, "
                          f"estimate {row['estimate']:.4g}, measured {row['measured']:.4g} "
                          f"({row['ratio']:.2f}x), brightness {row['mean_ratio']:.3f}, "
                          f"{secs:.2f} s, {row['work_per_pixel']:.0f} per pixel", flush=True)
                ratios = np.array([g["ratio"] for g in group])
                summary.append({"shot": shot, "integrator": integ, "target": target,
                                "renders": len(group),
                                "by_target": sum(g["stop_reason"] == "target" for g in group),
                                "median_ratio": float(np.median(ratios)),
                                "range": (float(ratios.min()), float(ratios.max())),
                                "inside": int(((ratios >= LO) & (ratios <= HI)).sum()),
                                "brightness": float(np.median([g["mean_ratio"] for g in group])),
                                "seconds": float(np.median([g["seconds"] for g in group])),
                                "work": float(np.median([g["work_per_pixel"] for g in group])),
                                "floor": ref.relmse_floor})
    with open(os.path.join(args.out, "target_error.csv"), "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]))
        wr.writeheader()
        wr.writerows(rows)
    cmd = " ".join(["tests/bench/target_error.py"] + (argv if argv is not None else sys.argv[1:]))
    lines = [f"`{cmd}` ({len(rows)} renders, {time.perf_counter() - t_start:.0f} s; "
             f"{w}x{h}, references bdpt {args.reference_spp} spp)", "",
             "| shot | integrator | target E | stopped by target | measured / E: median (range) "
             f"| in {LO}-{HI}x | brightness vs reference | median time | work per pixel | reference floor |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in summary:
        lines.append(f"| {s['shot']} | {s['integrator']} | {s['target']:g} | {s['by_target']}/{s['renders']} "
                     f"| {s['median_ratio']:.2f} ({s['range'][0]:.2f}-{s['range'][1]:.2f}) "
                     f"| {s['inside']}/{s['renders']} | {s['brightness']:.3f} | {s['seconds']:.2f} s "
                     f"| {s['work']:.0f} | {s['floor']:.2g} |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(args.out, "target_error.md"), "w") as f:
        f.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
