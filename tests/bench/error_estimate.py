#!/usr/bin/env python3
"""Calibration of the in-render error estimate (cmlt.metrics.error_estimate) against references.

For each shot, integrator and budget, renders are repeated with fresh seeds; each
render's *estimated* relMSE (no reference used) is compared with its relMSE *measured*
against a converged reference (bdpt, cached by cmlt.accuracy.render_reference). Two ways
of getting the estimate:

* ``variance`` (pt, bdpt): one render; its per-pixel variance of the mean
  (RenderResult.variance: the film's accumulators over sample passes) -> estimate_from_variance;
* ``groups`` (every integrator): G renders with seeds s..s+G-1 emulate one render whose
  samples (pt, bdpt) or chains (pssmlt, cmlt) are split into G independent groups; the
  image is their mean -> estimate_from_groups (jackknife standard error). This is what the
  core will hand over in one render (RenderResult.group_images); with seeds the groups
  also have independent bootstraps and normalisations, which one render's chain groups
  share (the shared scale term of estimate.py covers that);
* ``render`` (every integrator): one render's own estimate, what a sidecar records and
  ``--target-error`` stops on (cmlt.metrics.error_estimate.estimate_render): pt/bdpt from
  their variance, pssmlt/cmlt from the chain groups of that one render (RenderResult.
  group_images: chains from disjoint bootstrap start samples, one bootstrap and b).

The measured relMSE includes the reference's own error (``floor``, estimated from the
reference's variance); ``measured - floor`` is the column to read where the floor is not
small. Writes OUT/calibration.csv (every render) and prints the summary: per (shot,
integrator, mode) the median ratio estimated / measured and the share of renders in
0.67-1.5x (also written to OUT/calibration.md).

    .venv/bin/python tests/bench/error_estimate.py --shots cornell,caustic_glass --res 64x64 \\
        --repeats 8 --out tests/bench/results/accuracy
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time

import numpy as np

from cmlt.accuracy import (ShotFrame, estimate_from_groups, estimate_from_variance, measure,
                           parse_integrator, render_reference)
from cmlt.metrics.error_estimate import DENOMINATORS, estimate_render

#: sample budgets (samples or path evaluations per pixel) per render / per group
VARIANCE_SPP = {"pt": (16, 32, 64, 128, 256), "bdpt": (8, 16, 32, 64, 128)}
GROUP_SPP = {"pt": (2, 4, 8, 16, 32), "bdpt": (1, 2, 4, 8, 16),
             "pssmlt": (16, 32, 64, 128), "cmlt": (16, 32, 64, 128)}
#: budgets of the ``render`` mode: one render, its own estimate
RENDER_SPP = {"pt": (16, 32, 64, 128, 256), "bdpt": (8, 16, 32, 64, 128),
              "pssmlt": (128, 256, 512, 1024), "cmlt": (128, 256, 512, 1024)}
LO, HI = 0.67, 1.5


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shots", default="cornell,caustic_glass")
    ap.add_argument("--res", default="64x64")
    ap.add_argument("--integrators", default="pt,bdpt,pssmlt,cmlt")
    ap.add_argument("--modes", default="variance,groups")
    ap.add_argument("--groups", type=int, default=8, help="G of the groups mode")
    ap.add_argument("--repeats", type=int, default=8, help="renders per (integrator, budget)")
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--seed-base", type=int, default=0,
                    help="added to every render's seed (variance 1000+, render 2000+, groups "
                         "100000+): another draw of the same renders, e.g. to check on seeds "
                         "a choice was not made on")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cache", default="renders/cache/accuracy")
    ap.add_argument("--out", default="renders/bench/error_estimate")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    os.makedirs(args.out, exist_ok=True)
    rows = []
    t_start = time.perf_counter()
    for shot in [s for s in args.shots.split(",") if s]:
        sf = ShotFrame(f"sequences/{shot}/shot.usda", None, (w, h), args.threads)
        ref = render_reference(sf, "bdpt", args.reference_spp, args.cache)
        floor = ref.relmse_floor
        print(f"# {shot} {w}x{h}: reference bdpt {args.reference_spp} spp, its own relMSE "
              f"{floor:.3g} ± {ref.relmse_floor_stderr:.2g}", flush=True)
        for integ in [s for s in args.integrators.split(",") if s]:
            spec = parse_integrator(integ, sf.core)
            for mode in [m for m in args.modes.split(",") if m]:
                if mode == "variance" and spec.name not in VARIANCE_SPP:
                    continue
                budgets = {"variance": VARIANCE_SPP, "render": RENDER_SPP}.get(mode, GROUP_SPP)[spec.name]
                for spp in budgets:
                    for rep in range(args.repeats):
                        ests = {}
                        if mode == "variance":
                            seed = args.seed_base + 1000 + rep
                            r = sf.render(spec, spp=spp, seed=seed)
                            image = r.image
                            for d in DENOMINATORS:
                                ests[d] = estimate_from_variance(image, r.variance, passes=spp,
                                                                 keep_pixels=False, denominator=d)
                            total = spp
                        elif mode == "render":
                            seed = args.seed_base + 2000 + rep
                            st = sf.settings(spec, None, spp, seed)
                            r = sf.core.render(sf.scene, st)
                            image = np.asarray(r.image, np.float64)
                            for d in DENOMINATORS:
                                ests[d] = estimate_render(r, denominator=d)[0]
                            total = spp
                        else:
                            G = args.groups
                            runs = [sf.render(spec, spp=spp, seed=args.seed_base + 100000 + rep * G + g)
                                    for g in range(G)]
                            Y = np.stack([x.image for x in runs])
                            image = Y.mean(0)
                            for d in DENOMINATORS:
                                ests[d] = estimate_from_groups(Y, keep_pixels=False, denominator=d)
                            total = spp * G
                        m = measure(image, ref.image)["relmse"]
                        row = {"shot": shot, "integrator": integ, "mode": mode, "spp": total,
                               "repeat": rep, "measured": m, "floor": floor}
                        for d, est in ests.items():
                            # None: the render has no estimate (pssmlt/cmlt whose chains
                            # started from too few distinct bootstrap samples for
                            # independent groups); counted outside the band
                            row[f"est_{d}"] = est.relmse if est is not None else math.nan
                            row[f"se_{d}"] = est.stderr if est is not None else math.nan
                            row[f"ratio_{d}"] = (est.relmse / m if m > 0 else math.nan) if est is not None else math.nan
                        rows.append(row)
                    sel = [x for x in rows if (x["shot"], x["integrator"], x["mode"], x["spp"])
                           == (shot, integ, mode, total)]
                    parts = []
                    for d in DENOMINATORS:
                        rat = np.array([x[f"ratio_{d}"] for x in sel])
                        parts.append(f"{d} {np.nanmedian(rat):.2f} [{np.nanmin(rat):.2f}, {np.nanmax(rat):.2f}] "
                                     f"{np.mean((rat >= LO) & (rat <= HI)):.0%}")
                    print(f"{shot:>14} {integ:>6} {mode:>8} spp {total:5d}: measured "
                          f"{np.mean([x['measured'] for x in sel]):.4g}; est./meas. median "
                          f"[min, max] in-band: " + "; ".join(parts), flush=True)
    path = os.path.join(args.out, "calibration.csv")
    with open(path, "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]))
        wr.writeheader()
        for r in rows:
            wr.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    text = summary(rows)
    with open(os.path.join(args.out, "calibration.md"), "w") as f:
        f.write(f"`tests/bench/error_estimate.py {' '.join(sys.argv[1:] if argv is None else argv)}`"
                f" ({len(rows)} renders, {time.perf_counter() - t_start:.0f} s)\n\n" + text)
    print(f"\n{len(rows)} renders in {time.perf_counter() - t_start:.0f} s; wrote {path}\n")
    print(text)
    return 0


def summary(rows) -> str:
    """Markdown: per (shot, integrator, mode), the median ratio estimated / measured and
    the renders in the band, for each denominator."""
    out = ["| shot | integrator | estimate from | renders | no estimate | measured relMSE | "
           + " | ".join(f"{d}: median, in {LO}-{HI}x" for d in DENOMINATORS) + " |",
           "|---|---|---|---:|---:|---:|" + "---:|" * len(DENOMINATORS)]
    keys = []
    for r in rows:
        k = (r["shot"], r["integrator"], r["mode"])
        if k not in keys:
            keys.append(k)
    for k in keys:
        sel = [r for r in rows if (r["shot"], r["integrator"], r["mode"]) == k]
        meas = [r["measured"] for r in sel]
        cells = []
        for d in DENOMINATORS:
            rat = np.array([r[f"ratio_{d}"] for r in sel])
            cells.append(f"{np.nanmedian(rat):.2f}, {np.mean((rat >= LO) & (rat <= HI)):.0%}")
        missing = sum(1 for r in sel if math.isnan(r[f"est_{DENOMINATORS[0]}"]))
        out.append(f"| {k[0]} | {k[1]} | {k[2]} | {len(sel)} | {missing} | {min(meas):.2g}-{max(meas):.2g} | "
                   + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.exit(main())
