"""Frames split into Dask tasks (``cmlt render --dask SCHEDULER``; DESIGN.md §6).

What runs where, per frame:

* **client** (the process running the frame loop): reads the frame from the stage,
  runs the temporal driver's ``prepare`` (the pilot image of the pixel importance,
  the carry-over bootstrap, the coupling of the chain starts to the previous
  frame's), then, once the parts are back, combines them, normalises (the
  smoothed b), writes the frame atomically and keeps the state for the next frame.
  That state is small (the bootstrap's f*, the start picks, anchors, the b
  history): the frames of a cmlt sequence depend on each other only through it, and
  it never leaves the client.
* **workers**: one task per part of the frame. A task opens the stage itself (the
  shot's path is shipped, never geometry; a worker keeps the stage and the built
  core scene between tasks and only sends the core what changed), renders its part
  and returns raw sums:

  - pssmlt / cmlt: chains [c0, c1) of the frame's chains and the direct pass on rows
    [y0, y1); the result is the splat film's 128-bit fixed-point words and the
    normalisation accumulators of the bootstrap and of each chain. The client adds
    the words (integer adds: exact, in any order), merges the accumulators in chain
    order and develops the image in the core (``combine_mlt_parts``): bit for bit
    the single-process frame, for any number of parts or workers;
  - pt: rows [y0, y1) (a pixel's samples never leave its row band);
  - bdpt: the whole frame in one task (its light-tracing splats reach every pixel of
    a pass, so a pass does not split without moving W·H values per pass).

  The frame's shared inputs (pilot, bootstrap f*, chain starts) are scattered to the
  workers once per frame. A task is a pure function of its inputs, so when a worker
  dies Dask reruns its tasks elsewhere and the image is unchanged.

Time budgets are refused (a timed frame depends on the machine, and its parts would
end at different points).
"""
from __future__ import annotations

import os
import threading
import time
import uuid
from types import SimpleNamespace
from typing import Any, Dict, List, Optional

import numpy as np

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


# ---- the worker side ------------------------------------------------------------------

_WORKER: Dict[str, Any] = {}
_WORKER_LOCK = threading.Lock()


def _worker_stage(shot: str, stage_options: Optional[dict] = None) -> dict:
    """This worker's cache of ``shot``: the stage, opened once (with the client's
    ``stage_options``: variants, render settings prim), and its scene bridge."""
    import cmlt._core as core

    from ..usd import open_stage
    from .bridge import SceneBridge

    so = stage_options or {}
    variants = tuple(so.get("variants") or ())
    render_settings = so.get("render_settings")
    ident = (shot, variants, render_settings, so.get("ocio_config"), so.get("rendering_space"))
    c = _WORKER.get("shot")
    if c is None or c["ident"] != ident:
        from ..color import load_config, set_config
        stage = open_stage(shot, variants=variants, render_settings=render_settings)
        # the client's config and rendering space: colours are converted as it does
        set_config(load_config(so.get("ocio_config"), stage=stage,
                               rendering_space=so.get("rendering_space")))
        c = {"shot": shot, "ident": ident, "bridge": SceneBridge(core), "key": None,
             "stage": stage}
        _WORKER["shot"] = c
    return c


def open_shot(shot: str, stage_options: Optional[dict] = None) -> bool:
    """Open ``shot`` on this worker ahead of its first task (DaskRenderer.warm)."""
    with _WORKER_LOCK:
        _worker_stage(shot, stage_options)
    return True


def _worker_scene(shot: str, frame: float, camera, resolution,
                  stage_options: Optional[dict] = None):
    """(core, scene) of ``frame`` on this worker: the stage opened once per shot, the
    core scene updated with what changed since the worker's previous frame."""
    import cmlt._core as core

    from ..usd import load_frame

    so = stage_options or {}
    c = _worker_stage(shot, so)
    key = (float(frame), camera, tuple(resolution) if resolution else None)
    if c["key"] != key:
        c["key"] = None
        fs = load_frame(c["stage"], frame, camera=camera, resolution=resolution,
                        default_light=so.get("default_light") or "dome",
                        purposes=tuple(so["purposes"]) if so.get("purposes") else None)
        c["scene"] = c["bridge"].update(fs)
        c["key"] = key
    return core, c["scene"]


