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

The estimates (module doc of cmlt.shot.distributed: a frame is one preparation task
and N part tasks, submitted two frames ahead, so the client's work, the preparations
and the parts of consecutive frames overlap). Per frame: the client's CPU seconds C
(the frame loop, its scene, writing, the combine, and the in-process scheduler),
growing by c per task (a no-op task's client CPU, measured); the preparation's CPU
seconds R (a chain from frame to frame: no frame's parts start before its
preparation); the parts' worker CPU seconds W at one part per frame, plus a fixed cost
F per further part (the growth of W from 1 to 2 parts per frame). On a cluster
(the client on its own core, N worker cores, frames pipelined):

    T(N) = max(C + c·(N + 1), R, (R + W + F·(N − 1)) / N)

with N parts per frame (``--dask-parts N``), and with one part per frame and frames side
by side (the default while the frames left cover the workers, or ``--dask-parts 1``;
enough frames in flight) max(C + 2c, R, (R + W) / N);

and on this machine's 2 cores, which the client shares with the workers:
T(1) = max(C, R + W), T(2) = max(C, R, (C + R + W + F) / 2) for split frames (F = 0 side
by side; the reported figure takes the measured 2-worker CPU seconds instead). The same formulas on the
tasks' wall seconds (which the other load on a shared machine inflates) give the
wall estimate.
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
    ap.add_argument("--dask-parts", type=int, default=0, dest="dask_parts",
                    help="parts per frame of the '2 workers' runs (0: automatic, one per "
                    "frame while the frames left cover the workers; 1: whole frames, side "
                    "by side); the '2 workers, split' runs always use 2")
    ap.add_argument("--out", default=str(HERE / "results" / "scale"))
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster

    from cmlt.metrics import load_image
    from cmlt.shot import RenderOptions

    w, h = (int(v) for v in args.res.split("x"))

    def opts(threads, parts):
        return RenderOptions(integrator="cmlt", resolution=(w, h), spp=args.spp,
                             chains=args.chains, bootstrap_samples=args.bootstrap_samples,
                             threads=threads, dask_parts=parts, mlt_paths="all")

    t = time.perf_counter()
    clusters = {n: LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                dashboard_address=":0") for n in (1, 2)}
    clients = {n: Client(c) for n, c in clusters.items()}
    startup = time.perf_counter() - t

    # dispatch latency and the client's CPU per task: round trips of a no-op task, one
    # at a time (2 workers)
    c2 = clients[2]
    c2.submit(_noop, 0, pure=False).result()
    t, c = time.perf_counter(), time.process_time()
    for i in range(100):
        c2.submit(_noop, i, pure=False).result()
    latency = (time.perf_counter() - t) / 100
    client_per_task = (time.process_time() - c) / 100

    tmp = tempfile.mkdtemp(prefix="cmlt-scale-")
    # "2 workers, split": every frame in 2 parts (the fixed cost of a further part)
    runs = (("1 worker", 1, args.dask_parts), ("2 workers", 2, args.dask_parts),
            ("2 workers, split", 2, 2), ("one process", 0, 0))
    walls = {name: [] for name, _, _ in runs}
    recs = {}
    cpus = {}               # the client process's CPU seconds per run
    ref_images = None
    for rep in range(args.repeats):
        for name, n, parts in runs:
            out = os.path.join(tmp, f"{name.replace(' ', '_').replace(',', '')}_{rep}",
                               "f.####.exr")
            wall, cpu, res, rr = run(SHOT, args.frames, out, opts(2 if n == 0 else 1, parts),
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
        for n in ("1 worker", "2 workers", "2 workers, split"))

    med = {k: statistics.median(v) for k, v in walls.items()}
    n_frames = len(recs["2 workers"])

    def per_frame(name, key):
        return [r["stats"]["dask"][key] for r in recs[name]]

    def mean(v):
        return float(np.mean(v)) if v else 0.0

    keys = ("bytes_to_workers", "bytes_from_workers", "tasks", "parts", "wait_s", "combine_s",
            "prepare_task_s", "prepare_cpu_s", "prepare_thread_cpu_s", "part_render_s",
            "part_task_s", "part_scene_s", "part_cpu_s", "part_thread_cpu_s")
    d = {name: {k: mean(per_frame(name, k)) for k in keys}
         for name in ("1 worker", "2 workers", "2 workers, split")}
    d1, d2, dsplit = d["1 worker"], d["2 workers"], d["2 workers, split"]
    ahead = sum(per_frame("2 workers", "submitted_ahead"))
    frame_wall2 = mean([r["stats"]["wall_time_s"] for r in recs["2 workers"]])
    extra_parts = max(1.0, dsplit["parts"] - d1["parts"])

    def model(client, prep, work, fixed, per_task):
        cluster = {n: max(client + per_task * (n + 1), prep,
                          (prep + work + fixed * (n - 1)) / n) for n in (1, 2, 4, 16, 100)}
        # one part per frame, frames side by side (--dask-parts 1): no fixed cost grows
        cluster.update({f"{n} (1 part)": max(client + per_task * 2, prep, (prep + work) / n)
                        for n in (16, 100)})
        machine = {1: max(client, prep + work),
                   2: max(client, prep, (client + prep + work + fixed) / 2)}
        return cluster, machine

    # CPU seconds: the client process's per frame (median run), the tasks'
    cpu_client = {n: statistics.median(cpus[n]) / n_frames for n in ("1 worker", "2 workers")}
    # the tasks' own threads (a one-thread render runs on it): the worker process's other
    # threads (Dask's event loop, profiler, heartbeats) cost CPU per second of wall time,
    # which the load of a shared machine stretches; their share is reported beside
    fixed_cpu = max(0.0, (dsplit["part_thread_cpu_s"] - d1["part_thread_cpu_s"]) / extra_parts)
    base_cpu = max(0.0, cpu_client["1 worker"] - 2 * client_per_task)   # without its 2 tasks
    est_cpu, mach_cpu = model(base_cpu, d1["prepare_thread_cpu_s"], d1["part_thread_cpu_s"],
                              fixed_cpu, client_per_task)
    mach_cpu[1] = max(cpu_client["1 worker"], d1["prepare_thread_cpu_s"] + d1["part_thread_cpu_s"])
    mach_cpu[2] = max(cpu_client["2 workers"], d2["prepare_thread_cpu_s"],
                      (cpu_client["2 workers"] + d2["prepare_thread_cpu_s"]
                       + d2["part_thread_cpu_s"]) / 2)
    # the same with the worker processes' CPU seconds (their other threads included)
    mach_proc = {1: max(cpu_client["1 worker"], d1["prepare_cpu_s"] + d1["part_cpu_s"]),
                 2: max(cpu_client["2 workers"], d2["prepare_cpu_s"],
                        (cpu_client["2 workers"] + d2["prepare_cpu_s"] + d2["part_cpu_s"]) / 2)}
    # wall seconds of the tasks (the client's part stays its CPU seconds)
    fixed = max(0.0, (dsplit["part_task_s"] - d1["part_task_s"]) / extra_parts)
    est, _ = model(base_cpu, d1["prepare_task_s"], d1["part_task_s"], fixed,
                   latency)
    summary = {
        "frames": n_frames, "res": [w, h], "spp": args.spp, "chains": args.chains,
        "bootstrap_samples": args.bootstrap_samples, "repeats": args.repeats,
        "wall_s": walls, "median_wall_s": med,
        "ratio_2_over_1_workers": med["2 workers"] / med["1 worker"],
        "ratio_2_workers_over_one_process": med["2 workers"] / med["one process"],
        "ratio_2_workers_split_over_1_worker": med["2 workers, split"] / med["1 worker"],
        "ratios_per_round_2_over_1": [a / b for a, b in zip(walls["2 workers"],
                                                             walls["1 worker"])],
        "per_frame_2_workers_split": dsplit,
        "bit_identical": identical, "cluster_startup_s": startup,
        "noop_task_latency_s": latency, "client_cpu_per_task_s": client_per_task,
        "per_frame_2_workers": d2, "per_frame_1_worker": d1,
        "frames_submitted_ahead_2_workers": ahead,
        "frame_wall_2_workers_s": frame_wall2, "fixed_per_part_s": fixed,
        "estimate_frame_s": est, "estimate_speedup_100_vs_1": est[1] / est[100],
        "estimate_speedup_100_vs_1_one_part": est[1] / est["100 (1 part)"],
        "client_cpu_s": cpus, "client_cpu_per_frame_s": cpu_client,
        "fixed_cpu_per_part_s": fixed_cpu, "estimate_cpu_frame_s": est_cpu,
        "estimate_cpu_this_machine_s": mach_cpu,
        "estimate_cpu_ratio_2_over_1": mach_cpu[2] / mach_cpu[1],
        "estimate_process_cpu_this_machine_s": mach_proc,
        "estimate_process_cpu_ratio_2_over_1": mach_proc[2] / mach_proc[1],
        "estimate_cpu_speedup_100_vs_1": est_cpu[1] / est_cpu[100],
        "estimate_cpu_speedup_100_vs_1_one_part": est_cpu[1] / est_cpu["100 (1 part)"],
        "machine": {"cpus": os.cpu_count(), "load_avg": os.getloadavg()},
    }
    load = os.getloadavg()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out + ".json").write_text(json.dumps(summary, indent=1) + "\n")
    md = [
        "# Dask scaling (tests/bench/scale.py)", "",
        f"`{' '.join(['tests/bench/scale.py'] + (argv if argv is not None else sys.argv[1:]))}`: "
        f"cmlt, camera_pan, {n_frames} frames, {w}x{h}, spp {args.spp}, {args.chains} chains, "
        f"bootstrap {args.bootstrap_samples}; LocalCluster workers of 1 thread; the one-process "
        f"run with 2 threads. Median of {args.repeats} interleaved runs; load average at the "
        f"end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min) on "
        f"{os.cpu_count()} cores (shared machine).", "",
        "| run | wall s (median) | runs |", "|---|---|---|"]
    for k in ("one process", "1 worker", "2 workers", "2 workers, split"):
        md.append(f"| {k} | {med[k]:.1f} | {', '.join(f'{v:.1f}' for v in walls[k])} |")
    md += ["",
           f"2 workers / 1 worker: **{summary['ratio_2_over_1_workers']:.2f}x** "
           f"(per round: {', '.join(f'{v:.2f}' for v in summary['ratios_per_round_2_over_1'])}); "
           f"2 workers, every frame split in 2 parts / 1 worker: "
           f"{summary['ratio_2_workers_split_over_1_worker']:.2f}x; "
           f"2 workers / one process: {summary['ratio_2_workers_over_one_process']:.2f}x. "
           f"Dask images bit-identical to the one-process run: **{identical}**.", "",
           "Per frame (2 workers, mean): "
           f"{d2['tasks']:.0f} tasks ({d2['parts']:.0f} parts and the preparation; "
           f"{ahead} of {n_frames} frames submitted ahead), "
           f"{d2['bytes_to_workers'] / 1e3:.1f} kB to the workers (the preparation to the "
           f"workers of the parts + the task specs), {d2['bytes_from_workers'] / 1e3:.1f} kB "
           f"back (splat words, accumulators, rows, the preparation); frame {frame_wall2:.3f} s "
           f"wall; preparation {d2['prepare_task_s']:.3f} s ({d2['prepare_cpu_s']:.3f} CPU-s); "
           f"parts {d2['part_task_s']:.3f} worker-s (core render {d2['part_render_s']:.3f} s, "
           f"scene update {d2['part_scene_s']:.3f} s; {d2['part_cpu_s']:.3f} CPU-s); the client "
           f"waited {d2['wait_s']:.3f} s for them; combine {d2['combine_s'] * 1e3:.1f} ms.", "",
           f"Per-task costs: no-op round trip {latency * 1e3:.2f} ms, of it "
           f"{client_per_task * 1e3:.2f} ms CPU on the client (with its scheduler); fixed cost "
           f"of a part {fixed_cpu * 1e3:.1f} ms CPU ({fixed * 1e3:.1f} ms wall: growth of the "
           f"parts' worker time from {d1['parts']:.0f} to {dsplit['parts']:.0f} parts per frame, "
           "'2 workers, split' against '1 worker').",
           "",
           "CPU-seconds model (module doc; the other load on this shared machine does not "
           f"enter): client {cpu_client['1 worker']:.3f} / {cpu_client['2 workers']:.3f} CPU-s "
           f"per frame with 1 / 2 workers, preparation {d1['prepare_thread_cpu_s']:.3f}, parts "
           f"{d1['part_thread_cpu_s']:.3f} / {d2['part_thread_cpu_s']:.3f} CPU-s per frame at "
           f"{d1['parts']:.0f} / {d2['parts']:.0f} parts (the tasks' threads; the worker "
           f"processes' CPU during the parts: {d1['part_cpu_s']:.3f} / {d2['part_cpu_s']:.3f} "
           f"CPU-s). On 2 idle cores: 1 worker "
           f"{mach_cpu[1]:.3f} s, 2 workers {mach_cpu[2]:.3f} s per frame: "
           f"**{mach_cpu[2] / mach_cpu[1]:.2f}x** (with the worker processes' CPU: "
           f"{mach_proc[2] / mach_proc[1]:.2f}x). On a cluster: "
           + ", ".join(f"N={n}: {v:.3f} s" for n, v in est_cpu.items())
           + f"; 100 workers vs 1: {est_cpu[1] / est_cpu[100]:.1f}x with 100 parts per frame, "
           f"{est_cpu[1] / est_cpu['100 (1 part)']:.1f}x with one part per frame and frames "
           "side by side (--dask-parts 1).", "",
           "The same on the tasks' wall seconds: "
           + ", ".join(f"N={n}: {v:.3f} s" for n, v in est.items())
           + f"; 100 workers vs 1: {summary['estimate_speedup_100_vs_1']:.1f}x "
           f"({summary['estimate_speedup_100_vs_1_one_part']:.1f}x with one part per frame).",
           ""]
    Path(args.out + ".md").write_text("\n".join(md))
    print("\n".join(md))
    for c in clients.values():
        c.close()
    for c in clusters.values():
        c.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
