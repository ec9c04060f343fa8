#!/usr/bin/env python3
"""The pixel samplers at equal samples per pixel: relMSE against a converged reference
and the error estimate's calibration (estimate / measured relMSE).

Samplers (RenderSettings::sampler): ``sobol`` (one Owen-scrambled Sobol sequence per
pixel), ``sobol-blocks`` (a sequence of its own per block of 8 samples: what a frame with
a target error renders) and ``independent``; with ``--replicates R,...`` also R renders of
N/R samples with their own seeds (own scrambles) averaged — the study that chose the
block size before sobol-blocks existed (R renders of N/R samples are R blocks of N/R).

    .venv/bin/python tests/bench/sampler_blocks.py sequences/cornell/shot.usda --res 64x64 \\
        --spp 32,128,512 --seeds 6

Prints a markdown table per shot: median relMSE over the seeds, its ratio to
independent samples', and the median and range of estimate / measured (the film's
variance of the mean through cmlt.metrics.error_estimate.estimate_from_variance; the
replicates have no estimate).
"""
from __future__ import annotations

import argparse
import statistics
import sys

import numpy as np

from cmlt.accuracy import ShotFrame, estimate_from_variance, measure, parse_integrator, render_reference


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shots", nargs="+")
    ap.add_argument("--res", default="64x64")
    ap.add_argument("--integrator", default="pt")
    ap.add_argument("--spp", default="32,128,512")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--samplers", default="sobol,sobol-blocks,independent")
    ap.add_argument("--replicates", default="", help="R,... : R sobol renders of spp/R averaged")
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cache", default="renders/cache/accuracy")
    a = ap.parse_args(argv)
    res = tuple(int(v) for v in a.res.split("x"))
    spps = [int(v) for v in a.spp.split(",")]
    reps = [int(v) for v in a.replicates.split(",") if v]
    for shot in a.shots:
        sf = ShotFrame(shot, resolution=res, threads=a.threads)
        ref = render_reference(sf, "bdpt", a.reference_spp, cache_dir=a.cache).image
        print(f"\n{shot} {a.res} {a.integrator}, seeds 1..{a.seeds}, bdpt {a.reference_spp}-spp reference\n")
        print("| spp | sampler | relMSE (median) | × independent | estimate / measured: median (range) |")
        print("|---:|---|---:|---:|---:|")
        for spp in spps:
            rows, base = [], None
            configs = [(s, 1) for s in a.samplers.split(",")] + [("sobol", r) for r in reps]
            for sampler, R in configs:
                spec = parse_integrator(f"{a.integrator}:sampler={sampler}", sf.core)
                errs, ratios = [], []
                for seed in range(1, a.seeds + 1):
                    if R == 1:
                        run = sf.render(spec, spp=spp, seed=seed)
                        m = measure(run.image, ref)["relmse"]
                        ratios.append(estimate_from_variance(run.image, run.variance).relmse / m)
                    else:
                        img = np.mean([sf.render(spec, spp=spp // R, seed=1000 * seed + r).image
                                       for r in range(R)], axis=0)
                        m = measure(img, ref)["relmse"]
                    errs.append(m)
                med = statistics.median(errs)
                name = sampler if R == 1 else f"{R} sobol renders of {spp // R}"
                rows.append((name, med, ratios))
                if sampler == "independent" and R == 1:
                    base = med
            for name, med, ratios in rows:
                rel = f"{base / med:.2f}× lower" if base else ""
                est = (f"{statistics.median(ratios):.2f} ({min(ratios):.2f}–{max(ratios):.2f})"
                       if ratios else "—")
                print(f"| {spp} | {name} | {med:.4g} | {rel} | {est} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
