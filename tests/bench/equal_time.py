#!/usr/bin/env python3
"""Accuracy against time: relMSE of each integrator at equal wall time.

For one frame of a shot, renders a converged reference once (cached under
``renders/bench/``), then renders with each integrator under each time budget
(the core's own time budget, RenderSettings.time_budget: every integrator stops
when the wall time is used up, fixed passes included) and measures the relative
MSE against the reference:

    relMSE = mean over pixels and channels of (I - R)^2 / (R^2 + 1e-2)

All integrators run side by side in one process on the same machine state, so
the ratios between them are what to read; absolute seconds depend on the load.

    python tests/bench/equal_time.py sequences/cornell/shot.usda --seconds 2,4,8 \\
        --integrators pt,bdpt --json renders/bench/cornell.json --plot renders/bench/cornell.png
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np


def relmse(img: np.ndarray, ref: np.ndarray) -> float:
    return float(np.mean((img - ref) ** 2 / (ref ** 2 + 1e-2)))


def build_scene(shot: str, frame: float, res):
    from cmlt.shot.bridge import SceneBridge
    from cmlt.usd import load_frame, open_stage
    import cmlt._core as core

    stage = open_stage(shot)
    fs = load_frame(stage, frame, resolution=res)
    bridge = SceneBridge(core)
    scene = bridge.update(fs)
    return core, stage, bridge, scene, fs.resolution


def settings(core, integrator, spp, res, seed, threads, extra):
    st = core.RenderSettings()
    st.width, st.height = res
    st.spp, st.seed, st.threads, st.integrator = int(spp), int(seed), int(threads), integrator
    for key, value in extra.items():
        if hasattr(st, key):
            setattr(st, key, value)
    return st


def timed_render(core, scene, st):
    t0 = time.perf_counter()
    r = core.render(scene, st)
    return r, time.perf_counter() - t0


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
    core, stage, _, scene, res = build_scene(args.shot, args.frame if args.frame is not None
                                             else stage_start(args.shot), (w, h))
    budgets = [float(s) for s in args.seconds.split(",")]
    integrators = [s.strip() for s in args.integrators.split(",") if s.strip()]

    # -- reference (cached) -------------------------------------------------------
    cache = Path("renders/bench")
    cache.mkdir(parents=True, exist_ok=True)
    key = f"{Path(args.shot).parent.name}_{w}x{h}_{args.reference_integrator}_{args.reference_spp}.npy"
    ref_path = cache / key
    if ref_path.exists():
        ref = np.load(ref_path)
    else:
        print(f"reference: {args.reference_integrator} {args.reference_spp} spp ...", flush=True)
        r, dt = timed_render(core, scene, settings(core, args.reference_integrator, args.reference_spp,
                                                   (w, h), 12345, args.threads, {}))
        ref = np.asarray(r.image, dtype=np.float64)
        np.save(ref_path, ref)
        print(f"reference done in {dt:.1f} s", flush=True)

    rows = []
    for integ in integrators:
        name, _, opts = integ.partition(":")        # e.g. cmlt:tries=4:inner_length=2
        extra = {}
        for kv in [x for x in opts.split(":") if x]:
            k, v = kv.split("=")
            default = getattr(core.RenderSettings(), k)
            extra[k] = (v == "1") if isinstance(default, bool) else type(default)(v)
        for budget in budgets:
            st = settings(core, name, 1 << 24, (w, h), args.seed, args.threads, extra)
            st.time_budget = budget
            r, dt = timed_render(core, scene, st)
            img = np.asarray(r.image, dtype=np.float64)
            stats = dict(r.stats)
            evals = stats.get("path_evaluations", stats.get("samples", 0))
            row = {
                "integrator": integ, "budget_s": budget, "spp": float(evals) / (w * h),
                "time_s": dt, "relmse": relmse(img, ref),
                "mean_ratio": float(img.mean() / max(ref.mean(), 1e-12)),
                "samples_per_s": float(evals) / max(dt, 1e-9),
                "rays_per_s": float(stats.get("rays", 0)) / max(dt, 1e-9),
                "trace_fraction": float(stats.get("trace_s", 0.0)) / max(float(stats.get("busy_s", 0.0)), 1e-9),
            }
            rows.append(row)
            print(f"{integ:>24} budget {budget:6.1f}s  per px {row['spp']:8.1f}  time {dt:6.2f}s  "
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
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(5, 4))
        for integ in integrators:
            pts = [(r["time_s"], r["relmse"]) for r in rows if r["integrator"] == integ]
            ax.loglog(*zip(*pts), "o-", label=integ)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("relMSE")
        ax.set_title(Path(args.shot).parent.name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
    return 0


def stage_start(shot: str) -> float:
    from cmlt.usd import open_stage
    return float(open_stage(shot).GetStartTimeCode())


if __name__ == "__main__":
    sys.exit(main())
