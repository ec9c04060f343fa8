#!/usr/bin/env python3
"""Parameter study of cmlt (σ, k, m) at equal time on a shot (benchmark, not a test).

For each configuration: calibrate the evaluations per pixel that fill the time budget,
render with a few seeds, report the mean relMSE against the cached BDPT reference of
tests/bench/equal_time.py (run that first to create it).

    .venv/bin/python tests/bench/cmlt_params.py sequences/cornell/shot.usda --res 96x96 --seconds 2
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from equal_time import build_scene, relmse, settings, stage_start  # noqa: E402

CONFIGS = [  # (sigma, tries, inner_length)
    (0.03, 8, 2), (0.01, 8, 1), (0.01, 4, 2),
    (0.01, 8, 8), (0.003, 8, 8), (0.03, 8, 8), (0.1, 8, 8),
    (0.01, 4, 8), (0.01, 16, 8), (0.01, 8, 2), (0.01, 8, 32),
]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--res", default="96x96")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--inner", default="bundle")
    ap.add_argument("--first", type=int, default=0, help="only the first N configurations")
    ap.add_argument("--reference", default=None, help=".npy (default renders/bench/<shot>_<res>_bdpt_2048.npy)")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    core, _, _, scene, res = build_scene(args.shot, stage_start(args.shot), (w, h))
    stem = Path(args.shot).parent.name
    ref = np.load(args.reference or f"renders/bench/{stem}_{w}x{h}_bdpt_2048.npy")
    print(f"{'sigma':>6} {'k':>3} {'m':>3} {'evals/px':>9} {'relMSE':>9} {'±':>8}")
    for sigma, k, m in (CONFIGS[:args.first] if args.first else CONFIGS):
        extra = {"sigma": sigma, "tries": k, "inner_length": m, "inner": args.inner}
        t0 = time.perf_counter()
        core.render(scene, settings(core, "cmlt", 32, res, 99, 2, extra))
        spp = max(1, int(32 * args.seconds / (time.perf_counter() - t0)))
        errs = [relmse(np.asarray(core.render(scene, settings(core, "cmlt", spp, res, s, 2, extra)).image), ref)
                for s in range(args.seeds)]
        print(f"{sigma:>6} {k:>3} {m:>3} {spp:>9} {np.mean(errs):>9.5f} {np.std(errs, ddof=1) / len(errs) ** 0.5:>8.5f}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
