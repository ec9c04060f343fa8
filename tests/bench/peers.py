#!/usr/bin/env python3
"""Side by side with peer renderers: the same USD frame rendered by cmlt, Mitsuba 3 and
LuxCore, each for the same wall-clock budget on the same number of threads, with relMSE
against a converged reference and samples per second.

    .venv/bin/python -m pip install mitsuba pyluxcore          # the peers (not a cmlt dependency)
    .venv/bin/python tests/bench/peers.py --shots cornell,caustic_glass --seconds 4 \\
        --res 128x128 --out renders/bench/peers

Writes OUT/peers.md (the tables, printed too), OUT/peers.json (every number, the scene
conversion notes, what each peer did), OUT/refs/*.npy (the references, reused by later runs
with the same settings) and OUT/<shot>_refs.png (the references side by side, to look at).

The scene is the same scene: cmlt's loaded frame, converted by
``cmlt.accuracy.peers.convert_frame`` (its module docstring lists what carries over
and what does not); the renderers and their worker processes live there too.

What is compared
----------------
relMSE = mean over pixels and channels of (I - R)^2 / (R^2 + 1e-2), as equal_time.py.
Each renderer is compared with ITS OWN converged reference (``--ref-seconds`` of its
``--ref`` integrator, cached), which makes relMSE-against-time comparable between renderers
even where their images are not identical (a residual light-unit or BSDF difference would
otherwise count as error). As a check that the scenes do match, each peer reference is
also compared with cmlt's: mean-brightness ratios (plain, per channel, and with pixels
clipped at 20x the median so that a few pixels of visible light do not decide it) and
relMSE between the two references; every row reports relMSE against cmlt's reference too
(on a shot where a peer's own reference cannot converge in the time given, that column is
the better one). References by default: cmlt bdpt, Mitsuba path, LuxCore PATHCPU (its
BIDIRCPU comes out brighter than its PATHCPU and than cmlt and Mitsuba on the Cornell box).

Equal time: cmlt uses ``RenderSettings.time_budget``. Mitsuba has no time limit: after
compiling its kernels (not timed, reported as setup) it renders passes of ``pass_spp``
samples per pixel, chosen from a calibration pass so that one pass is about a tenth of the
budget, with new seeds, averaging them, until the budget is used (the last pass may
overshoot a little; the time column is the real wall time). LuxCore: the session is
stopped when the budget has passed since ``Start()`` returned (its scene preprocessing is
setup). Threads: cmlt ``threads``, Mitsuba ``drjit.set_thread_count``, LuxCore
``native.threads.count``. The ``cpu/wall`` column (process CPU time over wall time) shows
how many cores each one really got.

The machine is shared: numbers are ratios measured side by side, interleaved round-robin
over the renderers one render at a time, not absolute speeds; ``--repeats N`` renders each
N times and reports medians. cmlt renders in the driver process, each peer in a worker
process of its own (``cmlt.accuracy.peers``, "Peer worker processes", says why they cannot share one). A
peer that does not install, import or run is reported and skipped (it is first tried on
a 16x16 version of the first shot). Mitsuba's LLVM variant needs a system libLLVM recent enough
for Dr.Jit (Debian 12: ``apt-get install libllvm19``); DRJIT_LIBLLVM_PATH is pointed at the
newest one found, and without it the scalar variant is used.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
import traceback
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

SHOTS = {
    "cornell": "sequences/cornell/shot.usda",
    "caustic_glass": "sequences/caustic_glass/shot.usda",
}
DEFAULT_INTEGRATORS = {
    "cmlt": "pt,bdpt,pssmlt,cmlt",
    "mitsuba": "path,ptracer",
    "luxcore": "PATHCPU,BIDIRCPU,PATHCPU+METROPOLIS,BIDIRCPU+METROPOLIS",
}
DEFAULT_REFS = {"cmlt": "bdpt", "mitsuba": "path", "luxcore": "PATHCPU"}

from cmlt.accuracy.peers import (RemoteRenderer, Worker, clipped_ratio,  # noqa: E402
                                 luminance, start_peer)
from cmlt.accuracy.render import CmltRenderer  # noqa: E402
from cmlt.accuracy.render import stage_start as _stage_start  # noqa: E402
from cmlt.metrics import rel_mse as relmse  # noqa: E402


# ============================================================== driver

def save_png(path: Path, images: List[np.ndarray], scale: float):
    try:
        import OpenImageIO as oiio
    except Exception:
        return
    strip = np.concatenate([np.clip(im * scale, 0, 1) ** (1 / 2.2) for im in images], axis=1)
    h, w = strip.shape[:2]
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        return
    out.open(str(path), oiio.ImageSpec(w, h, 3, "uint8"))
    out.write_image((strip * 255 + 0.5).astype(np.uint8))
    out.close()


def fmt(v, digits=3):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, float):
        if v == 0:
            return "0"
        if abs(v) >= 1e5 or abs(v) < 1e-3:
            return f"{v:.{digits}g}"
        return f"{v:.{digits}g}" if abs(v) < 1 else f"{v:.{max(digits, 1)}g}"
    return str(v)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shots", default="cornell,caustic_glass",
                    help="comma-separated: names under sequences/ (cornell, caustic_glass, ...) or .usd paths")
    ap.add_argument("--frame", type=float, default=None, help="time code (default: each stage's start)")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--seconds", type=float, default=4.0, help="wall-clock budget per render")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--renderers", default="cmlt,mitsuba,luxcore")
    ap.add_argument("--cmlt", default=DEFAULT_INTEGRATORS["cmlt"], help="cmlt integrators")
    ap.add_argument("--mitsuba", default=DEFAULT_INTEGRATORS["mitsuba"],
                    help="Mitsuba integrators (path, ptracer, prb)")
    ap.add_argument("--luxcore", default=DEFAULT_INTEGRATORS["luxcore"],
                    help="LuxCore ENGINE[+SAMPLER] (sampler default SOBOL)")
    ap.add_argument("--mitsuba-variant", default="auto",
                    help="auto (llvm_ad_rgb, else scalar_rgb), or a variant name")
    ap.add_argument("--ref", default=",".join(f"{k}={v}" for k, v in DEFAULT_REFS.items()),
                    help="reference integrator per renderer")
    ap.add_argument("--ref-seconds", type=float, default=120.0,
                    help="time of each renderer's converged reference (cached)")
    ap.add_argument("--repeats", type=int, default=1, help="timed renders per integrator (median)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--pixel-filter", default="box", choices=("box", "gaussian"), dest="pixel_filter",
                    help="every renderer's pixel filter (box: one pixel; gaussian: sigma 0.5 px)")
    ap.add_argument("--keep-specular", action="store_true",
                    help="leave cmlt's 4%% specular layer on opaque materials (peers stay Lambert)")
    ap.add_argument("--out", default="renders/bench/peers")
    args = ap.parse_args(argv)

    os.chdir(ROOT)
    w, h = (int(v) for v in args.res.lower().split("x"))
    out_dir = Path(args.out)
    (out_dir / "refs").mkdir(parents=True, exist_ok=True)
    shots = [s.strip() for s in args.shots.split(",") if s.strip()]
    shot_paths = {s: (SHOTS.get(s) or (s if s.endswith((".usd", ".usda", ".usdc"))
                                       else f"sequences/{s}/shot.usda")) for s in shots}
    renderers = [r.strip() for r in args.renderers.split(",") if r.strip()]
    integrators = {"cmlt": args.cmlt, "mitsuba": args.mitsuba, "luxcore": args.luxcore}
    integrators = {k: [x.strip() for x in v.split(",") if x.strip()] for k, v in integrators.items()}
    refs = dict(DEFAULT_REFS)
    refs.update(dict(kv.split("=", 1) for kv in args.ref.split(",") if "=" in kv))
    load0 = os.getloadavg()
    started = time.strftime("%Y-%m-%d %H:%M:%S")

    # ---- which peers work here (each started in a worker process and tried at 16x16)
    status: Dict[str, dict] = {"cmlt": {"ok": True, "note": "ok (in the driver process)"}}
    workers: Dict[str, Worker] = {}
    log_dir = out_dir / "logs"
    log_dir.mkdir(parents=True, exist_ok=True)
    first = shot_paths[shots[0]]
    probe_c = CmltRenderer(first, args.frame if args.frame is not None else _stage_start(first),
                           (16, 16), True, args.threads, args.pixel_filter)
    for r in renderers:
        if r == "cmlt":
            continue
        if r not in ("mitsuba", "luxcore"):
            status[r] = {"ok": False, "note": "unknown renderer"}
            continue
        w_, st = start_peer(r, args.mitsuba_variant, probe_c.peer_scene, args.threads, log_dir)
        status[r] = st
        if w_ is not None:
            workers[r] = w_
    del probe_c
    for r in renderers:
        st = status[r]
        print(f"  {r}: {'available' if st['ok'] else 'NOT AVAILABLE'} ({st['note']})", flush=True)
    active = [r for r in renderers if status[r]["ok"]]

    rows: List[dict] = []
    ref_rows: List[dict] = []
    conversions: Dict[str, dict] = {}
    for shot in shots:
        path = shot_paths[shot]
        frame = args.frame if args.frame is not None else _stage_start(path)
        print(f"\n== {shot} ({path}, frame {frame:g}, {w}x{h}, {args.seconds:g} s, "
              f"{args.threads} threads)", flush=True)
        rend: Dict[str, object] = {}
        c = CmltRenderer(path, frame, (w, h), not args.keep_specular, args.threads,
                         args.pixel_filter)
        rend["cmlt"] = c
        ps = c.peer_scene
        conversions[shot] = {"triangles": ps.triangle_count(), "meshes": len(ps.meshes),
                             "sphere_lights": len(ps.spheres), "notes": ps.notes,
                             "cmlt_lambert_materials": c.lambert_materials,
                             "camera_hfov_deg": ps.camera.hfov_deg, "digest": ps.digest(),
                             "load_warnings": list(c.fs.warnings)}
        for n in ps.notes:
            print(f"  conversion: {n}", flush=True)
        status["cmlt"]["version"] = c.version
        for r in active:
            if r == "cmlt" or not status[r]["ok"]:
                continue
            try:
                rend[r] = RemoteRenderer(workers[r], ps, 900.0)
                status[r]["version"] = rend[r].version
            except Exception as e:
                status[r]["ok"] = False
                status[r]["note"] = f"scene build failed on {shot}: {type(e).__name__}: {e}"
                print(f"  {r}: {status[r]['note']}", flush=True)
                traceback.print_exc()

        # ---- references (each renderer's own, cached)
        ref_img: Dict[str, np.ndarray] = {}
        for r, R in rend.items():
            integ = refs[r]
            key = (f"{shot}_f{frame:g}_{w}x{h}_{r}_{integ.replace('+', '-')}_{args.ref_seconds:g}s_"
                   f"{'spec' if args.keep_specular else 'lambert'}_{ps.digest()}")
            f = out_dir / "refs" / f"{key}.npy"
            meta_f = f.with_suffix(".json")
            if f.exists():
                ref_img[r] = np.load(f)
                meta = json.loads(meta_f.read_text()) if meta_f.exists() else {}
                print(f"  reference {r} {integ}: cached {f.name}", flush=True)
            else:
                print(f"  reference {r} {integ}: rendering {args.ref_seconds:g} s ...", flush=True)
                try:
                    out = R.render(integ, args.ref_seconds, 12345)
                except Exception as e:
                    print(f"  reference {r} failed: {type(e).__name__}: {e}", flush=True)
                    status[r]["note"] = f"reference failed on {shot}: {e}"
                    continue
                ref_img[r] = out["image"]
                np.save(f, out["image"])
                meta = {k: v for k, v in out.items() if k != "image"}
                meta_f.write_text(json.dumps(meta, indent=2, default=float))
                print(f"    {out['time_s']:.1f} s, {out['spp']:.0f} spp", flush=True)
            ref_rows.append({"shot": shot, "renderer": r, "integrator": integ,
                             "seconds": meta.get("time_s"), "spp": meta.get("spp")})
        base = ref_img.get("cmlt")
        for rr in ref_rows:
            if rr["shot"] != shot or rr["renderer"] not in ref_img:
                continue
            im = ref_img[rr["renderer"]]
            rr["mean_rgb"] = [float(x) for x in im.reshape(-1, 3).mean(0)]
            if base is not None:
                rr["mean_ratio_vs_cmlt"] = luminance(im) / max(luminance(base), 1e-12)
                rr["clipped_ratio_vs_cmlt"] = clipped_ratio(im, base, base)
                rr["mean_ratio_rgb_vs_cmlt"] = [
                    float(a / max(b, 1e-12)) for a, b in zip(im.reshape(-1, 3).mean(0),
                                                             base.reshape(-1, 3).mean(0))]
                rr["relmse_vs_cmlt_ref"] = relmse(im, base)
        order = [r for r in ("cmlt", "mitsuba", "luxcore") if r in ref_img]
        if base is not None and order:
            save_png(out_dir / f"{shot}_refs.png", [ref_img[r] for r in order],
                     0.5 / max(float(np.mean(base)), 1e-12))

        # ---- timed renders, interleaved round-robin over renderers
        queue: List[Tuple[str, str]] = []
        lists = [[(r, i) for i in integrators[r]] for r in rend if r in ref_img]
        for k in range(max((len(l) for l in lists), default=0)):
            for l in lists:
                if k < len(l):
                    queue.append(l[k])
        results: Dict[Tuple[str, str], List[dict]] = {}
        for rep in range(args.repeats):
            for r, integ in queue:
                try:
                    out = rend[r].render(integ, args.seconds, args.seed + rep)
                except Exception as e:
                    print(f"  {r} {integ}: FAILED {type(e).__name__}: {e}", flush=True)
                    results.setdefault((r, integ), []).append({"error": f"{type(e).__name__}: {e}"})
                    continue
                img = out.pop("image")
                out["finite"] = bool(np.isfinite(img).all())
                img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
                out["relmse"] = relmse(img, ref_img[r])
                out["relmse_vs_cmlt_ref"] = relmse(img, base) if base is not None else None
                out["mean_ratio"] = clipped_ratio(img, ref_img[r], ref_img[r])
                out["cpu_per_wall"] = out["cpu_s"] / max(out["time_s"], 1e-9)
                results.setdefault((r, integ), []).append(out)
                print(f"  {r:>8} {integ:<22} time {out['time_s']:6.2f} s  relMSE {out['relmse']:.5f}"
                      f"  (vs cmlt ref {fmt(out['relmse_vs_cmlt_ref'], 4)})  mean/ref "
                      f"{out['mean_ratio']:.4f}  spp {out['spp']:8.1f}  samples/s "
                      f"{out['samples_per_s']:.3g}  cpu/wall {out['cpu_per_wall']:.2f}", flush=True)
        for (r, integ), outs in results.items():
            good = [o for o in outs if "error" not in o]
            row = {"shot": shot, "renderer": r, "integrator": integ, "budget_s": args.seconds,
                   "runs": outs}
            if good:
                for k in ("time_s", "setup_s", "relmse", "relmse_vs_cmlt_ref", "mean_ratio", "spp",
                          "samples_per_s", "cpu_per_wall"):
                    vals = [o[k] for o in good if o.get(k) is not None]
                    row[k] = float(np.median(vals)) if vals else None
            else:
                row["error"] = outs[0]["error"]
            rows.append(row)

    load1 = os.getloadavg()
    # ---- report
    cmd = "python tests/bench/peers.py " + " ".join(
        a if " " not in a else repr(a) for a in (argv if argv is not None else sys.argv[1:]))
    md = [f"# cmlt vs peers: equal time, {w}x{h}, {args.seconds:g} s per render, "
          f"{args.threads} threads", "",
          f"`{cmd}` — {started}, {platform.node()}, {os.cpu_count()} cores; load average "
          f"{load0[0]:.1f} at start, {load1[0]:.1f} at end (a shared, loaded machine: read the "
          f"ratios, not the absolute speeds). Renderers interleaved, one render at a time "
          f"(cmlt in the driver process, each peer in a worker process of its own).", "",
          "relMSE: against the renderer's own converged reference "
          f"({', '.join(f'{r} {refs[r]}' for r in renderers)}, {args.ref_seconds:g} s each); "
          "\"vs cmlt ref\": against cmlt's reference (includes any scene mismatch). "
          "mean/ref: clipped mean brightness over the own reference's. "
          "spp: samples (cmlt MLT: path evaluations; Mitsuba ptracer: light paths) per pixel; "
          "samples/s over all pixels. Each number is the median of "
          f"{args.repeats} render(s); setup (scene build, Mitsuba's kernel compilation) is not timed.", "",
          "| shot | renderer | integrator | budget s | time s | relMSE | vs cmlt ref | mean/ref "
          "| spp | samples/s | cpu/wall |",
          "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        if "error" in row:
            md.append(f"| {row['shot']} | {row['renderer']} | {row['integrator']} | "
                      f"{row['budget_s']:g} | - | failed: {row['error'][:60]} | | | | | |")
            continue
        md.append(f"| {row['shot']} | {row['renderer']} | {row['integrator']} | {row['budget_s']:g} | "
                  f"{row['time_s']:.2f} | {row['relmse']:.4g} | {fmt(row['relmse_vs_cmlt_ref'], 4)} | "
                  f"{row['mean_ratio']:.3f} | {row['spp']:.1f} | {row['samples_per_s']:.3g} | "
                  f"{row['cpu_per_wall']:.2f} |")
    md += ["", "References and scene match (a peer's reference against cmlt's: ratio of mean "
           "luminance, of the per-channel means, of the means with pixels clipped at 20x the "
           "median (so that the few pixels of visible lights and highlights do not decide "
           "it), and relMSE between the two references):", "",
           "| shot | renderer | reference | time s | spp | mean / cmlt | R, G, B / cmlt | clipped mean / cmlt | relMSE vs cmlt ref |",
           "|---|---|---|---:|---:|---:|---|---:|---:|"]
    for rr in ref_rows:
        rgb = rr.get("mean_ratio_rgb_vs_cmlt")
        md.append(f"| {rr['shot']} | {rr['renderer']} | {rr['integrator']} | "
                  f"{fmt(rr.get('seconds'))} | {fmt(rr.get('spp'))} | "
                  f"{fmt(rr.get('mean_ratio_vs_cmlt'), 4)} | "
                  f"{', '.join(f'{x:.3f}' for x in rgb) if rgb else '-'} | "
                  f"{fmt(rr.get('clipped_ratio_vs_cmlt'), 4)} | "
                  f"{fmt(rr.get('relmse_vs_cmlt_ref'), 4)} |")
    md += ["", "Renderers:", ""]
    for r in renderers:
        st = status[r]
        extra = f", variant {st['variant']}" if st.get("variant") else ""
        md.append(f"- {r}: {'ran' if st['ok'] else 'NOT RUN'} (version {st.get('version', '?')}"
                  f"{extra}): {st['note']}")
    md += ["", "Conversion notes (what the peers do not get exactly as cmlt):", ""]
    for shot, cv in conversions.items():
        lam = ("cmlt's opaque materials made exactly Lambertian (ior = 1): "
               + ", ".join(cv["cmlt_lambert_materials"])) if cv["cmlt_lambert_materials"] else \
            "cmlt's materials unchanged"
        md.append(f"- {shot}: {cv['triangles']} triangles in {cv['meshes']} meshes, "
                  f"{cv['sphere_lights']} sphere light(s); {lam}; "
                  + ("; ".join(cv["notes"]) if cv["notes"] else "nothing else to note"))
    text = "\n".join(md) + "\n"
    print("\n" + text, flush=True)
    (out_dir / "peers.md").write_text(text)
    result = {"command": cmd, "started": started, "host": platform.node(), "cores": os.cpu_count(),
              "loadavg_start": load0, "loadavg_end": load1, "res": [w, h],
              "budget_s": args.seconds, "threads": args.threads, "ref_seconds": args.ref_seconds,
              "references": refs, "renderers": status, "rows": rows, "reference_rows": ref_rows,
              "conversion": conversions, "worker_logs": {r: str(w_.log_path) for r, w_ in workers.items()}}
    (out_dir / "peers.json").write_text(json.dumps(result, indent=2, default=float))
    print(f"wrote {out_dir / 'peers.md'} and {out_dir / 'peers.json'}", flush=True)
    for w_ in workers.values():
        w_.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
