#!/usr/bin/env python3
"""Where the relMSE estimate's error comes from: numerator or denominator (benchmark, not a test).

The estimate of a pixel's relMSE is v / D: v the variance of the pixel's mean from
independent blocks (unbiased), D a stand-in for R^2 + eps (src/cmlt/metrics/error_estimate.py).
This study renders each trial as B independent blocks of --block-spp samples (one render per
block, its own seed: what ``--sampler sobol-blocks`` gives one render), and compares, over
trials and block counts, estimate / measured relMSE for the denominators the package knows
(``DENOMINATORS``: corrected, plug-in, geometric, and the default ``guarded`` -- max(R',
I / 4)^2 + eps with R' the mean without the largest and smallest block), and two more:

- ``oracle``: the reference's own R^2 + eps -- what the numerator alone is worth;
- ``leave-max-out``: (R'')^2 + eps, R'' the mean without the largest block only, unguarded
  (where one block holds all of a pixel's light it is 0 and the term v / eps).

It prints, per denominator, the share of renders whose estimate is within 0.67-1.5x the
measured relMSE and per block count the median [min, max] ratio.

    .venv/bin/python tests/bench/denominator_study.py sequences/caustic_glass/shot.usda \\
        --reference bdpt:16384,pssmlt:16384 --blocks 8,32,128 --trials 6
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from cmlt.accuracy import ShotFrame, parse_integrator, render_reference
from cmlt.metrics.error_estimate import DENOMINATORS, REL_MSE_EPS as EPS, estimate_from_groups

LO, HI = 0.67, 1.5


def estimates(Y: np.ndarray, R: np.ndarray):
    """Image and {denominator: relMSE estimate} from blocks Y (B, H, W, 3) as equal groups
    (cmlt.metrics.error_estimate.estimate_from_groups), and the oracle's."""
    B = Y.shape[0]
    I = Y.mean(0)
    v = Y.var(0, ddof=1) / B
    out = {d: estimate_from_groups(Y, keep_pixels=False, denominator=d).relmse for d in DENOMINATORS}
    out["oracle"] = float((v / (R * R + EPS)).mean())
    lmo = (Y.sum(0) - Y.max(0)) / (B - 1)
    out["leave-max-out"] = float((v / (lmo * lmo + EPS)).mean())
    return I, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--integrator", default="pt")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--blocks", default="8,32,128", help="block counts B per trial")
    ap.add_argument("--block-spp", type=int, default=8, help="samples per block")
    ap.add_argument("--trials", type=int, default=6)
    ap.add_argument("--reference", default="bdpt:4096",
                    help="integrator:spp[,integrator:spp...]: the references' mean")
    ap.add_argument("--cache", default="renders/cache/accuracy")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    w, h = (int(x) for x in args.res.lower().split("x"))
    sf = ShotFrame(args.shot, None, (w, h), args.threads)
    refs = []
    for part in args.reference.split(","):
        integ, spp = part.split(":")
        refs.append(render_reference(sf, integ, int(spp), args.cache).image)
    R = np.mean(refs, 0)
    spec = parse_integrator(args.integrator, sf.core)
    ratios = {}
    for B in (int(x) for x in args.blocks.split(",")):
        for t in range(args.trials):
            Y = np.stack([np.asarray(sf.core.render(sf.scene, sf.settings(
                spec, None, args.block_spp, 100000 * (B + 1) + 1000 * t + b)).image, np.float64)
                for b in range(B)])
            I, est = estimates(Y, R)
            measured = float(((I - R) ** 2 / (R * R + EPS)).mean())
            for name, e in est.items():
                ratios.setdefault(name, {}).setdefault(B, []).append(e / measured)
            print(f"# B {B} trial {t}: measured relMSE {measured:.4g}", file=sys.stderr, flush=True)
    print(f"{sf.name}, {args.integrator}, {w}x{h}, blocks of {args.block_spp} samples, {args.trials} "
          f"trials per block count; reference: mean of {args.reference}\n")
    print("| denominator | in 0.67-1.5x | " + " | ".join(f"B = {B}: median [min, max]" for B in
                                                     sorted(next(iter(ratios.values())))) + " |")
    print("|---|---:|" + "---:|" * len(next(iter(ratios.values()))))
    for name, by_b in ratios.items():
        allr = np.concatenate([np.asarray(x) for x in by_b.values()])
        share = float(np.mean((allr >= LO) & (allr <= HI)))
        cells = [f"{np.median(x):.2f} [{min(x):.2f}, {max(x):.2f}]" for _, x in sorted(by_b.items())]
        print(f"| {name} | {share:.0%} ({len(allr)}) | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
