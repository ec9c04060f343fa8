"""Run a bench script's ``--child`` mode under callgrind, collecting inside one function
(shared by kernel_instructions.py and cache_misses.py, which pickle the frame outside
valgrind so that usd-core never runs under it)."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Dict, Sequence

ROOT = Path(__file__).resolve().parents[2]


def run_child(script: str, toggle: str, out_file: Path, child_args: Sequence[str],
              valgrind_args: Sequence[str] = ()) -> Dict[str, int]:
    """``python SCRIPT --child CHILD_ARGS...`` under callgrind with ``valgrind_args``,
    collecting only inside functions matching ``toggle``; the event totals of the run
    (``Ir`` first, then e.g. the cache simulation's). Exits with the child's error output
    when it fails or when nothing was collected (``toggle`` matched no function)."""
    cmd = ["valgrind", "--tool=callgrind", *valgrind_args, "--collect-atstart=no",
           f"--toggle-collect={toggle}", f"--callgrind-out-file={out_file}",
           sys.executable, str(script), "--child", *map(str, child_args)]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT,
                       env=dict(os.environ, PYTHONWARNINGS="ignore"))
    if p.returncode != 0 or not out_file.exists():
        sys.stderr.write(p.stderr[-3000:])
        raise SystemExit(1)
    text = out_file.read_text()
    events = re.search(r"^events: (.*)$", text, re.M).group(1).split()
    totals = re.search(r"^(?:summary|totals): (.*)$", text, re.M).group(1).split()
    counts = dict(zip(events, (int(v) for v in totals)))
    if not counts.get("Ir"):
        raise SystemExit(f"callgrind collected nothing inside {toggle!r}: no function of "
                         "that name ran (renamed?)")
    return counts


def cache_geometry(out_file: Path) -> Dict[str, str]:
    """The simulated caches of a ``--cache-sim=yes`` run: {'I1'|'D1'|'LL': description}."""
    return dict(re.findall(r"^desc: (I1|D1|LL) cache: +(.*)$", out_file.read_text(), re.M))
