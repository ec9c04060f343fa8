"""Frames split into Dask tasks (``cmlt render --dask SCHEDULER``; DESIGN.md §6).

What runs where, per frame (the workers' side is :mod:`cmlt.shot.dask_worker`):

* **client** (the process running the frame loop): reads the frame from the stage,
  submits its tasks, and once its parts are back combines them, normalises (the
  smoothed b, which needs the b history of every frame before), writes the frame
  atomically and keeps the state for the next frame, as without Dask.
* **workers**: per frame, one *preparation* task — the temporal driver's
  :func:`cmlt.temporal.driver.prepare_frame`: the seed, the screen anchors and film
  offset (every integrator), for pssmlt / cmlt also the pilot image of the pixel
  importance, the carry-over bootstrap and the chain starts coupled to the previous
  frame's — and one task per *part*. A frame's
  preparation takes the previous frame's preparation as its input (its f*, starts and
  anchors: what the next frame needs of a frame, never its image), so the
  preparations are a task chain from frame to frame; the first frame's comes from the
  client's state (the frame before in memory, or ``--state-dir``). A task opens the
  stage itself (the shot's path is shipped, never geometry; a worker keeps the stage
  and the built scenes of its last two frames and only sends the core what changed).
  The parts return raw sums:

  - pssmlt / cmlt: chains [c0, c1) of the frame's chains and the direct pass on rows
    [y0, y1), with the frame's preparation as their shared input; the result is the
    splat film's 128-bit fixed-point words and the normalisation accumulators of the
    bootstrap and of each chain. The client adds the words (integer adds: exact, in
    any order), merges the accumulators in chain order and develops the image in the
    core (``combine_mlt_parts``): bit for bit the single-process frame, for any number
    of parts or workers;
  - pt: rows [y0, y1) (a pixel's samples never leave its row band);
  - bdpt: the whole frame in one task (its light-tracing splats reach every pixel of
    a pass, so a pass does not split without moving W·H values per pass); frames
    still run side by side, one per worker.

* **parts per frame** (``--dask-parts``; 0, the default, is :meth:`DaskRenderer.auto_parts`):
  one per frame while the run of frames left covers the workers, so frames run side by
  side and none pays a further part's fixed cost; one per worker for a single frame and
  the last frames of a run.
* **pipelining**: while frame f renders, the tasks of the next frames are submitted
  (``AHEAD`` of them, more when a frame has fewer parts than there are workers), each
  when it follows the one before in the loop and the settings match (else a frame's
  tasks are submitted when it comes). Priorities keep the order: a
  frame's parts before the next frame's, and a frame's preparation before the parts
  of the frame before it, so the workers render frame f+1 while the client combines
  and writes frame f, and the preparation chain never waits behind parts.

A task is a pure function of its inputs, so when a worker dies Dask reruns what it
lost (a lost preparation from the one before it) and the images are unchanged.

Time budgets are refused (a timed frame depends on the machine, and its parts would
end at different points).
"""
from __future__ import annotations

import os
import time
import uuid
from types import SimpleNamespace
from typing import Dict, List, Optional

import numpy as np

from ..temporal.driver import carry_of
from .dask_worker import open_shot, prepare_task, render_part

__all__ = ["connect", "DaskRenderer", "DistributedError", "part_ranges"]


class DistributedError(RuntimeError):
    """A --dask scheduler that cannot be reached or used."""