def render_part(spec: dict, shared: dict) -> dict:
    """One task: render the part ``spec`` of a frame (see the module doc) with the
    frame's ``shared`` inputs; returns its image rows / raw sums and stats. A pure
    function of (spec, shared)."""
    with _WORKER_LOCK:                   # one render per worker process at a time
        t0, c0 = time.perf_counter(), time.process_time()
        core, scene = _worker_scene(spec["shot"], spec["frame"], spec["camera"],
                                    spec["resolution"], spec.get("stage_options"))
        t_scene = time.perf_counter() - t0
        st = core.RenderSettings()
        for name, value in spec["settings"].items():
            setattr(st, name, value)
        threads = int(spec.get("threads") or 0)
        if threads <= 0:
            try:
                from distributed import get_worker
                threads = int(get_worker().state.nthreads)
            except Exception:            # not on a worker (tests call it directly)
                threads = 1
        st.threads = threads
        st.mlt_film_offset_x, st.mlt_film_offset_y = spec["film_offset"]
        if shared.get("pilot") is not None:
            st.pilot = shared["pilot"]
        if shared.get("bootstrap_f") is not None:
            st.mlt_bootstrap_f = shared["bootstrap_f"]
        if shared.get("initial_states") is not None:
            st.mlt_initial_states = core.MltStates.from_bytes(shared["initial_states"])
        rows, chains = spec.get("rows"), spec.get("chains")
        if rows is not None:
            st.partial = True
            st.part_row_begin, st.part_row_end = rows
            st.part_chain_begin, st.part_chain_end = chains if chains is not None else (0, 0)
        r = core.render(scene, st)
        y0, y1 = rows if rows is not None else (0, st.height)
        out = {"stats": dict(r.stats), "rows": (y0, y1),
               "image": np.asarray(r.image)[y0:y1].copy(),
               "variance": np.asarray(r.variance)[y0:y1].copy(),
               "direct": None if r.direct is None else np.asarray(r.direct)[y0:y1].copy(),
               "part": r.mlt_part, "bootstrap_f": None}
        if r.bootstrap_f is not None and spec.get("want_bootstrap_f"):
            out["bootstrap_f"] = np.asarray(r.bootstrap_f)
        # seconds: scene update, whole task (wall), whole task (CPU of the worker process)
        out["times"] = (t_scene, time.perf_counter() - t0, time.process_time() - c0)
        return out


# ---- the client side ------------------------------------------------------------------

#: RenderResult.stats entries that add up over the parts of a frame
_ADDITIVE = ("samples", "camera_rays", "shadow_rays", "rays", "splats", "busy_s", "trace_s",
             "shade_s", "nan_samples", "packet_queries", "packet_rays", "packet_shadow_rays",
             "bundle_rays", "bundle_busy_s", "bundle_trace_s", "states_visited",
             "long_streak_rejections")


def _scheduler_address(client) -> str:
    try:
        return str(client.scheduler.address)
    except AttributeError:
        return ""


def _nbytes(obj) -> int:
    from dask.sizeof import sizeof
    return int(sizeof(obj))


