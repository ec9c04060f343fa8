"""The peers' shared harness: one worker process per peer renderer, the driver-side
handle, the probe render that decides whether a peer runs, the ``--peers`` parser and
the session of an accuracy run.

Each peer renders in a child process of its own, driven from here one render at a time
(so the renders are still interleaved on the same machine state). They cannot share one
process: importing pyluxcore preloads its bundled tbbmalloc_proxy, which replaces malloc
for the whole process, and Mitsuba then aborts with "free(): invalid pointer"; and a
Dr.Jit built against a too-old libLLVM aborts the process from inside LLVM. A worker that
dies is reported (with the tail of its log) and the run goes on without it.
"""

from __future__ import annotations

import io
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Callable, Dict, List, Sequence, Tuple

import numpy as np

from .luxcore import LuxCoreRenderer
from .mitsuba import MitsubaRenderer, setup_llvm_env
from .scene import PScene


#: each peer's integrator when none is named (``--peers mitsuba`` = ``mitsuba:path``)
DEFAULT_PEER_INTEGRATORS = {"mitsuba": "path", "luxcore": "PATHCPU"}
#: the Python module each peer needs, and what to install
PEER_MODULES = {"mitsuba": "mitsuba", "luxcore": "pyluxcore"}


class WorkerDied(RuntimeError):
    pass


def worker_main(conn, renderer: str, variant: str, threads: int, log_path: str):
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    sys.stdout = io.TextIOWrapper(os.fdopen(1, "wb", buffering=0), write_through=True)
    sys.stderr = sys.stdout
    R = None
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            os._exit(0)
        cmd = msg[0]
        try:
            if cmd == "quit":
                conn.send({"ok": True})
                os._exit(0)
            elif cmd == "scene":
                ps = msg[1]
                t0 = time.perf_counter()
                R = (MitsubaRenderer(ps, variant, threads) if renderer == "mitsuba"
                     else LuxCoreRenderer(ps, threads))
                conn.send({"ok": True, "version": R.version, "setup_s": time.perf_counter() - t0})
            elif cmd == "render":
                _, integ, budget, seed = msg
                print(f"render {integ} {budget} s seed {seed}", flush=True)
                out = R.render(integ, budget, seed)
                conn.send({"ok": True, "out": out})
            else:
                conn.send({"error": f"unknown command {cmd!r}"})
        except Exception as e:
            traceback.print_exc()
            conn.send({"error": f"{type(e).__name__}: {e}"})


class Worker:
    """One peer renderer in a child process (spawned: no state inherited from here)."""

    def __init__(self, renderer: str, variant: str, threads: int, log_dir: Path):
        import multiprocessing as mp
        ctx = mp.get_context("spawn")
        self.renderer, self.variant = renderer, variant
        self.log_path = log_dir / f"{renderer}{'_' + variant if variant else ''}.log"
        env_before = dict(os.environ)
        if renderer == "mitsuba" and variant.startswith("llvm"):
            setup_llvm_env()                  # inherited by the spawned child
        self.libllvm = os.environ.get("DRJIT_LIBLLVM_PATH")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=worker_main, daemon=True,
                                args=(child, renderer, variant, threads, str(self.log_path)))
        self.proc.start()
        child.close()
        os.environ.clear()
        os.environ.update(env_before)

    def log_tail(self, n: int = 6) -> str:
        try:
            lines = [l for l in self.log_path.read_text(errors="replace").splitlines() if l.strip()]
        except OSError:
            return ""
        return " | ".join(l.strip()[:200] for l in lines[-n:])

    def call(self, msg, timeout: float) -> dict:
        if not self.proc.is_alive():
            raise WorkerDied(f"worker is not running (exit code {self.proc.exitcode})")
        try:
            self.conn.send(msg)
        except OSError as e:
            self.proc.join(2)
            raise WorkerDied(f"worker gone ({e}; exit code {self.proc.exitcode}); "
                             f"log: {self.log_tail()}")
        deadline = time.perf_counter() + timeout
        while True:
            try:
                if self.conn.poll(0.2):
                    break
            except OSError:
                break
            if not self.proc.is_alive():
                raise WorkerDied(f"worker died (exit code {self.proc.exitcode}); log: {self.log_tail()}")
            if time.perf_counter() > deadline:
                self.proc.kill()
                raise WorkerDied(f"no answer in {timeout:.0f} s; worker killed; log: {self.log_tail()}")
        try:
            reply = self.conn.recv()
        except (EOFError, OSError):
            self.proc.join(2)
            raise WorkerDied(f"worker died (exit code {self.proc.exitcode}); log: {self.log_tail()}")
        if "error" in reply:
            raise RuntimeError(reply["error"])
        return reply

    def close(self):
        try:
            if self.proc.is_alive():
                self.call(("quit",), 10.0)
        except Exception:
            pass
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()


