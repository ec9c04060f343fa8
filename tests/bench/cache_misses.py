#!/usr/bin/env python3
"""Cache behaviour of the integrators per path evaluation (benchmark, not a test):
simulated L1 data-cache and last-level-cache misses of pt, bdpt, pssmlt and cmlt
(scalar and coherent bundles) on the same frames.

This machine's virtual CPUs expose no hardware counters (``perf stat -e cache-misses``
answers "not supported"), so the caches are simulated: callgrind with
``--cache-sim=yes`` (the CPU's cache geometry given explicitly, ``--l1`` / ``--ll``, printed with the
results: valgrind reads this VM's last level as a 256 MB direct-mapped cache), collecting inside the integrator's frame function only
(``--toggle-collect=cmlt::render_<integrator>*``), one thread. Instruction counts repeat
exactly; the miss counts move a little between runs (the core's thread pool still has
helper threads that valgrind interleaves: over three runs on cornell pt and the
Metropolis integrators within 7 %, bdpt's D1 misses 43-83 per evaluation). The frame is
built outside valgrind and handed to the child as a pickled FrameScene, so usd-core never
runs under valgrind.

Last-level misses are split into reads and writes: on these frames every read hits the
32 MB L3 after its first touch (the scene, film and chain states fit), and the write
misses are the first touch of memory the frame allocates (pssmlt's and cmlt's chain
objects and primary-sample vectors), paid once per frame, not per evaluation.

A *path evaluation* is what the sidecar counts: ``stats.path_evaluations`` for pssmlt
and cmlt (bootstrap, pilot, direct pass and every proposal or candidate of the
chains), ``stats.samples`` for pt and bdpt (one camera sample; bdpt's light subpath
with it). Whole-frame counts are divided by it, so each integrator's set-up (pilot,
bootstrap, chain starts, splat film) is spread over its evaluations.

    .venv/bin/python tests/bench/cache_misses.py                      # cornell, caustic_glass
    .venv/bin/python tests/bench/cache_misses.py --shots cornell --res 32x32 --spp 16

Needs valgrind (Debian: ``apt-get install valgrind``).
"""
from __future__ import annotations

import argparse
import json
import pickle
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from callgrind_child import cache_geometry, run_child  # noqa: E402

SHOTS = {"cornell": "sequences/cornell/shot.usda",
         "caustic_glass": "sequences/caustic_glass/shot.usda"}
#: (label, integrator, settings)
CONFIGS = (
    ("pt", "pt", {}),
    ("bdpt", "bdpt", {}),
    ("pssmlt", "pssmlt", {}),
    ("cmlt scalar (k=2)", "cmlt", {"packets": False}),
    ("cmlt k=8 scalar", "cmlt", {"packets": False, "tries": 8}),
    ("cmlt k=8 coherent (packets)", "cmlt", {"packets": True, "tries": 8}),
)
EVENTS = ("Ir", "Dr", "Dw", "I1mr", "D1mr", "D1mw", "ILmr", "DLmr", "DLmw")


def child(frame_file: str, integrator: str, settings: dict, res, spp: int, out: str) -> None:
    import cmlt._core as core
    from cmlt.shot.bridge import SceneBridge
    with open(frame_file, "rb") as f:
        fs = pickle.load(f)
    scene = SceneBridge(core).update(fs)
    st = core.RenderSettings()
    st.width, st.height = res
    st.spp, st.threads, st.integrator, st.seed = spp, 1, integrator, 1
    st.mlt_paths = "all"  # the chains on every path (auto: none on cornell)
    for k, v in settings.items():
        setattr(st, k, v)
    r = core.render(scene, st)
    s = dict(r.stats)
    evals = s.get("path_evaluations") or s.get("samples")
    Path(out).write_text(json.dumps({"evaluations": int(evals), "rays": int(s["rays"])}))


def callgrind(frame_file: Path, label: str, integrator: str, settings: dict, args, tmp: Path):
    tag = re.sub(r"[^a-z0-9]+", "_", f"{frame_file.stem}_{label}".lower())
    cg, out = tmp / f"{tag}.callgrind", tmp / f"{tag}.json"
    counts = run_child(__file__, f"cmlt::render_{integrator}*", cg,
                       [frame_file, "--integrator", integrator, "--settings", json.dumps(settings),
                        "--out", out, "--res", args.res, "--spp", args.spp],
                       ["--cache-sim=yes", f"--I1={args.l1}", f"--D1={args.l1}", f"--LL={args.ll}"])
    return counts, json.loads(out.read_text()), cache_geometry(cg)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", default="32x32")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--shots", default=",".join(SHOTS))
    ap.add_argument("--out", default=None, help="write the table (markdown) here too")
    # valgrind reads this VM's last level as 256 MB direct-mapped; give the CPU's own
    # (AMD EPYC: 32 kB 8-way L1s, a 32 MB 16-way L3), size,associativity,line
    ap.add_argument("--l1", default="32768,8,64", help="L1 (I and D) size,assoc,line")
    ap.add_argument("--ll", default="33554432,16,64", help="last level size,assoc,line")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--integrator", default="pt", help=argparse.SUPPRESS)
    ap.add_argument("--settings", default="{}", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    res = tuple(int(v) for v in args.res.lower().split("x"))
    if args.child:
        child(args.child, args.integrator, json.loads(args.settings), res, args.spp,
              args.out)
        return 0
    from cmlt.usd import load_frame, open_stage
    tmp = Path(tempfile.mkdtemp(prefix="cmlt_cachesim_"))
    lines = [f"`tests/bench/cache_misses.py --res {args.res} --spp {args.spp} --shots "
             f"{args.shots}` (callgrind --cache-sim=yes, one thread, inside "
             "cmlt::render_<integrator>)", "",
             "| shot | integrator | path evaluations | rays / evaluation | instructions / "
             "evaluation | D1 misses / evaluation | D1 miss rate | LL read misses / "
             "evaluation | LL write misses / evaluation |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    caches = {}
    for shot in [s for s in args.shots.split(",") if s]:
        frame = tmp / f"{shot}.pickle"
        with open(frame, "wb") as f:
            pickle.dump(load_frame(open_stage(str(ROOT / SHOTS[shot])), 1.0, resolution=res), f)
        for label, integ, settings in CONFIGS:
            c, r, caches = callgrind(frame, label, integ, settings, args, tmp)
            n = max(1, r["evaluations"])
            d1 = c.get("D1mr", 0) + c.get("D1mw", 0)
            refs = c.get("Dr", 0) + c.get("Dw", 0)
            row = (f"| {shot} | {label} | {r['evaluations']:,} | {r['rays'] / n:.2f} | "
                   f"{c['Ir'] / n:,.0f} | {d1 / n:.1f} | {d1 / max(1, refs) * 100:.2f} % | "
                   f"{c.get('DLmr', 0) / n:.3f} | {c.get('DLmw', 0) / n:.2f} |")
            lines.append(row)
            print(row, flush=True)
    lines += ["", "Simulated caches: " + "; ".join(f"{k} {v}" for k, v in caches.items())]
    print(lines[-1])
    if args.out:
        Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
