#!/usr/bin/env python3
"""Fingerprints of small renders of every sequence with every integrator.

A refactoring that must not change any image (the same seed, settings and thread
count give the same pixels) is checked by running this script on the commit before
and the commit after and comparing the two files:

    .venv/bin/python tests/bench/fingerprint.py --out /tmp/before.json     # on the old commit
    .venv/bin/python tests/bench/fingerprint.py --compare /tmp/before.json # on the new one

Each case renders two consecutive frames (so the Metropolis integrators also carry
their chains and normalisation from one frame to the next) at a small resolution
and budget through the command line, and records the SHA-256 of each frame's
float32 pixels (all channels, AOVs included) together with the sample counts from
its sidecar. ``--pixel-filter box`` forces the one-pixel box filter (to compare with
renders made before the default filter became gaussian). ``--compare`` prints every case that differs and exits 1 if any does.
Hashes are exact: they are only comparable on the same machine (the CPU's SIMD
width decides Embree's kernels) and the same thread count.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
INTEGRATORS = ("pt", "bdpt", "pssmlt", "cmlt")


def _cases(shots):
    for shot in shots:
        for integ in INTEGRATORS:
            extra = []
            if integ in ("pssmlt", "cmlt"):
                extra = ["--chains", "64", "--bootstrap-samples", "2000"]
            yield shot, integ, extra
    # coherent MLT's scalar reference path and wider bundles (packets on)
    for shot in shots[:2]:
        yield shot, "cmlt", ["--chains", "64", "--bootstrap-samples", "2000", "--tries", "8"]
        yield shot, "cmlt", ["--chains", "64", "--bootstrap-samples", "2000", "--tries", "8",
                             "--no-packets"]
        yield shot, "cmlt", ["--chains", "64", "--bootstrap-samples", "2000", "--inner", "mtm",
                             "--tries", "4"]
        yield shot, "pssmlt", ["--chains", "64", "--bootstrap-samples", "2000",
                               "--importance", "luminance", "--direct-fraction", "0"]


def _hash_exr(path: str) -> str:
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"{path}: {oiio.geterror()}")
    try:
        pixels = inp.read_image(format="float")
    finally:
        inp.close()
    return hashlib.sha256(pixels.tobytes()).hexdigest()


def run(args) -> dict:
    shots = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "sequences").glob("*/shot.usda"))
    shots += sorted(str(p.relative_to(ROOT)) for p in (ROOT / "tests/data/usd").glob("*.usda"))
    if args.shots:
        keep = set(args.shots.split(","))
        shots = [s for s in shots if Path(s).parent.name in keep or Path(s).stem in keep]
    cmlt = str(Path(sys.executable).with_name("cmlt"))
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for shot, integ, extra in _cases(shots):
            key = " ".join([shot, integ] + extra)
            pattern = os.path.join(tmp, "f.####.exr")
            # the stage's own start frame and the one after (some stages have no time samples)
            cmd = [cmlt, "render", str(ROOT / shot), "--frames", "all", "--out", pattern,
                   "--res", args.res, "--spp", str(args.spp), "--integrator", integ,
                   "--seed", "7", "--threads", str(args.threads), "--quiet",
                   "--aov", "albedo,normal,depth"] + extra
            if integ in ("pssmlt", "cmlt") and args.mlt_extra:
                cmd += args.mlt_extra.split()
            if args.pixel_filter:     # not in the key: runs with and without it compare
                cmd += ["--pixel-filter", args.pixel_filter]
            cmd = _first_two_frames(cmd, ROOT / shot)
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            if proc.returncode != 0:
                out[key] = {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
                print(f"{key}: error: {out[key]['error']}", flush=True)
                continue
            frames = []
            for exr in sorted(Path(tmp).glob("f.*.exr")):
                side_path = Path(str(exr) + ".json")
                side = json.loads(side_path.read_text())
                stats = side.get("stats", {})
                frames.append({"sha256": _hash_exr(str(exr)),
                               "samples": stats.get("samples"), "rays": stats.get("rays")})
                exr.unlink()
                side_path.unlink()
            out[key] = {"frames": frames}
            print(f"{key}: {' '.join(f['sha256'][:12] for f in frames)}", flush=True)
    return out


def _first_two_frames(cmd, shot: Path):
    """Replace --frames all by the stage's first two time codes (or its one frame)."""
    from pxr import Usd
    stage = Usd.Stage.Open(str(shot))
    start = stage.GetStartTimeCode() if stage.HasAuthoredTimeCodeRange() else 1.0
    end = stage.GetEndTimeCode() if stage.HasAuthoredTimeCodeRange() else start
    spec = f"{start:g}:{min(start + 1, end):g}" if end > start else f"{start:g}"
    i = cmd.index("--frames")
    return cmd[:i + 1] + [spec] + cmd[i + 2:]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", help="write the fingerprints to this JSON file")
    ap.add_argument("--compare", metavar="JSON", help="compare with an earlier run's file")
    ap.add_argument("--mlt-extra", default="",
                    help="more flags for every pssmlt/cmlt case, left out of the cases' keys: a "
                         "new setting whose value reproduces the old images is checked against "
                         "the old commit's file (e.g. --mlt-extra='--mlt-traced-caustics chains')")
    ap.add_argument("--res", default="40x30")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--shots", help="comma-separated sequence or stage names (default: all)")
    ap.add_argument("--pixel-filter", help="render with this pixel filter (e.g. box: the "
                    "one-pixel film of renders before the filters existed; default: the "
                    "renderer's default)")
    args = ap.parse_args(argv)
    result = run(args)
    if args.out:
        Path(args.out).write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    if args.compare:
        before = json.loads(Path(args.compare).read_text())
        bad = [k for k in sorted(set(before) | set(result)) if before.get(k) != result.get(k)]
        for k in bad:
            print(f"DIFFERS: {k}\n  before: {before.get(k)}\n  after:  {result.get(k)}")
        print(f"{len(result) - len(bad)} of {len(set(before) | set(result))} cases identical")
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
