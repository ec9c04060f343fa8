#!/usr/bin/env python3
"""How close the hard stages' Metropolis renders come to the no-stuck-chain bound
(tests/python/hard/test_hard_stages.py, test05: no chain holds more than 5 % of the
chains' image): per stage and integrator, the sidecar's ``max_chain_share`` of each
test seed, its maximum and median. The renders are the test's own (same seeds and
budget), so a margin read here is the margin the test has.

    .venv/bin/python tests/bench/chain_share.py                       # every stage
    .venv/bin/python tests/bench/chain_share.py scale_unit,scale_1e5  # some
    .venv/bin/python tests/bench/chain_share.py bulb_room --seeds 1:40  # beyond the test's seeds
    .venv/bin/python tests/bench/chain_share.py bulb_room --set emission_guiding=0  # a setting changed
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    seeds = None  # the test's own: 1..case.test_seeds
    if "--seeds" in argv:
        k = argv.index("--seeds")
        a, b = (int(v) for v in argv[k + 1].split(":"))
        seeds = range(a, b + 1)
        argv = argv[:k] + argv[k + 2:]
    extra = {}  # --set name=value (repeatable): core settings on top of the stage's
    while "--set" in argv:
        k = argv.index("--set")
        key, _, value = argv[k + 1].partition("=")
        try:
            extra[key] = float(value) if "." in value or "e" in value.lower() else int(value)
        except ValueError:
            extra[key] = value
        argv = argv[:k] + argv[k + 2:]
    spec = importlib.util.spec_from_file_location("cmlt_hard_references",
                                                  ROOT / "sequences" / "hard" / "make_references.py")
    refs = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = refs
    spec.loader.exec_module(refs)
    from cmlt.shot.bridge import SceneBridge
    names = argv[0].split(",") if argv else list(refs.CASES)
    for name in names:
        if name not in refs.CASES:
            print(f"chain_share.py: no hard stage '{name}' (stages: {', '.join(refs.CASES)})", file=sys.stderr)
            return 2
        case = refs.CASES[name]
        core, fs = refs.load(case)
        scene = SceneBridge(core).update(fs)
        for integ in ("pssmlt", "cmlt"):
            shares = []
            for seed in seeds or range(1, case.test_seeds + 1):
                _, stats, _ = refs.render(case, integ, case.test_spp, seed, fs=fs, scene=scene, **extra)
                shares.append(float(stats.get("max_chain_share", float("nan"))))
            over = sum(x > 0.05 for x in shares)
            print(f"{name:20s} {integ:7s} max {max(shares):.4f}  median {float(np.median(shares)):.4f}  "
                  f"above 5 %: {over} of {len(shares)}  "
                  + " ".join(f"{x:.3f}" for x in shares), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
