#!/usr/bin/env python3
"""Scaling of ``cmlt render --dask``: wall time of a cmlt sequence on 1 and 2 local
Dask workers (and in one process for reference), bytes moved per frame, and an
estimate for 100 workers from the measured per-frame and per-task costs.

    .venv/bin/python tests/bench/scale.py                       # 24 frames, 64x48
    .venv/bin/python tests/bench/scale.py --frames 1:6 --repeats 1   # quicker

Runs are interleaved (1 worker, 2 workers, one process, then again) and the median of
the repeats is reported; every Dask run is checked bit-identical to the one-process
run. Each worker is one process with one thread; the one-process run uses --threads 2
(both cores). Writes tests/bench/results/scale.md and scale.json.

The estimate: per frame, the client's serial work S (stage read, the temporal
driver's pilot, bootstrap and chain-start coupling, normalisation, writing, scatter
and combine: the frame's wall time minus the time its tasks were running on the
workers) does not shrink with workers; the tasks' work P (worker seconds: core
render + the worker's scene update) divides over N workers, plus a fixed cost F per
task (measured as the growth of P from 2 to 4 tasks per frame) for the 2N tasks of a
frame, plus a per-task dispatch latency L (a no-op task's round trip, measured), and
the client's combine per part C:  T(N) = S + (P_2 + F·(2N − 2))/N + L + 2N·C.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SHOT = ROOT / "sequences" / "camera_pan" / "shot.usda"


def _noop(x):
    return x


def run(shot, frames, out, opts, client):
    from cmlt.shot import render_sequence
    t0, c0 = time.perf_counter(), time.process_time()
    res = render_sequence(str(shot), frames, out, opts, progress=False, quiet=True,
                          client=client)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    recs = [json.load(open(p + ".json")) for p in res.written]
    return wall, cpu, res, recs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", default="1:24")
    ap.add_argument("--res", default="64x48")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--chains", type=int, default=256)
    ap.add_argument("--bootstrap-samples", type=int, default=8192, dest="bootstrap_samples")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", default=str(HERE / "results" / "scale"))
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster

    from cmlt.metrics import load_image
    from cmlt.shot import RenderOptions

    w, h = (int(v) for v in args.res.split("x"))

    def opts(threads):
        return RenderOptions(integrator="cmlt", resolution=(w, h), spp=args.spp,
                             chains=args.chains, bootstrap_samples=args.bootstrap_samples,
                             threads=threads)

    t = time.perf_counter()
    clusters = {n: LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                dashboard_address=":0") for n in (1, 2)}
    clients = {n: Client(c) for n, c in clusters.items()}
    startup = time.perf_counter() - t

    # dispatch latency: round trips of a no-op task, one at a time (2 workers)
    c2 = clients[2]
    c2.submit(_noop, 0, pure=False).result()
    t = time.perf_counter()
    for i in range(100):
        c2.submit(_noop, i, pure=False).result()
    latency = (time.perf_counter() - t) / 100

    tmp = tempfile.mkdtemp(prefix="cmlt-scale-")
    walls = {"one process": [], "1 worker": [], "2 workers": []}
    recs = {}
    cpus = {}               # the client process's CPU seconds per run
    ref_images = None
    for rep in range(args.repeats):
        for name, n in (("1 worker", 1), ("2 workers", 2), ("one process", 0)):
            out = os.path.join(tmp, f"{name.replace(' ', '_')}_{rep}", "f.####.exr")
            wall, cpu, res, rr = run(SHOT, args.frames, out, opts(2 if n == 0 else 1),
                                     clients[n] if n else None)
            walls[name].append(wall)
            cpus.setdefault(name, []).append(cpu)
            recs.setdefault(name, rr)
            images = [load_image(p) for p in res.written]
            if name == "one process" and ref_images is None:
                ref_images = images
            recs[name + " images"] = images
            print(f"{name:12s} run {rep + 1}: {wall:7.2f} s", flush=True)
    identical = all(
        all(np.array_equal(a, b) for a, b in zip(ref_images, recs[f"{n} images"]))
        for n in ("1 worker", "2 workers"))

    med = {k: statistics.median(v) for k, v in walls.items()}
    n_frames = len(recs["2 workers"])

    def per_frame(name, key):
        return [r["stats"]["dask"][key] for r in recs[name]]

    def mean(v):
        return float(np.mean(v)) if v else 0.0

    d2 = {k: mean(per_frame("2 workers", k)) for k in
          ("bytes_to_workers", "bytes_from_workers", "tasks", "scatter_s", "wait_s",
           "combine_s", "part_render_s", "part_task_s", "part_scene_s")}
    d1 = {k: mean(per_frame("1 worker", k)) for k in ("tasks", "part_task_s", "part_render_s")}
    frame_wall2 = mean([r["stats"]["wall_time_s"] for r in recs["2 workers"]])
    # serial on the client: the frame's wall time minus the time its tasks ran
    serial = frame_wall2 - (d2["wait_s"] - d2["scatter_s"])
    fixed = max(0.0, (d2["part_task_s"] - d1["part_task_s"]) / max(1.0, d2["tasks"] - d1["tasks"]))
    combine_per_part = d2["combine_s"] / max(1.0, d2["tasks"])

    def estimate(n):
        return serial + (d1["part_task_s"] + fixed * (2 * n - d1["tasks"])) / n + latency \
            + 2 * n * combine_per_part

    est = {n: estimate(n) for n in (1, 2, 4, 16, 100)}
    # the same model on CPU seconds (robust to the other load on a shared machine):
    # the client's CPU per frame, the workers' CPU per frame at 2 and 4 tasks
    cpu_client = statistics.median(cpus["2 workers"]) / n_frames
    cpu1 = mean(per_frame("1 worker", "part_cpu_s"))
    cpu2 = mean(per_frame("2 workers", "part_cpu_s"))
    fixed_cpu = max(0.0, (cpu2 - cpu1) / max(1.0, d2["tasks"] - d1["tasks"]))

    def estimate_cpu(n):
        return cpu_client + (cpu1 + fixed_cpu * (2 * n - d1["tasks"])) / n + latency

    est_cpu = {n: estimate_cpu(n) for n in (1, 2, 4, 16, 100)}
    summary = {
        "frames": n_frames, "res": [w, h], "spp": args.spp, "chains": args.chains,
        "bootstrap_samples": args.bootstrap_samples, "repeats": args.repeats,
        "wall_s": walls, "median_wall_s": med,
        "ratio_2_over_1_workers": med["2 workers"] / med["1 worker"],
        "ratio_2_workers_over_one_process": med["2 workers"] / med["one process"],
        "bit_identical": identical, "cluster_startup_s": startup,
        "noop_task_latency_s": latency, "per_frame_2_workers": d2, "per_frame_1_worker": d1,
        "frame_wall_2_workers_s": frame_wall2, "client_serial_s": serial,
        "fixed_per_task_s": fixed, "combine_per_part_s": combine_per_part,
        "estimate_frame_s": est,
        "estimate_speedup_100_vs_1": est[1] / est[100],
        "client_cpu_s": cpus, "client_cpu_per_frame_s": cpu_client,
        "worker_cpu_per_frame_s": {"1 worker": cpu1, "2 workers": cpu2},
        "fixed_cpu_per_task_s": fixed_cpu, "estimate_cpu_frame_s": est_cpu,
        "estimate_cpu_ratio_2_over_1": est_cpu[2] / est_cpu[1],
        "estimate_cpu_speedup_100_vs_1": est_cpu[1] / est_cpu[100],
        "machine": {"cpus": os.cpu_count(), "load_avg": os.getloadavg()},
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out + ".json").write_text(json.dumps(summary, indent=1) + "\n")
    md = [
        "# Dask scaling (tests/bench/scale.py)", "",
        f"`{' '.join(['tests/bench/scale.py'] + (argv if argv is not None else sys.argv[1:]))}`: "
        f"cmlt, camera_pan, {n_frames} frames, {w}x{h}, spp {args.spp}, {args.chains} chains, "
        f"bootstrap {args.bootstrap_samples}; LocalCluster workers of 1 thread; the one-process "
        f"run with 2 threads. Median of {args.repeats} interleaved runs; load average at the "
        f"end {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared machine).", "",
        "| run | wall s (median) | runs |", "|---|---|---|"]
    for k in ("one process", "1 worker", "2 workers"):
        md.append(f"| {k} | {med[k]:.1f} | {', '.join(f'{v:.1f}' for v in walls[k])} |")
    md += ["",
           f"2 workers / 1 worker: **{summary['ratio_2_over_1_workers']:.2f}x**; "
           f"2 workers / one process: {summary['ratio_2_workers_over_one_process']:.2f}x. "
           f"Dask images bit-identical to the one-process run: **{identical}**.", "",
           "Per frame (2 workers, mean): "
           f"{d2['tasks']:.0f} tasks, {d2['bytes_to_workers'] / 1e3:.1f} kB to the workers "
           f"(the shared inputs once per worker + the task specs), "
           f"{d2['bytes_from_workers'] / 1e3:.1f} kB back (splat words, accumulators, rows); "
           f"client serial {serial:.3f} s of a {frame_wall2:.3f} s frame; tasks "
           f"{d2['part_task_s']:.3f} worker-s (of it core render {d2['part_render_s']:.3f} s, "
           f"scene update {d2['part_scene_s']:.3f} s); scatter {d2['scatter_s'] * 1e3:.1f} ms, "
           f"combine {d2['combine_s'] * 1e3:.1f} ms.", "",
           f"Per-task costs: no-op round trip {latency * 1e3:.2f} ms; fixed cost of a part "
           f"{fixed * 1e3:.1f} ms (growth of the tasks' worker time from "
           f"{d1['tasks']:.0f} to {d2['tasks']:.0f} parts per frame); combine "
           f"{combine_per_part * 1e3:.2f} ms per part.", "",
           "Estimated frame time T(N) = S + (P + F(2N-2))/N + L + 2N C "
           "(module doc): " + ", ".join(f"N={n}: {v:.3f} s" for n, v in est.items()) +
           f"; 100 workers vs 1: {summary['estimate_speedup_100_vs_1']:.1f}x, bounded by the "
           f"client's serial {serial:.3f} s per frame.", "",
           "The same model on CPU seconds (the other load on this shared machine does not "
           f"enter): client {cpu_client:.3f} CPU-s per frame, workers {cpu1:.3f} / "
           f"{cpu2:.3f} CPU-s per frame at {d1['tasks']:.0f} / {d2['tasks']:.0f} tasks "
           f"(fixed {fixed_cpu * 1e3:.1f} ms per task): "
           + ", ".join(f"N={n}: {v:.3f} s" for n, v in est_cpu.items())
           + f"; 2 workers / 1 worker on idle cores: {est_cpu[2] / est_cpu[1]:.2f}x; "
           f"100 workers vs 1: {est_cpu[1] / est_cpu[100]:.1f}x.", ""]
    Path(args.out + ".md").write_text("\n".join(md))
    print("\n".join(md))
    for c in clients.values():
        c.close()
    for c in clusters.values():
        c.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
