#!/usr/bin/env python3
"""Equal-time benchmark of the integrators on the Cornell box and caustic_glass.

Calls ``tests/bench/equal_time.py`` once per shot (pt, bdpt, pssmlt and cmlt, each to the
core's time budget), writing ``renders/bench/<shot>.json`` / ``.png``, then prints a markdown
table: relMSE against a converged reference at each equal-time budget, and samples/s.

    .venv/bin/python tests/bench/run_all.py                      # 2,4,8 s, 128x128, 2 threads
    .venv/bin/python tests/bench/run_all.py --seconds 1,2 --reference-spp 1024   # quicker

The references (cached in renders/bench/*.npy, keyed by shot, size, integrator and spp)
are bdpt for both shots (PT finds the caustic slowly; on the Cornell box a bdpt
reference keeps pt from being compared with its own estimator's bias, if it had one).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

SHOTS = {
    "cornell": ("sequences/cornell/shot.usda", "bdpt"),
    "caustic_glass": ("sequences/caustic_glass/shot.usda", "bdpt"),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", default="2,4,8")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--integrators", default="pt,bdpt,pssmlt,cmlt")
    ap.add_argument("--shots", default=",".join(SHOTS))
    ap.add_argument("--out", default="renders/bench")
    args = ap.parse_args(argv)

    integrators = args.integrators
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for name in [s for s in args.shots.split(",") if s]:
        shot, ref_integ = SHOTS[name]
        cmd = [sys.executable, str(HERE / "equal_time.py"), str(ROOT / shot),
               "--seconds", args.seconds, "--res", args.res, "--threads", str(args.threads),
               "--integrators", integrators, "--reference-integrator", ref_integ,
               "--reference-spp", str(args.reference_spp),
               "--json", str(out / f"{name}.json"), "--plot", str(out / f"{name}.png")]
        print("$ " + " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, cwd=ROOT)
        results[name] = json.loads((out / f"{name}.json").read_text())

    print()
    print(f"Equal time, {args.res}, {args.threads} threads; relMSE vs a {args.reference_spp}-spp "
          f"reference (lower is better)")
    print()
    print("| shot | integrator | budget (s) | time (s) | spp | relMSE | mean/ref | samples/s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name, res in results.items():
        for r in res["rows"]:
            print(f"| {name} | {r['integrator']} | {r['budget_s']:g} | {r['time_s']:.2f} | "
                  f"{r['spp']} | {r['relmse']:.5f} | {r['mean_ratio']:.4f} | "
                  f"{r['samples_per_s']:.3g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
