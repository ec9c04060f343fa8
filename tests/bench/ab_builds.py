#!/usr/bin/env python3
"""Before / after from the same command: the core modules of two (or more) builds,
swapped into the installed package in turn, each running the same ``cmlt render``,
interleaved (A B A B ...), medians of ``--repeats``.

    # the module of the commit before, built next to this tree:
    git worktree add ../before HEAD~1 && cmake -S ../before -B ../before/build -G Ninja \\
        -DCMAKE_BUILD_TYPE=Release -DCMLT_BUILD_TESTS=OFF -DPython_EXECUTABLE=$PWD/.venv/bin/python \\
        -Dnanobind_ROOT="$(.venv/bin/python -m nanobind --cmake_dir)" && cmake --build ../before/build
    .venv/bin/python tests/bench/ab_builds.py --modules ../before/build/src/bindings/_core*.so,build/py/src/bindings/_core*.so \\
        --repeats 3 -- sequences/cornell/shot.usda --integrator pt --spp 64 --res 256x256 --threads 2

The module swapped is the one the package loads (``cmlt._core.__file__``): on a CPU
that runs the x86-64-v4 build, ``cmlt/x86-64-v4/_core*.so`` (``src/cmlt/_core_select.py``),
so compare like with like — ``build/py/src/bindings/x86-64-v4/_core*.so`` of both trees,
or both portable modules with ``CMLT_CORE_ISA=baseline`` set.

Per module: the render time (``stats.time_s`` of the sidecar), samples/s, the process's
wall time (start-up included), the trace share (``trace_s / busy_s``) and the speed-up
against the first module. The installed module is restored afterwards.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _install(src: Path, installed: Path) -> None:
    """Put `src` in place of the installed module by a copy beside it and a rename: a
    process that has the module mapped (a render running meanwhile) keeps the file it
    loaded. Copying over the file in place changed the pages under such a process (it
    died of SIGBUS)."""
    tmp = installed.with_name(installed.name + ".swap")
    shutil.copy(src, tmp)
    os.replace(tmp, installed)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--modules", required=True, help="comma-separated _core module files (A,B,...)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("render", nargs=argparse.REMAINDER, help="-- then the cmlt render arguments")
    a = ap.parse_args(argv)
    args = a.render[1:] if a.render[:1] == ["--"] else a.render
    import cmlt._core
    installed = Path(cmlt._core.__file__)  # the module the installed package imports
    mods = [Path(p).resolve() for p in a.modules.split(",")]
    cli = str(Path(sys.executable).with_name("cmlt"))
    res = {m: [] for m in mods}
    with tempfile.TemporaryDirectory() as td:
        backup = Path(td) / "installed.so"
        shutil.copy(installed, backup)
        try:
            for _ in range(a.repeats):
                for m in mods:
                    _install(m, installed)
                    out = Path(tempfile.mkdtemp(dir=td))
                    t0 = time.perf_counter()
                    p = subprocess.run([cli, "render", *args, "--out", str(out / "f.####.exr"), "--quiet"],
                                       capture_output=True, text=True, cwd=ROOT)
                    wall = time.perf_counter() - t0
                    if p.returncode:
                        sys.stderr.write(p.stderr)
                        return 1
                    st = json.loads(next(out.glob("*.exr.json")).read_text())["stats"]
                    res[m].append((st["time_s"], wall, st.get("trace_s", 0.0) / st["busy_s"], st["samples"]))
                    print(f"  {m.name}: render {st['time_s']:.3f} s, wall {wall:.2f} s", file=sys.stderr, flush=True)
        finally:
            _install(backup, installed)
    base = statistics.median(r[0] for r in res[mods[0]])
    for m in mods:
        t = statistics.median(r[0] for r in res[m])
        w = statistics.median(r[1] for r in res[m])
        share = statistics.median(r[2] for r in res[m])
        n = res[m][0][3]
        runs = ", ".join(f"{r[0]:.3f}" for r in res[m])
        print(f"{m}: render {t:.3f} s (runs {runs}), {n / t:.3g} samples/s, wall {w:.2f} s "
              f"({n / w:.3g} samples/s with start-up), trace share {share:.1%}, speed-up {base / t:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