class RemoteRenderer:
    """Driver-side handle with the same render() as cmlt.accuracy.render.CmltRenderer."""

    def __init__(self, worker: Worker, ps: "PScene", timeout: float):
        self.worker = worker
        self.name = worker.renderer
        r = worker.call(("scene", ps), timeout)
        self.version = r["version"]
        self.setup_s = r["setup_s"]

    def render(self, integrator: str, budget: float, seed: int) -> dict:
        # generous: Mitsuba compiles kernels and calibrates before its timed passes
        return self.worker.call(("render", integrator, budget, seed), 300.0 + 3.0 * budget)["out"]


def small_copy(ps: "PScene", res=(16, 16)) -> "PScene":
    import copy
    q = copy.copy(ps)
    q.camera = copy.copy(ps.camera)
    q.camera.width, q.camera.height = res
    return q


def start_peer(renderer: str, variant_pref: str, ps: "PScene", threads: int, log_dir: Path,
               say: Callable[[str], None] = print):
    """Start a worker and check it renders a 16x16 version of ``ps``. Returns
    (worker or None, status dict); ``say`` gets the progress messages."""
    if renderer == "mitsuba":
        variants = ["llvm_ad_rgb", "scalar_rgb"] if variant_pref == "auto" else [variant_pref]
        module = "mitsuba"
    else:
        variants, module = [""], "pyluxcore"
    import importlib.util
    if importlib.util.find_spec(module) is None:
        return None, {"ok": False, "note": f"{module} is not installed in this Python "
                                           f"({sys.executable} -m pip install {module})"}
    tried = []
    for v in variants:
        say(f"starting {renderer} {v} ...")
        w = Worker(renderer, v, threads, log_dir)
        try:
            RemoteRenderer(w, small_copy(ps), 600.0)
            probe_integ = "path" if renderer == "mitsuba" else "PATHCPU"
            out = w.call(("render", probe_integ, 0.3, 1), 600.0)["out"]
            if not np.isfinite(out["image"]).all():
                raise RuntimeError("probe image is not finite")
        except Exception as e:
            tried.append(f"{v or renderer}: {e}")
            w.close()
            continue
        tried.append(f"{v or renderer}: ok")
        st = {"ok": True, "note": "; ".join(tried), "variant": v or None}
        if w.libllvm and v.startswith("llvm"):
            st["libllvm"] = w.libllvm
        return w, st
    return None, {"ok": False, "note": "; ".join(tried)}


# ============================================================== peers beside cmlt

def parse_peers(text: str) -> List[Tuple[str, str]]:
    """``mitsuba,luxcore:BIDIRCPU`` -> [("mitsuba", "path"), ("luxcore", "BIDIRCPU")];
    a renderer without an integrator gets its default (DEFAULT_PEER_INTEGRATORS). Raises
    ValueError naming an unknown renderer."""
    out = []
    for item in [t.strip() for t in text.split(",") if t.strip()]:
        ren, _, integ = item.partition(":")
        ren = ren.lower()
        if ren not in DEFAULT_PEER_INTEGRATORS:
            raise ValueError(f"--peers {text!r}: unknown peer {ren!r}; choose from "
                             f"{', '.join(DEFAULT_PEER_INTEGRATORS)} (renderer[:integrator])")
        out.append((ren, integ or DEFAULT_PEER_INTEGRATORS[ren]))
    if not out:
        raise ValueError(f"--peers {text!r}: name at least one peer")
    return out


class PeerSession:
    """The peers of an accuracy run: one worker process per renderer, started and probed
    once; :meth:`load` sends each frame's converted scene; :meth:`render` renders it to a
    wall-time budget. ``status[renderer]`` says whether it runs and why not."""

    def __init__(self, renderers: Sequence[str], probe_scene: "PScene", threads: int,
                 log_dir: str, variant: str = "auto", say: Callable[[str], None] = print):
        self.status: Dict[str, dict] = {}
        self.workers: Dict[str, Worker] = {}
        self.handles: Dict[str, RemoteRenderer] = {}
        self.say = say
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        for ren in dict.fromkeys(renderers):
            w, st = start_peer(ren, variant, probe_scene, threads, Path(log_dir), say=say)
            self.status[ren] = st
            if w is not None:
                self.workers[ren] = w

    def available(self, renderer: str) -> bool:
        return renderer in self.workers and self.status[renderer].get("ok", False)

    def load(self, ps: "PScene") -> None:
        """Build ``ps`` in every running peer; a peer that fails is marked as not running."""
        self.handles = {}
        for ren, w in list(self.workers.items()):
            if not self.status[ren].get("ok"):
                continue
            try:
                self.handles[ren] = RemoteRenderer(w, ps, 900.0)
                self.status[ren]["version"] = self.handles[ren].version
            except Exception as e:          # noqa: BLE001 - a peer's failure is reported
                self.status[ren]["ok"] = False
                self.status[ren]["note"] = f"scene build failed: {type(e).__name__}: {e}"
                self.say(f"{ren}: {self.status[ren]['note']}")

    def render(self, renderer: str, integrator: str, seconds: float, seed: int) -> dict:
        out = self.handles[renderer].render(integrator, seconds, seed)
        img = np.asarray(out["image"], dtype=np.float64)
        out["finite"] = bool(np.isfinite(img).all())
        out["image"] = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
        return out

    def close(self) -> None:
        for w in self.workers.values():
            w.close()
        self.workers = {}
