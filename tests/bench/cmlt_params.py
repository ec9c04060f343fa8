#!/usr/bin/env python3
"""Parameter study of the Metropolis integrators at equal time (benchmark, not a test).

For each configuration (an integrator and settings), render a few seeds to the core's
time budget and report the mean relMSE against a converged reference (cached BDPT
render under renders/bench/, made if missing), with its standard error over seeds and
the path evaluations per pixel that fit the budget. All configurations run
interleaved seed by seed in one process, so slow phases of a shared machine hit them
alike; absolute numbers still depend on the load.

    .venv/bin/python tests/bench/cmlt_params.py sequences/caustic_glass/shot.usda \\
        --res 96x96 --seconds 2 --seeds 3
    .venv/bin/python tests/bench/cmlt_params.py SHOT --configs "cmlt:tries=2:inner_length=4,pssmlt"
"""
from __future__ import annotations

import argparse

import numpy as np

from cmlt.accuracy import ShotFrame, measure, parse_integrator, render_reference

#: the default study: k (tries) and m (inner length) of cmlt's bundles, σ, the inner
#: rule, the large-step probability; pssmlt and bdpt for scale
CONFIGS = [
    "bdpt", "pssmlt", "pssmlt:large_step_probability=0.1",
    "cmlt", "cmlt:tries=2:inner_length=4", "cmlt:tries=4:inner_length=2", "cmlt:tries=4:inner_length=4",
    "cmlt:tries=2:inner_length=8", "cmlt:tries=16:inner_length=4", "cmlt:tries=8:inner_length=1",
    "cmlt:tries=4:inner_length=4:sigma=0.003", "cmlt:tries=4:inner_length=4:sigma=0.03",
    "cmlt:tries=4:inner_length=4:inner=mtm", "cmlt:tries=4:inner_length=4:inner=seed",
    "cmlt:tries=4:inner_length=4:direct_fraction=0", "cmlt:tries=4:inner_length=4:importance=luminance",
]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--res", default="96x96")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--configs", default=None, help="comma-separated integrator[:setting=value...]")
    ap.add_argument("--reference-spp", type=int, default=2048)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    sf = ShotFrame(args.shot, None, (w, h), args.threads)
    ref = render_reference(sf, "bdpt", args.reference_spp, "renders/bench").image
    configs = [c for c in (args.configs.split(",") if args.configs else CONFIGS) if c]
    specs = {c: parse_integrator(c, sf.core) for c in configs}
    errs = {c: [] for c in configs}
    evals = {c: [] for c in configs}
    for seed in range(args.seeds):
        for spec in configs:
            r = sf.render(specs[spec], seconds=args.seconds, seed=seed)
            errs[spec].append(measure(r.image, ref)["relmse"])
            evals[spec].append(r.samples)
    print(f"\n{sf.name}, {w}x{h}, {args.seconds:g} s per render, {args.seeds} seeds, "
          f"{args.threads} threads; relMSE vs BDPT {args.reference_spp} spp\n")
    # the seeds are the same for every configuration: the per-seed ratio to the first
    # configuration removes what a seed's renders share (geometric mean, and the share of
    # seeds where the configuration is better)
    base = np.asarray(errs[configs[0]])
    print(f"| configuration | evaluations / px | relMSE | ± (se) | × {configs[0]}, paired | better in |")
    print("|---|---:|---:|---:|---:|---:|")
    for spec in configs:
        e = np.asarray(errs[spec])
        se = e.std(ddof=1) / np.sqrt(len(e)) if len(e) > 1 else float("nan")
        ratio = float(np.exp(np.mean(np.log(e / base))))
        better = int(np.sum(e < base))
        print(f"| {spec} | {np.mean(evals[spec]):.0f} | {e.mean():.5f} | {se:.5f} | {ratio:.2f} | "
              f"{better}/{len(e)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
