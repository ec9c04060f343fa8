#!/usr/bin/env python3
"""The heavy tail of a shot's error over many seeds: per configuration, relMSE against a
converged reference for each seed, then its mean (± standard error), median, largest
value and the number of renders above ``--blob`` (a render with a blob: a few pixels many
times the reference). A Metropolis render's error is heavy-tailed where chains can get
stuck (an island of primary sample space keeps its start's share of the image), so a few
seeds decide the mean and three are not enough to see it: this bench draws forty.

Configurations are ``cmlt.accuracy.parse_integrator`` specs (``cmlt:mlt_sds=chains``,
``cmlt:mlt_sds=direct``, ``pssmlt:bootstrap_samples=1250000``, ``pt``), all at the same
evaluations per pixel; the per-render time is printed beside them (equal evaluations, not
equal time).

    .venv/bin/python tests/bench/heavy_tail.py sequences/caustic_glass/shot.usda \\
        --configs cmlt:mlt_sds=chains,cmlt,pt --spp 512 --seeds 3000:3039 --res 128x128

The hard stages (``--hard caustic_sds``) are rendered at their own resolution against
their own references (sequences/hard/make_references.py). ``--jsonl FILE`` appends every
render's record.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))


def _relmse(img: np.ndarray, ref: np.ndarray) -> float:
    return float(((img - ref) ** 2 / (ref * ref + 1e-2)).mean())


def _shot_renderer(shot: str, res, threads: int, cache: str):
    from cmlt.accuracy import ShotFrame, parse_integrator, render_reference
    sf = ShotFrame(shot, None, res, threads)
    ref = np.asarray(render_reference(sf, "bdpt", 16384, cache).image, np.float64)[..., :3]

    def render(cfg: str, spp: int, seed: int):
        spec = parse_integrator(cfg, sf.core)
        r = sf.core.render(sf.scene, sf.settings(spec, None, spp, seed))
        return np.asarray(r.image, np.float64), dict(r.stats)
    return render, ref


def _hard_renderer(name: str, threads: int):
    spec = importlib.util.spec_from_file_location("cmlt_hard_references",
                                                  ROOT / "sequences" / "hard" / "make_references.py")
    refs = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = refs
    spec.loader.exec_module(refs)
    from cmlt.accuracy import parse_integrator
    from cmlt.shot.bridge import SceneBridge
    case = refs.CASES[name]
    core, fs = refs.load(case)
    scene = SceneBridge(core).update(fs)
    ref = refs.make_reference(case).image

    def render(cfg: str, spp: int, seed: int):
        p = parse_integrator(cfg, core)
        st = refs.core_settings(core, fs, p.name, spp, seed, threads, tuple(case.settings))
        for key, value in p.overrides:
            setattr(st, key, value)
        r = core.render(scene, st)
        return np.asarray(r.image, np.float64), dict(r.stats)
    return render, ref


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot", nargs="?", default="sequences/caustic_glass/shot.usda")
    ap.add_argument("--hard", default="", help="a hard stage's name instead of a shot")
    ap.add_argument("--configs", default="cmlt:mlt_sds=chains,cmlt:mlt_sds=direct")
    ap.add_argument("--spp", type=int, default=512, help="samples or path evaluations per pixel")
    ap.add_argument("--seeds", default="3000:3039", help="first:last (inclusive)")
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--blob", type=float, default=0.005, help="relMSE above which a render counts as blobbed")
    ap.add_argument("--cache", default="renders/cache/accuracy")
    ap.add_argument("--jsonl", default="")
    args = ap.parse_args(argv)
    a, b = (int(v) for v in args.seeds.split(":"))
    if args.hard:
        render, ref = _hard_renderer(args.hard, args.threads)
        label = args.hard
    else:
        w, h = (int(v) for v in args.res.lower().split("x"))
        render, ref = _shot_renderer(args.shot, (w, h), args.threads, args.cache)
        label = Path(args.shot).parent.name
    out = open(args.jsonl, "a") if args.jsonl else None
    rows = {c: [] for c in args.configs.split(",")}
    for seed in range(a, b + 1):
        for cfg in rows:
            t0 = time.perf_counter()
            img, stats = render(cfg, args.spp, seed)
            e = _relmse(img, ref)
            rec = dict(shot=label, cfg=cfg, spp=args.spp, seed=seed, relmse=e,
                       time_s=stats.get("time_s", time.perf_counter() - t0),
                       max_chain_share=stats.get("max_chain_share"), stuck_chains=stats.get("stuck_chains"))
            rows[cfg].append(rec)
            if out:
                out.write(json.dumps(rec) + "\n")
                out.flush()
    print(f"{label}, {args.spp} per pixel, seeds {a}-{b}: relMSE against the reference")
    print("| configuration | mean ± s.e. | median | largest | renders > %g | time per render |" % args.blob)
    print("|---|---:|---:|---:|---:|---:|")
    for cfg, rs in rows.items():
        e = np.array([r["relmse"] for r in rs])
        se = e.std(ddof=1) / np.sqrt(len(e)) if len(e) > 1 else float("nan")
        t = float(np.median([r["time_s"] for r in rs]))
        print(f"| {cfg} | {e.mean():.3g} ± {se:.2g} | {np.median(e):.3g} | {e.max():.3g} | "
              f"{int((e > args.blob).sum())}/{len(e)} | {t:.2f} s |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
