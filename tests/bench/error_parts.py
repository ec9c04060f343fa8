#!/usr/bin/env python3
"""Where a Metropolis frame's error is: the chains' region against the rest.

pssmlt and cmlt add two estimators: the chains (the paths of the partition they render,
``--mlt-paths``) and the path-traced direct pass (every other path). This bench renders
each configuration over the same seeds, takes the chains' part of each render (image
minus ``RenderResult.direct``), and splits every render's relMSE against the converged
reference into the pixels where the chains carry light — their mean part over the first
configuration's renders above 2 % of (reference + 0.1) — and the rest. Configurations
without a direct pass (pt, bdpt) are split by the same mask, so their errors compare
region by region.

    .venv/bin/python tests/bench/error_parts.py sequences/caustic_glass/shot.usda \\
        --configs cmlt,pssmlt,pt --spp 512 --seeds 3000:3005 --res 128x128

Prints per render: the relMSE, its chains'-region and rest parts (they add up to it),
and per configuration the means; the chains' share of the reference's light.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))

#: a pixel is in the chains' region where their mean part exceeds this share of (R + 0.1)
REGION_SHARE = 0.02


def _relmse_terms(img: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return ((img - ref) ** 2 / (ref * ref + 1e-2)).mean(axis=2)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--configs", default="cmlt,pssmlt,pt",
                    help="cmlt.accuracy.parse_integrator specs; the first must have chains")
    ap.add_argument("--spp", type=int, default=512, help="samples or path evaluations per pixel")
    ap.add_argument("--seeds", default="3000:3005", help="first:last")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cache", default=str(ROOT / "renders" / "cache" / "accuracy"))
    args = ap.parse_args(argv)
    from cmlt.accuracy import ShotFrame, parse_integrator, render_reference

    w, h = (int(v) for v in args.res.lower().split("x"))
    a, b = (int(v) for v in args.seeds.split(":"))
    seeds = list(range(a, b + 1))
    configs = [c for c in args.configs.split(",") if c]
    sf = ShotFrame(args.shot, None, (w, h), args.threads)
    ref = np.asarray(render_reference(sf, "bdpt", args.reference_spp, args.cache).image, np.float64)[..., :3]

    runs = {}
    for cfg in configs:
        spec = parse_integrator(cfg, sf.core)
        out = []
        for seed in seeds:
            r = sf.core.render(sf.scene, sf.settings(spec, None, args.spp, seed))
            img = np.asarray(r.image, np.float64)[..., :3]
            direct = getattr(r, "direct", None)
            direct = None if direct is None or np.asarray(direct).size == 0 else np.asarray(direct, np.float64)[..., :3]
            out.append((img, direct, float(dict(r.stats)["time_s"])))
        runs[cfg] = out
    first = runs[configs[0]]
    if first[0][1] is None:
        raise SystemExit(f"{configs[0]}: no direct pass, so no chains' part to find the region by")
    chains = np.mean([img - d for img, d, _ in first], axis=0)
    region = chains.mean(axis=2) > REGION_SHARE * (ref.mean(axis=2) + 0.1)
    print(f"{args.shot}, {args.spp} per pixel, {w}x{h}: the chains' region is {int(region.sum())} of "
          f"{region.size} pixels; the chains carry {chains.sum() / ref.sum():.2%} of the reference's light")
    print("| configuration | seed | relMSE | chains' region | rest | time s |")
    print("|---|---:|---:|---:|---:|---:|")
    summary = []
    for cfg in configs:
        parts = []
        for (img, _, t), seed in zip(runs[cfg], seeds):
            e = _relmse_terms(img, ref)
            inside, rest = float(e[region].sum() / e.size), float(e[~region].sum() / e.size)
            parts.append((inside + rest, inside, rest, t))
            print(f"| {cfg} | {seed} | {inside + rest:.3g} | {inside:.3g} | {rest:.3g} | {t:.2f} |")
        m = np.mean(parts, axis=0)
        med = np.median(parts, axis=0)
        summary.append((cfg, m, med))
    print("\n| configuration | mean relMSE | chains' region | rest | median relMSE | median region | median rest | time s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for cfg, m, med in summary:
        print(f"| {cfg} | {m[0]:.3g} | {m[1]:.3g} | {m[2]:.3g} | {med[0]:.3g} | {med[1]:.3g} | {med[2]:.3g} | {m[3]:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
