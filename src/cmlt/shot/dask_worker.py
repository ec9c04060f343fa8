"""The worker side of ``cmlt render --dask`` (cmlt.shot.distributed): the tasks a
Dask worker runs, and the stage and built scenes it keeps between them.

* :func:`prepare_task`: a pssmlt/cmlt frame's preparation, the temporal driver's
  :func:`cmlt.temporal.driver.prepare_frame` (pilot, screen anchors, carry-over
  bootstrap, chain starts coupled to the previous frame's) from the previous frame's
  preparation (a Dask future: the frames' preparations are a task chain) or from the
  state the client holds for the first frame;
* :func:`render_part`: one part of a frame (chains and rows, or rows), with the
  frame's preparation as its shared input.

A worker keeps the stage (opened once per shot) and the core scenes of its last two
frames (a frame's parts and the next frame's preparation run side by side), each
updated from the frame it held with only what changed. Both tasks are pure functions
of their inputs, so a task Dask reruns elsewhere gives the same result.
"""
from __future__ import annotations

import threading
import time
from typing import Any, Dict, Optional

import numpy as np

__all__ = ["open_shot", "prepare_task", "render_part"]

#: built core scenes a worker keeps (the frame whose parts run, the next one's preparation)
SCENES_KEPT = 2

_WORKER: Dict[str, Any] = {}
_WORKER_LOCK = threading.Lock()


def _worker_stage(shot: str, stage_options: Optional[dict] = None) -> dict:
    """This worker's cache of ``shot``: the stage, opened once (with the client's
    ``stage_options``: variants, render settings prim), and its built scenes."""
    from ..usd import open_stage

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
        c = {"shot": shot, "ident": ident, "scenes": [], "stage": stage}
        _WORKER["shot"] = c
    return c


def open_shot(shot: str, stage_options: Optional[dict] = None) -> bool:
    """Open ``shot`` on this worker ahead of its first task (DaskRenderer.warm)."""
    with _WORKER_LOCK:
        _worker_stage(shot, stage_options)
    return True


def _worker_scene(spec: dict):
    """(core, scene) of the spec's frame on this worker: one of the last SCENES_KEPT
    frames' scenes, else the least recently used one updated to this frame."""
    import cmlt._core as core

    from ..usd import load_frame
    from .bridge import SceneBridge

    so = spec.get("stage_options") or {}
    c = _worker_stage(spec["shot"], so)
    res = spec["resolution"]
    key = (float(spec["frame"]), spec["camera"], tuple(res) if res else None)
    scenes = c["scenes"]                 # least recently used first
    for e in scenes:
        if e["key"] == key:
            scenes.remove(e)
            scenes.append(e)
            return core, e["scene"]
    e = scenes.pop(0) if len(scenes) >= SCENES_KEPT else {"bridge": SceneBridge(core)}
    fs = load_frame(c["stage"], key[0], camera=spec["camera"], resolution=res,
                    default_light=so.get("default_light") or "dome",
                    purposes=tuple(so["purposes"]) if so.get("purposes") else None)
    e["scene"] = e["bridge"].update(fs)  # a failed update drops the entry
    e["key"] = key
    scenes.append(e)
    return core, e["scene"]


def _settings(core, spec: dict):
    st = core.RenderSettings()
    for name, value in spec["settings"].items():
        setattr(st, name, value)
    threads = int(spec.get("threads") or 0)
    if threads <= 0:
        try:
            from distributed import get_worker
            threads = int(get_worker().state.nthreads)
        except Exception:                # not on a worker (tests call it directly)
            threads = 1
    st.threads = threads
    return st


def _address() -> str:
    """This worker's address ('' when not on a worker)."""
    try:
        from distributed import get_worker
        return str(get_worker().address)
    except Exception:                    # tests call the tasks directly
        return ""


def prepare_task(spec: dict, prev: Optional[dict]) -> dict:
    """The preparation of the spec's frame (module doc). ``prev``: the previous
    frame's preparation (its ``carry``), or ``{"carry": ...}`` from the client, or
    None. Returns the temporal record and pending values for the client, the render
    settings the frame's parts take (``st``) and the ``carry`` of the next frame."""
    from ..temporal.driver import prepare_frame

    with _WORKER_LOCK:
        t0, c0, h0 = time.perf_counter(), time.process_time(), time.thread_time()
        core, scene = _worker_scene(spec)
        st = _settings(core, spec)
        rec, pending = prepare_frame(core, scene, st, float(spec["frame"]), spec["temporal"],
                                     prev.get("carry") if prev else None)
        boot = pending["boot_f"]
        boot = None if boot is None else np.asarray(boot, dtype=np.float64)
        pending = dict(pending, boot_f=boot)
        pilot = getattr(st, "pilot", None)
        states = getattr(st, "mlt_initial_states", None)
        return {
            "rec": rec, "pending": pending,
            "st": {"seed": int(st.seed),
                   "pilot": None if pilot is None else np.asarray(pilot, dtype=np.float32),
                   "bootstrap_f": boot,
                   "initial_states": None if states is None else bytes(states.to_bytes()),
                   "film_offset": (float(st.film_offset_x), float(st.film_offset_y)),
                   "pixel_keys": pending.get("pixel_keys")},
            # what the next frame's preparation reads (as its FrameState would hold it)
            "carry": {"anchors": list(pending["anchors"]),
                      "film_offset": tuple(pending["film_offset"]),
                      "pixel_keys": pending.get("pixel_keys"),
                      "boot_f": b"" if boot is None else boot,      # the same values
                      "start_picks": list(pending["picks"])},
            "worker": _address(),
            "times": (time.perf_counter() - t0, time.process_time() - c0,
                      time.thread_time() - h0)}


def render_part(spec: dict, shared: Optional[dict]) -> dict:
    """One task: render the part ``spec`` of a frame (cmlt.shot.distributed) with the
    frame's preparation ``shared`` (its seed and film offset; for pssmlt/cmlt also the
    pilot, bootstrap and chain starts); returns its image rows / raw sums and stats. A
    pure function of (spec, shared)."""
    with _WORKER_LOCK:                   # one render per worker process at a time
        t0, c0, h0 = time.perf_counter(), time.process_time(), time.thread_time()
        core, scene = _worker_scene(spec)
        t_scene = time.perf_counter() - t0
        st = _settings(core, spec)
        given = (shared or {}).get("st") or {}
        if given:
            st.seed = given["seed"]
            st.film_offset_x, st.film_offset_y = given["film_offset"]
            if given.get("pixel_keys") is not None:
                st.pixel_keys = given["pixel_keys"]
            if given.get("pilot") is not None:
                st.pilot = given["pilot"]
            if given.get("bootstrap_f") is not None:
                st.mlt_bootstrap_f = given["bootstrap_f"]
            if given.get("initial_states") is not None:
                st.mlt_initial_states = core.MltStates.from_bytes(given["initial_states"])
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
               "robust": None if r.robust is None else np.asarray(r.robust)[y0:y1].copy(),
               "direct": None if r.direct is None else np.asarray(r.direct)[y0:y1].copy(),
               "part": r.mlt_part, "bootstrap_f": None}
        out["worker"] = _address()
        if r.bootstrap_f is not None and spec.get("want_bootstrap_f"):
            out["bootstrap_f"] = np.asarray(r.bootstrap_f)
        # seconds: scene update, whole task (wall), whole task (CPU of the worker process,
        # its other threads included; CPU of the task's thread, where a one-thread render
        # runs)
        out["times"] = (t_scene, time.perf_counter() - t0, time.process_time() - c0,
                        time.thread_time() - h0)
        return out
