#!/usr/bin/env python3
"""How much of two integrators' error is theirs, and how much they share (benchmark, not
a test).

pssmlt and cmlt render a frame from the same seed with the same bootstrap samples (keyed
(seed, bootstrap, i): the same chain starts and the same first estimate of b) and, with
``--mlt-paths caustics``, the same direct pass. Their errors E_A = I_A − R and E_B = I_B − R
then split into a part both have, (E_A + E_B) / 2, and a part that differs,
(E_A − E_B) / 2: the second is what the chains' kernels decide, the first is what no
kernel can change. Per seed and on average, this prints both integrators' relMSE
(``measure``: mean over pixels and channels of (I − R)² / (R² + 10⁻²)), the shared and
the differing part, and, from the seeds' spread, what the reference's own error and any
bias add (the error of the mean over seeds minus its variance).

    .venv/bin/python tests/bench/shared_error.py sequences/caustic_glass/shot.usda \\
        --res 128x128 --spp 256 --seeds 4 [--pair cmlt,pssmlt] [--cmlt-args mlt_paths=all]
"""
from __future__ import annotations

import argparse

import numpy as np

from cmlt.accuracy import ShotFrame, parse_integrator, render_reference


def weighted(e: np.ndarray, ref: np.ndarray) -> float:
    """relMSE of an error image e against the reference ref (the accuracy curves' measure)."""
    return float(np.mean(e[..., :3] ** 2 / (ref[..., :3] ** 2 + 1e-2)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--spp", type=int, default=256, help="path evaluations per pixel of every render")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--pair", default="cmlt,pssmlt", help="the two integrators (integrator[:setting=value...])")
    ap.add_argument("--cmlt-args", default="", help="settings added to both, e.g. mlt_paths=all")
    ap.add_argument("--reference-spp", type=int, default=4096)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    sf = ShotFrame(args.shot, None, (w, h), args.threads)
    ref = render_reference(sf, "bdpt", args.reference_spp, "renders/cache/accuracy").image
    extra = (":" + args.cmlt_args.replace(",", ":")) if args.cmlt_args else ""
    names = [n.strip() for n in args.pair.split(",")]
    if len(names) != 2:
        ap.error("--pair: two integrators, e.g. cmlt,pssmlt")
    specs = [parse_integrator(n + extra, sf.core) for n in names]
    print(f"\n{sf.name}, {w}x{h}, {args.spp} evaluations/px, {args.threads} threads, "
          f"{names[0]} and {names[1]}{' (' + args.cmlt_args + ')' if args.cmlt_args else ''}; "
          f"reference bdpt {args.reference_spp} spp\n")
    print(f"| seed | {names[0]} | {names[1]} | shared | differing | differing / {names[1]} |")
    print("|---:|---:|---:|---:|---:|---:|")
    rows, means = [], []
    for seed in range(1, args.seeds + 1):
        imgs = [np.asarray(sf.render(s, spp=args.spp, seed=seed).image, dtype=np.float64) for s in specs]
        ea, eb = imgs[0] - ref, imgs[1] - ref
        row = (weighted(ea, ref), weighted(eb, ref), weighted((ea + eb) / 2, ref), weighted((ea - eb) / 2, ref))
        rows.append(row)
        means.append((imgs[0] + imgs[1]) / 2)
        print(f"| {seed} | {row[0]:.5f} | {row[1]:.5f} | {row[2]:.5f} | {row[3]:.5f} | {row[3] / row[1]:.2f} |",
              flush=True)
    r = np.asarray(rows)
    print(f"| mean | {r[:, 0].mean():.5f} | {r[:, 1].mean():.5f} | {r[:, 2].mean():.5f} | {r[:, 3].mean():.5f} | "
          f"{r[:, 3].mean() / r[:, 1].mean():.2f} |")
    if len(means) > 1:
        m = np.mean(means, axis=0)
        spread = float(np.mean(np.var(means, axis=0, ddof=1)[..., :3] / len(means) / (ref[..., :3] ** 2 + 1e-2)))
        print(f"\nmean over seeds against the reference {weighted(m - ref, ref):.5f}, of which the seeds' "
              f"spread {spread:.5f}: the reference's own error and any bias about "
              f"{weighted(m - ref, ref) - spread:.5f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