def connect(address: str):
    """A ``distributed.Client`` for ``address``: ``local:N`` starts a LocalCluster of N
    single-threaded worker processes on this machine, anything else is a scheduler
    address (``tcp://host:8786``). Returns (client, cluster or None)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise DistributedError(f"--dask needs the 'distributed' package (pip install "
                               f"'cmlt[dask]'): {exc}") from None
    if address.startswith("local:"):
        try:
            n = int(address[len("local:"):])
        except ValueError:
            n = 0
        if n < 1:
            raise DistributedError(f"--dask {address}: expected local:N with N >= 1 workers")
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=":0")
        return Client(cluster), cluster
    try:
        return Client(address, timeout=30), None
    except (OSError, TimeoutError) as exc:
        raise DistributedError(f"--dask {address}: cannot reach the scheduler: {exc}") from None


def part_ranges(n: int, parts: int) -> List[tuple]:
    """[(begin, end)] of ``parts`` near-equal consecutive ranges covering 0..n."""
    parts = max(1, int(parts))
    return [(n * k // parts, n * (k + 1) // parts) for k in range(parts)]


# ---- the client side ------------------------------------------------------------------

#: RenderResult.stats entries that add up over the parts of a frame
_ADDITIVE = ("samples", "camera_rays", "shadow_rays", "rays", "splats", "busy_s", "trace_s",
             "shade_s", "nan_samples", "packet_queries", "lane_hits", "packet_rays",
             "packet_shadow_rays", "bundle_rays", "bundle_busy_s", "bundle_trace_s", "states_visited",
             "long_streak_rejections")


def _scheduler_address(client) -> str:
    try:
        return str(client.scheduler.address)
    except AttributeError:
        return ""


def _static(settings: dict) -> str:
    """What must match for tasks submitted ahead to be a frame's: its settings but the
    seed (the preparation sets it per frame)."""
    return repr(sorted((k, v) for k, v in settings.items() if k != "seed"))


def _nbytes(obj) -> int:
    """Bytes of ``obj`` pickled (as Dask sends it: an object referenced twice once)."""
    import pickle
    return len(pickle.dumps(obj, protocol=5))


#: frames whose tasks are submitted while a frame renders (the workers start the next
#: frames' preparations and parts while the client combines and writes this one): at
#: least AHEAD, and enough to give every worker two parts (fewer parts per frame than
#: workers: frames side by side), at most AHEAD_MAX
AHEAD, AHEAD_MAX = 2, 64


class DaskRenderer:
    """Renders the frames of one shot on a Dask cluster, part by part, one frame ahead.

    ``parts``: part tasks per frame (0: :meth:`auto_parts`). ``on_part``: called on
    the client as ``on_part(done, total, futures)`` after each part arrives (the
    progress bar; tests use it to kill a worker mid-frame).

    Per frame the client calls :meth:`prepare` (submits the frame's tasks unless they
    were submitted ahead, submits the next frame's, and returns the temporal record of
    the frame's preparation) and then :meth:`render` (waits for the parts and combines
    them). :meth:`plan` tells it which frame follows which in the loop."""

    def __init__(self, client, shot: str, camera=None, resolution=None, parts: int = 0,
                 threads: int = 0, on_part=None, address: str = "",
                 stage_options: Optional[dict] = None):
        self.client = client
        self.shot = os.path.abspath(shot)
        self.camera = camera
        self.resolution = tuple(resolution) if resolution else None
        self.parts = int(parts)
        self.threads = int(threads)
        self.on_part = on_part
        self.address = address
        #: how the workers open and read the stage, as the client does: variants,
        #: render_settings (prim path), default_light, purposes
        self.stage_options = dict(stage_options or {})
        self._fields = None
        self.warm_s = 0.0
        self._next: Dict[float, float] = {}     # frame -> the frame rendered after it
        self._run_left: Dict[float, int] = {}   # frame -> pipelined frames from it on
        self._ahead: Dict[float, dict] = {}     # frame -> its submitted tasks
        self._frame: Optional[dict] = None      # the frame being rendered
        self._submitted = 0                     # frames submitted so far

    def warm(self) -> float:
        """Open the stage on every worker now (imports, USD composition), so that the
        first frame's tasks do not each pay for it; returns the seconds it took. A worker
        that joins later opens it with its first task."""
        t0 = time.perf_counter()
        self.client.run(open_shot, self.shot, self.stage_options)
        self.warm_s = time.perf_counter() - t0
        return self.warm_s

    def workers(self) -> int:
        return max(1, len(self.worker_addresses()))

    def worker_addresses(self) -> List[str]:
        return sorted(self.client.scheduler_info().get("workers", {}))

    def plan(self, frames: List[float], predecessor: Dict[float, float]) -> None:
        """The frames the loop renders, in order: a frame whose predecessor (the frame
        its carried state comes from) is the one rendered just before it is submitted
        while that one renders."""
        self._next = {f: n for f, n in zip(frames, frames[1:]) if predecessor.get(n) == f}
        # frames in the run of pipelined frames from each frame on (itself included)
        self._run_left = {}
        for f in reversed(frames):
            n = self._next.get(f)
            self._run_left[f] = 1 + (self._run_left.get(n, 0) if n is not None else 0)

    def auto_parts(self, frame: float, n_workers: int) -> int:
        """Parts of ``frame`` with ``--dask-parts 0``: one while at least as many
        pipelined frames remain (itself included) as there are workers — the frames then
        run side by side, one per worker, and no frame pays for a further part — else
        one per worker (a single frame, and the last frames of a run, still spread)."""
        return 1 if self._run_left.get(float(frame), 1) >= n_workers else n_workers

    def close(self) -> None:
        """Cancel what was submitted ahead and not used (an interrupted loop)."""
        for h in list(self._ahead.values()) + ([self._frame] if self._frame else []):
            self._cancel(h)
        self._ahead.clear()
        self._frame = None

    def _settings_dict(self, core, st) -> dict:
        if self._fields is None:
            self._fields = [row["name"] for row in core.settings_table() if row.get("core", True)]
        return {name: getattr(st, name) for name in self._fields if hasattr(st, name)}

    @staticmethod
    def _cancel(h: dict) -> None:
        futures = ([h["prep"]] if h.get("prep") is not None else []) + h["parts"]
        for f in futures:
            f.cancel()

    def _submit(self, frame: float, settings: dict, temporal, prev) -> dict:
        """Submit frame ``frame``'s tasks: its preparation (from ``prev``: the previous
        frame's preparation future, the client's carry dict or None; the seed and the
        film offset, for pssmlt/cmlt also the pilot, bootstrap and chain starts) and its
        parts, which take the preparation as their shared input."""
        integ = str(settings["integrator"])
        W, H = int(settings["width"]), int(settings["height"])
        addresses = self.worker_addresses()
        n_workers = max(1, len(addresses))
        mlt = integ in ("pssmlt", "cmlt")
        # bdpt frames do not split, nor do Metropolis frames that bdpt renders where they
        # have no chains (chainless_integrator bdpt: whole frames, chains or not)
        whole = integ == "bdpt" or (mlt and str(settings.get("chainless_integrator", "pt")) == "bdpt")
        n_parts = 1 if whole else (self.parts or self.auto_parts(frame, n_workers))
        n_parts = max(1, min(n_parts, H))
        config = temporal.config()
        settings = dict(settings)
        base = {"shot": self.shot, "frame": float(frame), "camera": self.camera,
                "resolution": self.resolution, "settings": settings,
                "stage_options": self.stage_options, "threads": self.threads}
        token = uuid.uuid4().hex[:8]
        # priorities (higher first): a frame's parts before the next frame's, and a
        # frame's preparation before the parts of the frame before it (the
        # preparations are the chain every later frame waits for)
        self._submitted += 1
        order = -2 * self._submitted
        prep = self.client.submit(prepare_task, dict(base, temporal=config), prev,
                                  pure=False, key=f"cmlt-prepare-{frame:g}-{token}",
                                  retries=2, priority=order + 3)
        rows = part_ranges(H, n_parts)
        chains = part_ranges(int(settings["chains"]), n_parts) if mlt else [None] * n_parts
        futures, spec_bytes = [], 0
        for k in range(n_parts):
            spec = dict(base, rows=None if whole else rows[k], chains=chains[k],
                        want_bootstrap_f=mlt and k == 0 and not config["carry"])
            spec_bytes += _nbytes(spec)
            # Spread the parts over the workers, rotating from frame to frame: left to
            # itself the scheduler runs a frame's parts where its preparation's result
            # is (data locality), so with the preparations' chain on one worker the
            # others idle (2 local workers: 11 of 14 s busy against 14 of 14 s). A
            # preferred worker only: any other takes the part if that one is gone.
            place = ({"workers": [addresses[(k + self._submitted) % len(addresses)]],
                      "allow_other_workers": True} if addresses else {})
            futures.append(self.client.submit(render_part, spec, prep, pure=False,
                                              key=f"cmlt-part-{frame:g}-{k}-{token}",
                                              retries=2, priority=order, **place))
        return {"frame": float(frame), "key": _static(settings), "integ": integ, "W": W,
                "H": H, "mlt": mlt, "prep": prep, "parts": futures, "n_parts": n_parts,
                "n_workers": n_workers, "spec_bytes": spec_bytes, "prep_out": None,
                "t0": time.perf_counter()}

    def prepare(self, core, temporal, st, frame: float) -> dict:
        """Before the frame ``frame`` renders with ``st`` (core.RenderSettings, its
        size set): its tasks (submitted ahead, if they were submitted with these
        settings; else now, from the temporal driver's state), the next frame's, and
        the frame's preparation adopted by the driver. Returns its temporal record."""
        if float(st.time_budget) > 0.0:
            raise DistributedError("--dask: a time budget (--time-budget) is not supported: "
                                   "a timed frame depends on the machine; give --spp")
        settings = self._settings_dict(core, st)
        t0 = time.perf_counter()
        h = self._ahead.pop(float(frame), None)
        if h is not None and h["key"] != _static(settings):
            self._cancel(h)             # submitted with other settings: not this frame's
            h = None
        if h is None:
            prev = {"carry": carry_of(temporal.prev)} if temporal.prev is not None else None
            h = self._submit(frame, settings, temporal, prev)
        else:
            h["ahead"] = True
        h["t0"] = t0
        self._frame = h
        # the next AHEAD frames' tasks, each preparation from the one before
        f, prep = float(frame), h["prep"]
        ahead = min(AHEAD_MAX, max(AHEAD, -(-2 * h["n_workers"] // h["n_parts"])))
        for _ in range(ahead):
            f = self._next.get(f)
            if f is None:
                break
            if f not in self._ahead:
                self._ahead[f] = self._submit(f, settings, temporal, prep)
            prep = self._ahead[f]["prep"]
        try:
            out = h["prep"].result()     # a task's error raises here, once
        except BaseException:
            self.close()
            raise
        h["prep_out"] = out
        return temporal.adopt(st, dict(out["rec"]), dict(out["pending"]))

    def render(self, core, st, frame: float, reporter=None):
        """The frame ``frame`` (after :meth:`prepare`): a RenderResult-like namespace
        (image, variance, robust, direct, bootstrap_f, cancelled, stats)."""
        h = self._frame
        if h is None or h["frame"] != float(frame):
            raise DistributedError(f"--dask: frame {frame:g} rendered before it was prepared")
        integ, W, H, n_parts = h["integ"], h["W"], h["H"], h["n_parts"]
        futures = h["parts"]
        results: List[Optional[dict]] = [None] * n_parts
        index = {f.key: k for k, f in enumerate(futures)}
        from distributed import as_completed
        done = 0
        t_wait = time.perf_counter()
        try:
            for fut in as_completed(futures):
                results[index[fut.key]] = fut.result()   # a task's error raises here, once
                done += 1
                if reporter is not None:
                    reporter.frame_progress(done, n_parts)
                if self.on_part is not None:
                    self.on_part(done, n_parts, futures)
        except BaseException:
            self.close()
            raise
        self._frame = None
        t_combine = time.perf_counter()
        t_wait = t_combine - t_wait
        prep = h["prep_out"] or {}
        shared = prep.get("st") or {}
        boot = shared.get("bootstrap_f")
        out = self._combine(core, integ, W, H, results, boot)
        t_combine = time.perf_counter() - t_combine
        result_bytes = sum(_nbytes(r) for r in results)
        shared_bytes = _nbytes(prep) if prep else 0
        # the preparation moves to each other worker that ran a part of the frame
        moved = len({r.get("worker") for r in results} - {prep.get("worker")}) if prep else 0
        out.stats["time_s"] = time.perf_counter() - h["t0"]
        out.stats["rays_per_s"] = out.stats.get("rays", 0) / max(out.stats["time_s"], 1e-9)
        ptimes = prep.get("times") or (0.0, 0.0, 0.0)
        out.stats["dask"] = {
            "scheduler": self.address or _scheduler_address(self.client),
            "workers": h["n_workers"], "tasks": n_parts + 1,
            "parts": n_parts, "submitted_ahead": bool(h.get("ahead")),
            # how many workers ran them (the parts are spread: DaskRenderer._submit)
            "part_workers": len({r.get("worker") for r in results}),
            # the preparation to the other workers of its parts, the specs to their
            # tasks; the parts and the preparation come back to the client
            "bytes_to_workers": int(shared_bytes * moved + h["spec_bytes"]),
            "bytes_from_workers": int(result_bytes + shared_bytes),
            "split": "chains+rows" if h["mlt"] else ("rows" if integ == "pt" else "frame"),
            # seconds: on the client (waiting for the preparation and the parts, the
            # combine), on the workers (the preparation's task; summed over the parts:
            # core render, whole task including the worker's scene update, of it the
            # scene update, the whole task's CPU seconds: of the worker process, and of
            # the task's thread)
            "warmup_s": self.warm_s,         # once per sequence: DaskRenderer.warm
            "wait_s": t_wait, "combine_s": t_combine,
            "prepare_task_s": float(ptimes[0]), "prepare_cpu_s": float(ptimes[1]),
            "prepare_thread_cpu_s": float(ptimes[2]),
            "part_render_s": sum(float(r["stats"].get("time_s", 0.0)) for r in results),
            "part_task_s": sum(r["times"][1] for r in results),
            "part_scene_s": sum(r["times"][0] for r in results),
            "part_cpu_s": sum(r["times"][2] for r in results),
            "part_thread_cpu_s": sum(r["times"][3] for r in results)}
        return out

    @staticmethod
    def _combine(core, integ: str, W: int, H: int, results: List[dict], boot):
        stats = dict(results[0]["stats"])
        for key in _ADDITIVE:
            if key in stats:
                stats[key] = sum(r["stats"].get(key, 0) for r in results)
        stats["max_rejection_streak"] = max(r["stats"].get("max_rejection_streak", 0)
                                            for r in results)
        image = np.zeros((H, W, 3), np.float32)
        variance = np.zeros((H, W, 3), np.float32)
        # each pixel's trimmed mean (the estimate's denominator), NaN where a part has none
        robust = np.full((H, W, 3), np.nan, np.float32)
        direct = None
        for r in results:
            y0, y1 = r["rows"]
            image[y0:y1] = r["image"]
            variance[y0:y1] = r["variance"]
            if r.get("robust") is not None:
                robust[y0:y1] = r["robust"]
            if r["direct"] is not None:
                if direct is None:
                    direct = np.zeros((H, W, 3), np.float32)
                direct[y0:y1] = r["direct"]
        bootstrap_f = None
        if integ in ("pssmlt", "cmlt") and all(r["part"] is not None for r in results):
            # (a whole Metropolis frame, chainless_integrator bdpt, is its task's image)
            parts = [r["part"] for r in results]       # in chain order: part k has chains k
            image, mst = core.combine_mlt_parts(W, H, parts, direct)
            image = np.asarray(image)
            stats.update(b=mst["b"], b_stderr=mst["b_stderr"], mutations=mst["mutations"],
                         mutations_per_pixel=mst["mutations"] / float(W * H),
                         clamped_splats=mst["clamped_splats"])
            if boot is not None:
                bootstrap_f = np.asarray(boot, dtype=np.float64).astype(np.float32)
            else:
                bootstrap_f = results[0]["bootstrap_f"]
        return SimpleNamespace(image=image, variance=variance, robust=robust, direct=direct,
                               bootstrap_f=bootstrap_f, cancelled=False, stats=stats,
                               mlt_states=None, mlt_start_states=None)
