#!/usr/bin/env python3
"""Packet versus scalar tracing of cmlt's candidate bundles (benchmark, not a test).

Renders one frame with integrator cmlt twice per configuration — the bundle's camera
rays traced as Embree packets (rtcIntersect4/8/16, RenderSettings.packets = True) and
one by one (packets = False) — checks the images are bit-identical, and reports the
wall time, rays/s and the speed-up. The camera rays are the only rays traced as
packets (shadow and bounce rays stay scalar), so the end-to-end speed-up is bounded by
the camera rays' share of the work (printed as camera share).

    .venv/bin/python tests/bench/packets.py sequences/cornell/shot.usda --res 96x96 --spp 256
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from equal_time import build_scene, settings, stage_start  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot")
    ap.add_argument("--res", default="96x96")
    ap.add_argument("--spp", type=int, default=256, help="path evaluations per pixel")
    ap.add_argument("--tries", default="4,8,16", help="k values to measure")
    ap.add_argument("--inner", default="bundle")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3, help="best of N timings")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    core, _, _, scene, res = build_scene(args.shot, stage_start(args.shot), (w, h))
    print(f"max packet width {core.max_packet_width() if hasattr(core, 'max_packet_width') else '?'}; "
          f"{args.shot} {w}x{h}, {args.spp} evaluations/pixel, inner {args.inner}, {args.threads} threads")
    print(f"{'k':>3} {'scalar s':>9} {'packet s':>9} {'speed-up':>9} {'scalar Mrays/s':>15} "
          f"{'packet Mrays/s':>15} {'camera share':>13} {'identical':>9}")
    for k in (int(v) for v in args.tries.split(",")):
        out = {}
        for packets in (False, True):
            best, img, stats = None, None, None
            for _ in range(args.repeats):
                st = settings(core, "cmlt", args.spp, res, 1, args.threads,
                              {"tries": k, "inner": args.inner, "packets": packets,
                               "bootstrap_samples": 20000})
                t0 = time.perf_counter()
                r = core.render(scene, st)
                dt = time.perf_counter() - t0
                if best is None or dt < best:
                    best, img, stats = dt, np.asarray(r.image), r.stats
            out[packets] = (best, img, stats)
        (ts, a, sa), (tp, b, sb) = out[False], out[True]
        same = bool(np.array_equal(a, b))
        print(f"{k:>3} {ts:>9.3f} {tp:>9.3f} {ts / tp:>8.2f}x {sa['rays'] / ts / 1e6:>15.2f} "
              f"{sb['rays'] / tp / 1e6:>15.2f} {sa['camera_rays'] / sa['rays']:>13.2f} {str(same):>9}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