class DaskRenderer:
    """Renders the frames of one shot on a Dask cluster, part by part.

    ``parts``: tasks per frame (0: twice the number of workers). ``on_part``: called on
    the client as ``on_part(done, total, futures)`` after each part arrives (the
    progress bar; tests use it to kill a worker mid-frame)."""

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

    def warm(self) -> float:
        """Open the stage on every worker now (imports, USD composition), so that the
        first frame's tasks do not each pay for it; returns the seconds it took. A worker
        that joins later opens it with its first task."""
        t0 = time.perf_counter()
        self.client.run(open_shot, self.shot, self.stage_options)
        self.warm_s = time.perf_counter() - t0
        return self.warm_s

    def workers(self) -> int:
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def _settings_dict(self, core, st) -> dict:
        if self._fields is None:
            self._fields = [row["name"] for row in core.settings_table() if row.get("core", True)]
        return {name: getattr(st, name) for name in self._fields if hasattr(st, name)}

    def render(self, core, st, frame: float, reporter=None):
        """The frame ``frame`` with the settings ``st`` (core.RenderSettings, prepared by
        the temporal driver): a RenderResult-like namespace (image, variance, direct,
        bootstrap_f, cancelled, stats)."""
        integ = str(st.integrator)
        if float(st.time_budget) > 0.0:
            raise DistributedError("--dask: a time budget (--time-budget) is not supported: "
                                   "a timed frame depends on the machine; give --spp")
        W, H = int(st.width), int(st.height)
        n_workers = self.workers()
        n_parts = self.parts or 2 * n_workers
        if integ == "bdpt":
            n_parts = 1
        n_parts = max(1, min(n_parts, H))
        mlt = integ in ("pssmlt", "cmlt")
        t0 = time.perf_counter()

        # the frame's shared inputs, once per worker
        pilot = getattr(st, "pilot", None) if mlt else None
        boot = getattr(st, "mlt_bootstrap_f", None) if mlt else None
        states = getattr(st, "mlt_initial_states", None) if mlt else None
        shared = {"pilot": None if pilot is None else np.asarray(pilot, dtype=np.float32),
                  "bootstrap_f": None if boot is None else np.asarray(boot, dtype=np.float64),
                  "initial_states": None if states is None else bytes(states.to_bytes())}
        shared_bytes = _nbytes(shared)
        t_scatter = time.perf_counter()
        shared_f = self.client.scatter(shared, broadcast=True, hash=False)

        t_scatter = time.perf_counter() - t_scatter
        settings = self._settings_dict(core, st)
        rows = part_ranges(H, n_parts)
        chains = part_ranges(int(st.chains), n_parts) if mlt else [None] * n_parts
        token = uuid.uuid4().hex[:8]
        futures, spec_bytes = [], 0
        for k in range(n_parts):
            spec = {"shot": self.shot, "frame": float(frame), "camera": self.camera,
                    "resolution": self.resolution, "settings": settings,
                    "stage_options": self.stage_options,
                    "threads": self.threads,
                    "film_offset": (float(getattr(st, "mlt_film_offset_x", 0.0)),
                                    float(getattr(st, "mlt_film_offset_y", 0.0))),
                    "rows": None if integ == "bdpt" else rows[k], "chains": chains[k],
                    "want_bootstrap_f": k == 0 and boot is None}
            spec_bytes += _nbytes(spec)
            futures.append(self.client.submit(render_part, spec, shared_f, pure=False,
                                              key=f"cmlt-part-{frame:g}-{k}-{token}",
                                              retries=2))
        results: List[Optional[dict]] = [None] * n_parts
        index = {f.key: k for k, f in enumerate(futures)}
        from distributed import as_completed
        done = 0
        try:
            for fut in as_completed(futures):
                results[index[fut.key]] = fut.result()   # a task's error raises here, once
                done += 1
                if reporter is not None:
                    reporter.frame_progress(done, n_parts)
                if self.on_part is not None:
                    self.on_part(done, n_parts, futures)
        except BaseException:
            for f in futures:
                f.cancel()
            raise
        finally:
            shared_f.release() if hasattr(shared_f, "release") else None
        result_bytes = sum(_nbytes(r) for r in results)
        t_wait = time.perf_counter()
        out = self._combine(core, integ, W, H, results, boot)
        t_combine = time.perf_counter() - t_wait
        t_wait -= t0
        out.stats["time_s"] = time.perf_counter() - t0
        out.stats["rays_per_s"] = out.stats.get("rays", 0) / max(out.stats["time_s"], 1e-9)
        out.stats["dask"] = {
            "scheduler": self.address or _scheduler_address(self.client),
            "workers": n_workers, "tasks": n_parts,
            "bytes_to_workers": int(shared_bytes * n_workers + spec_bytes),
            "bytes_from_workers": int(result_bytes),
            "split": "chains+rows" if mlt else ("rows" if integ == "pt" else "frame"),
            # seconds: on the client (scatter of the shared inputs, until the last part
            # arrived, the combine), summed over the tasks (core render, whole task
            # including the worker's scene update, of it the scene update, the whole
            # task's CPU seconds)
            "warmup_s": self.warm_s,         # once per sequence: DaskRenderer.warm
            "scatter_s": t_scatter, "wait_s": t_wait, "combine_s": t_combine,
            "part_render_s": sum(float(r["stats"].get("time_s", 0.0)) for r in results),
            "part_task_s": sum(r["times"][1] for r in results),
            "part_scene_s": sum(r["times"][0] for r in results),
            "part_cpu_s": sum(r["times"][2] for r in results)}
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
        direct = None
        for r in results:
            y0, y1 = r["rows"]
            image[y0:y1] = r["image"]
            variance[y0:y1] = r["variance"]
            if r["direct"] is not None:
                if direct is None:
                    direct = np.zeros((H, W, 3), np.float32)
                direct[y0:y1] = r["direct"]
        bootstrap_f = None
        if integ in ("pssmlt", "cmlt"):
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
        return SimpleNamespace(image=image, variance=variance, direct=direct,
                               bootstrap_f=bootstrap_f, cancelled=False, stats=stats,
                               mlt_states=None, mlt_start_states=None)
