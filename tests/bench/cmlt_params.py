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
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from equal_time import build_scene, relmse, settings, stage_start  # noqa: E402

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


def parse(core, spec):
    name, _, opts = spec.partition(":")
    extra = {}
    for kv in [x for x in opts.split(":") if x]:
        k, v = kv.split("=")
        default = getattr(core.RenderSettings(), k)
        extra[k] = (v == "1") if isinstance(default, bool) else type(default)(v)
    return name, extra


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
    core, _, _, scene, res = build_scene(args.shot, stage_start(args.shot), (w, h))
    cache = Path("renders/bench")
    cache.mkdir(parents=True, exist_ok=True)
    ref_path = cache / f"{Path(args.shot).parent.name}_{w}x{h}_bdpt_{args.reference_spp}.npy"
    if ref_path.exists():
        ref = np.load(ref_path)
    else:
        print(f"reference: bdpt {args.reference_spp} spp ...", flush=True)
        ref = np.asarray(core.render(scene, settings(core, "bdpt", args.reference_spp, res, 12345,
                                                     args.threads, {})).image, np.float64)
        np.save(ref_path, ref)
    configs = [c for c in (args.configs.split(",") if args.configs else CONFIGS) if c]
    errs = {c: [] for c in configs}
    evals = {c: [] for c in configs}
    for seed in range(args.seeds):
        for spec in configs:
            name, extra = parse(core, spec)
            st = settings(core, name, 1 << 24, res, seed, args.threads, extra)
            st.time_budget = args.seconds
            r = core.render(scene, st)
            errs[spec].append(relmse(np.asarray(r.image, np.float64), ref))
            stats = dict(r.stats)
            evals[spec].append(float(stats.get("path_evaluations", stats.get("samples", 0))) / (w * h))
    print(f"\n{Path(args.shot).parent.name}, {w}x{h}, {args.seconds:g} s per render, {args.seeds} seeds, "
          f"{args.threads} threads; relMSE vs BDPT {args.reference_spp} spp\n")
    print("| configuration | evaluations / px | relMSE | ± (se) |")
    print("|---|---:|---:|---:|")
    for spec in configs:
        e = np.asarray(errs[spec])
        se = e.std(ddof=1) / np.sqrt(len(e)) if len(e) > 1 else float("nan")
        print(f"| {spec} | {np.mean(evals[spec]):.0f} | {e.mean():.5f} | {se:.5f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
