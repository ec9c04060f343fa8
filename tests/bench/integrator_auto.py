#!/usr/bin/env python3
"""Does ``--integrator auto`` pick well? Equal-time relMSE of pt, bdpt, pssmlt and cmlt on
every sequence, against the integrator auto chooses (benchmark, not a test).

For each shot (default: every sequences/*/shot.usda) and frame (default: the stage's start
frame): the auto choice (cmlt.shot.analyse.resolve_auto, the stage's first / middle / last
frames), a reference (the mean of --ref-parts independent BDPT renders of --ref-seconds each,
cached under renders/bench/; its own error is estimated from the spread of the parts), then every
integrator at the same time budget for each seed, interleaved seed by seed and shot by
shot so that slow phases of a shared machine hit them alike. Reports the mean relMSE over
seeds (± standard error), the best integrator and auto's ratio to it (the target is
<= 1.2), as a markdown table.

    .venv/bin/python tests/bench/integrator_auto.py --res 64x64 --seconds 2 --seeds 3 \\
        --ref-seconds 40 --threads 2 --markdown tests/bench/results/integrator_auto.md
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cmlt.accuracy import ShotFrame, measure, parse_integrator  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
INTEGRATORS = ("pt", "bdpt", "pssmlt", "cmlt")


def auto_choice(shot: str, res):
    import cmlt._core as core
    from cmlt.shot.analyse import resolve_auto
    from cmlt.usd import open_stage, stage_info

    stage = open_stage(shot)
    info = stage_info(stage)
    return resolve_auto(stage, info, core, [info.start], resolution=res), info.start


def reference(sf, res, name, frame, seconds, parts, cache: Path):
    """The mean of `parts` independent BDPT renders of `seconds` each, and its expected
    relMSE contribution: the per-pixel variance of the mean (from the spread of the
    parts) over the relMSE denominator, averaged. E[relMSE(I, ref)] = relMSE(I) + that,
    for a render I independent of the reference."""
    path = cache / f"auto_ref_{name}_{frame:g}_{res[0]}x{res[1]}_{parts}x{seconds:g}s.npz"
    if path.exists():
        z = np.load(path)
        return z["ref"], float(z["noise"])
    imgs = []
    for k in range(parts):
        imgs.append(np.asarray(sf.render(parse_integrator("bdpt", sf.core), seconds=seconds, seed=1001 + k).image,
                               np.float64))
    imgs = np.stack(imgs)
    ref = imgs.mean(axis=0)
    var_mean = imgs.var(axis=0, ddof=1) / parts
    noise = float(np.mean(var_mean / (ref ** 2 + 1e-2)))
    np.savez(path, ref=ref, noise=noise)
    return ref, noise


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shots", nargs="*", help="default: every sequences/*/shot.usda")
    ap.add_argument("--frame", action="append", default=[], metavar="NAME=FRAME",
                    help="extra frames, e.g. door_ajar=12 (repeatable)")
    ap.add_argument("--res", default="64x64")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref-seconds", type=float, default=40.0, help="per reference part")
    ap.add_argument("--ref-parts", type=int, default=4)
    ap.add_argument("--integrators", default=",".join(INTEGRATORS))
    ap.add_argument("--json", default=None)
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.res.lower().split("x"))
    res = (w, h)
    integrators = [s for s in args.integrators.split(",") if s]
    shots = args.shots or sorted(str(p) for p in (ROOT / "sequences").glob("*/shot.usda"))
    cache = ROOT / "renders" / "bench"
    cache.mkdir(parents=True, exist_ok=True)

    # the cases: (name, shot, frame); auto chooses per shot
    cases, choice = [], {}
    for shot in shots:
        name = Path(shot).parent.name
        auto, start = auto_choice(shot, res)
        choice[name] = auto
        cases.append((name, shot, float(start)))
        for extra in args.frame:
            n, _, f = extra.partition("=")
            if n == name:
                cases.append((name, shot, float(f)))
        print(f"{name}: auto -> {auto.name} ({auto.reason})", flush=True)

    scenes, refs = {}, {}
    for name, shot, frame in cases:
        sf = ShotFrame(shot, frame, res, args.threads)
        scenes[(name, frame)] = sf
        t0 = time.perf_counter()
        refs[(name, frame)] = reference(sf, res, name, frame, args.ref_seconds, args.ref_parts, cache)
        print(f"reference {name} frame {frame:g}: noise relMSE {refs[(name, frame)][1]:.3g} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)

    errs = {(c[0], c[2], i): [] for c in cases for i in integrators}
    for seed in range(args.seeds):
        for name, shot, frame in cases:
            sf = scenes[(name, frame)]
            ref, _ = refs[(name, frame)]
            for integ in integrators:
                r = sf.render(parse_integrator(integ, sf.core), seconds=args.seconds, seed=seed)
                e = measure(np.asarray(r.image, np.float64), ref)["relmse"]
                errs[(name, frame, integ)].append(e)
                print(f"seed {seed} {name} {frame:g} {integ}: {e:.4g}", flush=True)

    rows, out = [], {}
    for name, shot, frame in cases:
        means = {i: float(np.mean(errs[(name, frame, i)])) for i in integrators}
        ses = {i: float(np.std(errs[(name, frame, i)], ddof=1) / math.sqrt(args.seeds))
               if args.seeds > 1 else 0.0 for i in integrators}
        best = min(means, key=means.get)
        a = choice[name].name
        ratio = means[a] / means[best] if a in means else float("nan")
        noise = refs[(name, frame)][1]
        # the reference's own error adds to every mean alike; without it:
        net = {i: max(means[i] - noise, 1e-30) for i in integrators}
        net_best = min(net, key=net.get)
        net_ratio = net[a] / net[net_best] if a in net else float("nan")
        rows.append((name, frame, means, ses, best, a, ratio, noise, net_ratio))
        out[f"{name}@{frame:g}"] = {"mean": means, "se": ses, "best": best, "auto": a,
                                    "ratio": ratio, "net_ratio": net_ratio,
                                    "reason": choice[name].reason,
                                    "ref_noise": refs[(name, frame)][1],
                                    "runs": {i: errs[(name, frame, i)] for i in integrators}}
    head = ("| shot | frame | " + " | ".join(integrators) +
            " | best | auto | auto / best | ref. noise | auto / best, noise subtracted |")
    lines = [head, "|" + "---|" * (len(integrators) + 7)]
    for name, frame, means, ses, best, a, ratio, noise, net_ratio in rows:
        cells = [(f"**{means[i]:.4g}** ± {ses[i]:.2g}" if i == a else
                  f"{means[i]:.4g} ± {ses[i]:.2g}") for i in integrators]
        lines.append(f"| {name} | {frame:g} | " + " | ".join(cells) +
                     f" | {best} | {a} | {ratio:.2f} | {noise:.2g} | {net_ratio:.2f} |")
    table = "\n".join(lines)
    print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    if args.markdown:
        Path(args.markdown).write_text(table + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
