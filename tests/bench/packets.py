#!/usr/bin/env python3
"""Packet versus scalar tracing of cmlt's candidate bundles (benchmark, not a test).

Renders one frame with integrator cmlt with packets on (RenderSettings.packets = True:
a bundle's camera rays, subpath bounces and shadow rays answered by Embree's
rtcIntersect4/8/16 and rtcOccluded4/8/16) and off (the same queries one by one), checks
that the two images are bit-identical, and reports per k (tries):

- whole render: wall time of the frame (best of --repeats) and its speed-up;
- bundles only: CPU time spent evaluating the inner chains' bundles (bundle_busy_s)
  and, of it, inside BVH queries (bundle_trace_s) — the part packets can speed up;
- packet share: of all rays of the frame, those answered by a packet (packet_ray_share),
  and of those, the share of visibility (shadow) rays.

The configurations alternate (scalar, packet, scalar, ...) so a change in the machine's
load hits both alike.

    .venv/bin/python tests/bench/packets.py sequences/cornell/shot.usda --res 96x96 --spp 256
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from cmlt.accuracy import ShotFrame, parse_integrator


def measure(sf, args, k):
    """{packets: (best wall s, image, stats of that run)} for packets off and on."""
    out = {}
    for _ in range(args.repeats):
        for packets in (False, True):
            # the chains on every path by default (auto would leave cornell to the direct
            # pass); --mlt-paths auto measures the frame as cmlt renders it by default
            spec = parse_integrator(f"cmlt:tries={k}:inner={args.inner}:packets={int(packets)}"
                                    f":inner_length={args.inner_length}:mlt_paths={args.mlt_paths}", sf.core)
            st = sf.settings(spec, spp=args.spp, seed=args.seed)
            t0 = time.perf_counter()
            r = sf.core.render(sf.scene, st)
            dt = time.perf_counter() - t0
            if packets not in out or dt < out[packets][0]:
                out[packets] = (dt, np.asarray(r.image), r.stats)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot", nargs="+")
    ap.add_argument("--res", default="96x96")
    ap.add_argument("--spp", type=int, default=256, help="path evaluations per pixel")
    ap.add_argument("--tries", default="4,8,16", help="k values to measure")
    ap.add_argument("--inner-length", type=int, default=8, help="m")
    ap.add_argument("--inner", default="bundle")
    ap.add_argument("--mlt-paths", default="all",
                    help="the paths the chains render: all (every path: the bundles' study) or auto "
                         "(cmlt's default: the caustic paths where there are any; the rest is the "
                         "path-traced direct pass, which traces in packets either way)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3, help="best of N timings")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    rows = []
    for shot in args.shot:
        sf = ShotFrame(shot, None, (w, h), args.threads)
        core = sf.core
        print(f"# {shot} {w}x{h}, {args.spp} evaluations/pixel, chains on {args.mlt_paths} paths, inner {args.inner}, "
              f"m={args.inner_length}, {args.threads} threads, packet width "
              f"{core.max_packet_width() if hasattr(core, 'max_packet_width') else '?'}",
              flush=True)
        for k in (int(v) for v in args.tries.split(",")):
            m = measure(sf, args, k)
            (ts, a, sa), (tp, b, sb) = m[False], m[True]
            row = dict(
                shot=Path(shot).parent.name or shot, k=k,
                wall_scalar=ts, wall_packet=tp, wall_speedup=ts / tp,
                bundle_busy_scalar=sa["bundle_busy_s"], bundle_busy_packet=sb["bundle_busy_s"],
                bundle_trace_scalar=sa["bundle_trace_s"], bundle_trace_packet=sb["bundle_trace_s"],
                packet_share=sb["packet_ray_share"],
                shadow_share=sb["packet_shadow_rays"] / max(sb["packet_rays"], 1),
                bundle_share=sb["bundle_rays"] / max(sb["rays"], 1),
                identical=bool(np.array_equal(a, b)) and sa["rays"] == sb["rays"])
            row["busy_speedup"] = row["bundle_busy_scalar"] / max(row["bundle_busy_packet"], 1e-12)
            row["trace_speedup"] = row["bundle_trace_scalar"] / max(row["bundle_trace_packet"], 1e-12)
            rows.append(row)
            print(f"k={k:>2}: wall {ts:.3f} s -> {tp:.3f} s ({row['wall_speedup']:.2f}x); "
                  f"bundles {row['bundle_busy_scalar']:.3f} -> {row['bundle_busy_packet']:.3f} CPU s "
                  f"({row['busy_speedup']:.2f}x), their BVH queries "
                  f"{row['bundle_trace_scalar']:.3f} -> {row['bundle_trace_packet']:.3f} "
                  f"({row['trace_speedup']:.2f}x); rays in packets {row['packet_share']:.0%} "
                  f"(shadow {row['shadow_share']:.0%}), in bundles {row['bundle_share']:.0%}; "
                  f"identical {row['identical']}", flush=True)
    if args.markdown:
        print("\n| shot | k | whole frame | bundles (CPU) | bundles' BVH queries | rays in packets "
              "| of them shadow | identical |")
        print("|---|---:|---:|---:|---:|---:|---:|:---:|")
        for r in rows:
            print(f"| {r['shot']} | {r['k']} | {r['wall_speedup']:.2f}× | {r['busy_speedup']:.2f}× "
                  f"| {r['trace_speedup']:.2f}× | {r['packet_share']:.0%} | {r['shadow_share']:.0%} "
                  f"| {'yes' if r['identical'] else 'NO'} |")
    return 0 if all(r["identical"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
