"""One frame's job: load the frame, update the core scene, render it on a
worker thread (so that Ctrl-C reaches the main thread), let the temporal
driver rescale it, and write preview, state, sidecar and EXR — the image last,
so that a finished image always has its sidecar (and preview and state).
"""
from __future__ import annotations

import hashlib
import os
import signal
import threading
import time
from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

import numpy as np

from .._version import __version__
from ..color import ColorError
from ..io.exr import ExrWriteError, NonFiniteImageError, check_crop, write_exr
from ..io.preview import write_preview
from ..io.sidecar import write_sidecar
from .analyse import frame_effects
from .bridge import BridgeError, SceneBridge
from .core_settings import settings_message
from .errors import RenderError, UsageError
from .memory import scene_memory
from .options import preview_path
from .output import aov_images, header_metadata, product_channels, to_output
from .progress import Reporter

__all__ = ["ShotJob", "render_frame", "render_interruptible"]


@dataclass
class ShotJob:
    """What every frame of a sequence shares, and what the frames so far left."""

    shot: str
    stage: Any
    info: Any                           # cmlt.usd.StageInfo
    opts: Any                           # RenderOptions
    core: Any                           # the cmlt._core module
    st: Any                             # core.RenderSettings (width, height set per frame)
    resolved: Any                       # cmlt.settings.RenderSettings
    sources: Dict[str, str]
    color_attrs: Dict[str, Any]         # EXR colour-space attributes
    display: Optional[str]
    view: Optional[str]
    aovs: Tuple[str, ...]
    settings_record: Dict[str, Any]     # the sidecar's "settings"
    reporter: Reporter
    result: Any                         # SequenceResult
    bridge: SceneBridge = None
    temporal: Any = None                # TemporalDriver, made on the first frame
    make_temporal: Any = None           # (width, height) -> TemporalDriver
    distributed: Any = None             # cmlt.shot.distributed.DaskRenderer (--dask), or None
    effects_cache: Any = None           # time -> FrameEffects (cmlt.shot.analyse)
    on_estimate: Any = None             # (work, seconds, relmse) -> None: the live estimate
    layers: Tuple = ()                  # the render product's layers (cmlt.usd.render_products)
    held: Any = None                    # (hold_key, RenderResult, frame) of the last render

    def __post_init__(self):
        if self.bridge is None:
            self.bridge = SceneBridge(self.core)
        self.shot_abs = os.path.abspath(self.shot)

    def warn(self, texts) -> None:
        """Show warnings and keep the distinct ones in the result."""
        self.reporter.warnings(texts)
        for w in texts:
            if w not in self.result.warnings:
                self.result.warnings.append(w)


#: how the caveat of target_error_caveat begins
CAVEAT_PT_TARGET = "--target-error with pt: caustics carry"


def target_error_caveat(resolved, effects: dict) -> Optional[str]:
    """The warning for ``--target-error`` with pt on a frame whose caustics carry at least
    :data:`cmlt.analysis.auto.CAUSTIC_SHARE` of the flux onto what the camera sees: pt
    finds those paths (L S+ D seen from the camera) only by BSDF-sampling into the light
    through the specular chain, so its pass-to-pass variance does not see most of their
    error, and the estimate falls short of it (tests/bench/results/accuracy:
    caustic_glass pt measured 1.4-5x its target). None otherwise."""
    from ..analysis.auto import CAUSTIC_SHARE
    if float(getattr(resolved, "target_error", 0.0) or 0.0) <= 0.0:
        return None
    if str(getattr(resolved, "integrator", "")) != "pt":
        return None
    share = float(effects.get("caustic_share", 0.0))      # auto's rule (analysis/auto.py)
    if share < CAUSTIC_SHARE:
        return None
    return (f"{CAVEAT_PT_TARGET} {share:.0%} of the light on what the "
            "camera sees, and pt samples them too rarely for its error estimate to see "
            "their error: the frame may stop well above the target (bdpt or cmlt estimate "
            "it; --integrator auto picks bdpt here)")


class _SigintFlag:
    """SIGINT handled by ``on_interrupt()`` instead of KeyboardInterrupt, until
    restore() puts the previous handler back."""

    def __init__(self, on_interrupt):
        self._previous = signal.signal(signal.SIGINT, lambda signum, frame: on_interrupt())

    def restore(self) -> None:
        signal.signal(signal.SIGINT, self._previous)


def _interrupt_handler(on_interrupt) -> Optional[_SigintFlag]:
    """A _SigintFlag where Ctrl-C would raise KeyboardInterrupt on this thread (the main
    thread, Python's default handler installed), else None."""
    if threading.current_thread() is not threading.main_thread():
        return None
    try:
        if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            return None
        return _SigintFlag(on_interrupt)
    except (ValueError, OSError):       # no signals here (an embedding interpreter)
        return None


def render_interruptible(core, scene, st, reporter: Reporter, on_estimate=None):
    """Run core.render on a worker thread so that Ctrl-C reaches the main
    thread promptly; the progress callback then asks the core to stop.
    With a target error, each estimate goes to the reporter's frame bar and to
    ``on_estimate(work, seconds, relmse)``. Returns (result, interrupted, units_total)."""
    cancel = threading.Event()
    box: dict = {}
    last_total = [None]

    def progress(done, total):
        last_total[0] = total
        reporter.frame_progress(done, total)
        return not cancel.is_set()

    def estimate(work_done, seconds, relmse):
        shown = getattr(reporter, "frame_estimate", None)
        if shown is not None:
            shown(work_done, seconds, relmse)
        if on_estimate is not None:
            on_estimate(work_done, seconds, relmse)

    targeted = float(getattr(st, "target_error", 0.0) or 0.0) > 0.0
    finished = threading.Event()

    def work():
        try:
            extra = {"on_estimate": estimate} if targeted else {}
            box["result"] = core.render(scene, st, progress=progress, **extra)
        except BaseException as exc:          # re-raised on the main thread
            box["error"] = exc
        finally:
            finished.set()

    worker = threading.Thread(target=work, name="cmlt-render", daemon=True)
    interrupted = False

    def interrupt():
        nonlocal interrupted
        if interrupted:
            reporter.warn("still cancelling; waiting for the render threads to stop")
        interrupted = True
        cancel.set()

    # While the render runs, Ctrl-C only asks it to stop. Python's own handler raises
    # KeyboardInterrupt wherever the main thread happens to be — between the waits below
    # that can be outside any try — and the process would exit with the core still
    # rendering on the worker, whose threads then meet the interpreter's finalisation
    # ("terminate called without an active exception", SIGABRT). Only where Ctrl-C is to
    # raise at all (Python's default handler; not where it is ignored, as in a background
    # job) and only on the main thread (a Dask worker's frames keep the checks below).
    handler = _interrupt_handler(interrupt)
    try:
        try:
            worker.start()
        except KeyboardInterrupt:
            # Ctrl-C inside start(), where no handler was installed: the thread may be
            # running already. It must never be left rendering while the process exits,
            # so cancel it and wait below.
            interrupt()
            if worker.ident is None:        # it never started
                raise
        # Wait on an Event, not Thread.join: an interrupted join can leave the
        # thread looking finished while it still runs.
        while not finished.is_set():
            try:
                finished.wait(0.05)
            except KeyboardInterrupt:
                interrupt()
    finally:
        if handler is not None:
            handler.restore()
    if "error" in box:
        raise box["error"]
    return box["result"], interrupted, last_total[0]


def _load(job: ShotJob, frame: float):
    from ..usd import UsdLoadError, load_frame

    opts = job.opts
    try:
        fs = load_frame(job.stage, frame, camera=opts.camera, resolution=opts.resolution,
                        default_light=opts.default_light,
                        purposes=opts.purposes if opts.purposes else None)
    except (UsdLoadError, ColorError) as exc:
        raise RenderError(f"{job.shot}: frame {frame:g}: {exc}"
                          if isinstance(exc, ColorError) else str(exc)) from None
    job.warn(fs.warnings)
    return fs


def _settings_error(job: ShotJob, exc) -> Exception:
    msg, usage = settings_message(str(exc), job.resolved, job.sources)
    return (UsageError if usage else RenderError)(msg)


def _check_chains(job: ShotJob, scene) -> None:
    """pssmlt/cmlt: the chains this frame starts (the core's count: at most
    ``chains``, at most what the budget feeds) must fit in memory, checked before
    the driver or the core allocates them; a ``chains`` the budget cannot feed is
    a warning naming its flag or attribute (once per sequence). A frame without chains
    (mlt_paths auto on a scene without near-specular materials) is a warning once."""
    from .core_settings import where
    from .preflight import chain_memory_problem

    core, resolved = job.core, job.resolved
    if str(resolved.integrator) not in ("pssmlt", "cmlt") or \
            not hasattr(core, "temporal_chain_count"):
        return
    if hasattr(core, "mlt_resolve_paths"):
        job.st.mlt_paths = str(resolved.mlt_paths)  # as requested (the driver resolves per frame)
        if core.mlt_resolve_paths(scene, job.st) == "none":
            # no chains in this frame: say so once (a user who asked for Metropolis gets
            # a path-traced frame)
            if not getattr(job, "_chainless_warned", False):
                job._chainless_warned = True
                how = ("rendered by bdpt (--chainless-integrator: "
                       f"{job.sources.get('chainless_integrator', 'given')})"
                       if str(getattr(resolved, "chainless_integrator", "pt")) == "bdpt"
                       else "path traced")
                job.warn([f"{resolved.integrator}: no material of the frame can be near-specular, so "
                          f"there are no caustic paths for the chains (--mlt-paths auto): the frame "
                          f"is {how}; --mlt-paths all runs the chains on every path"])
            return
    n = int(core.temporal_chain_count(job.st))
    asked = int(resolved.chains)
    name = where("chains", asked, job.sources)
    problem = chain_memory_problem(n, name)
    if problem:
        user = not job.sources.get("chains", "").startswith("stage:")
        raise (UsageError if user else RenderError)(problem)
    if asked > n and job.sources.get("chains", "default") != "default" and \
            not getattr(job, "_chains_warned", False):
        job._chains_warned = True
        job.warn([f"{name}: the budget of a {job.st.width}x{job.st.height} frame at spp "
                  f"{job.st.spp} feeds only {n} chain(s), so {n} run"])


def hold_key(job: ShotJob, st) -> Optional[bytes]:
    """What a frame's render depends on beyond its core scene and the job's fixed
    settings; None when the frame may not be held: timed (its work depends on the
    machine), rendered by Dask, or --no-frame-hold. A frame whose core scene is the last
    frame's (SceneBridge's UpdateReport.unchanged) and whose key is the last render's
    takes that render (_render).

    The core's render is a function of the scene and the settings alone, bit for bit
    (any thread count; the random streams are keyed by seed, chain and dimension, never
    by the frame). The key is every scalar setting (the size, the seed — per frame with
    --seed-per-frame —, the film offset, what auto resolved for the frame, ...) and, for
    pssmlt/cmlt, the chain starts, the bootstrap values and the pilot the temporal driver
    gives the frame. A frame with the same scene and the same key renders the last
    frame's image, variance and statistics exactly, so it takes them instead (a held
    shot with stored seeds: a static camera over a still set).
    """
    if not getattr(job.opts, "hold_frames", True) or job.distributed is not None:
        return None
    if float(getattr(st, "time_budget", 0.0) or 0.0) > 0.0:
        return None
    h = hashlib.sha256()
    scalars = []
    for name in sorted(dir(st)):
        if not name.startswith("_"):
            v = getattr(st, name)
            if isinstance(v, (bool, int, float, str)):
                scalars.append((name, v))
    h.update(repr(scalars).encode())
    states = getattr(st, "mlt_initial_states", None)
    h.update(b"states:" + (b"-" if states is None else bytes(states.to_bytes())))
    for name in ("mlt_bootstrap_f", "pilot"):
        v = getattr(st, name, None)
        h.update(name.encode() + b":" + (b"-" if v is None else
                                         np.ascontiguousarray(v, dtype=np.float64).tobytes()))
    keys = getattr(st, "pixel_keys", None)
    h.update(b"pixel_keys:" + (b"-" if keys is None else np.asarray(keys, dtype="<u4").tobytes()))
    return h.digest()


def _render(job: ShotJob, scene, frame: float, width: int, height: int):
    """The core's render of the frame (the temporal driver around it), checked
    finite; returns (result, stats, image, temporal record, state bytes, units)."""
    core, resolved = job.core, job.resolved
    _check_chains(job, scene)
    try:
        if job.distributed is not None:     # on the workers, maybe submitted ahead
            trec = job.distributed.prepare(core, job.temporal, job.st, frame)
        else:
            trec = job.temporal.prepare(scene, job.st, frame)
    except core.SettingsError as exc:
        raise _settings_error(job, exc) from None
    except core.SceneError as exc:
        raise RenderError(f"{job.shot}: frame {frame:g}: {exc}") from None
    budget = getattr(job.reporter, "frame_budget", None)
    if budget is not None:          # the live rate of the frame bar
        timed = float(getattr(resolved, "time_budget", 0.0) or 0.0) > 0.0
        budget(None if timed else float(width) * float(height) * float(resolved.spp))
    key = hold_key(job, job.st)
    same_scene = job.bridge.last_update is not None and job.bridge.last_update.unchanged
    held = (job.held if key is not None and same_scene and job.held is not None
            and job.held[0] == key else None)
    try:
        if held is not None:                # the last frame's render, bit for bit
            r, interrupted, units = held[1], False, None
        elif job.distributed is not None:   # the frame's parts as Dask tasks
            r, interrupted, units = job.distributed.render(core, job.st, frame, job.reporter), \
                False, None
        else:
            r, interrupted, units = render_interruptible(core, scene, job.st, job.reporter,
                                                         job.on_estimate)
    except core.SettingsError as exc:
        raise _settings_error(job, exc) from None
    except core.SceneError as exc:
        raise RenderError(f"{job.shot}: frame {frame:g}: {exc}") from None
    if interrupted or r.cancelled:
        raise KeyboardInterrupt
    stats = dict(r.stats)
    if held is not None:
        # the image and its statistics are frame held[2]'s; this frame traced nothing
        stats["held_from_frame"] = float(held[2])
        for k in ("time_s", "rays", "rays_per_s", "busy_s", "trace_s"):
            if k in stats:
                stats[k] = type(stats[k])(0)
    else:
        job.held = (key, r, frame) if key is not None else None
    image = np.asarray(r.image)
    if not np.isfinite(image).all():
        raise RenderError(f"{job.shot}: frame {frame:g}: the core returned "
                          f"{int((~np.isfinite(image)).sum())} non-finite pixel values")
    from ..metrics.error_estimate import estimate_record
    stats["error_estimate"] = estimate_record(r, stats)     # relMSE without a reference
    image, trec, state_bytes = job.temporal.finish(r, stats, image, frame, trec)
    return r, stats, image, trec, state_bytes, units


def _write(job: ShotJob, path: str, frame: float, image, out_image, crop, record, metadata,
           aovs, state_bytes, group_images=None):
    """Preview, state, sidecar and EXR, each written to a temporary name and
    renamed into place only once all four are complete, the image last
    (:func:`cmlt.io.atomic.staged_paths`): a frame that fails to write leaves
    the previous frame's files as they were. Returns (state file, preview)."""
    from ..io.atomic import staged_paths
    from ..io.exr import HALF_MAX
    from ..io.sidecar import sidecar_path

    opts = job.opts
    pv = state_file = None
    finals = []
    if opts.preview:
        pv = preview_path(path, opts.preview_format)
        record["preview"] = os.path.basename(pv)
        finals.append(pv)
    if opts.state_dir:
        from ..temporal.state import state_path
        state_file = state_path(opts.state_dir, frame)
        record["temporal"]["state_out"] = os.path.abspath(state_file)
        finals.append(state_file)
    finals += [sidecar_path(path), path]
    tmp = {}

    def named(text: str) -> str:        # messages name the final files, not temporaries
        for final, t in tmp.items():
            text = text.replace(t, final)
        return text
    try:
        with staged_paths(finals) as tmps:
            tmp.update(zip(finals, tmps))
            if pv:
                shown = image if crop is None else image[crop[1]:crop[3], crop[0]:crop[2]]
                if opts.exposure:             # previews only: the EXR stays as rendered
                    shown = shown * (2.0 ** float(opts.exposure))
                write_preview(shown, tmp[pv], job.display, job.view)
            if state_file:
                from ..temporal.state import write_state
                write_state(tmp[state_file], state_bytes)
            aovs, layout, halfs = product_channels(aovs, job.layers)
            clamped, peak = write_exr(tmp[path], out_image, half=opts.half,
                                      compression=opts.compression, colorspace=None,
                                      metadata=metadata, attributes=job.color_attrs, aovs=aovs,
                                      crop=crop, layers=layout, half_channels=halfs)
            if clamped:
                msg = (f"--half: frame {frame:g}: {clamped} value(s) above half's largest "
                       f"finite value {HALF_MAX:g} (up to {peak:.6g}) clamped to it in {path}; "
                       "write float (no --half) to keep them")
                record.setdefault("warnings", []).append(msg)
                job.warn([msg])
            groups = _group_images(job, group_images, path)
            if groups:
                record["error_group_images"] = groups
            write_sidecar(path, record, to=tmp[sidecar_path(path)])
    except ExrWriteError as exc:            # its message starts with the path
        raise RenderError(named(f"cannot write: {exc}")) from None
    except NonFiniteImageError as exc:      # e.g. an overflow in the output colour space
        raise RenderError(named(f"frame {frame:g}: {exc}")) from None
    except OSError as exc:
        name = named(str(exc.filename)) if exc.filename else ""
        where = f" ({name})" if name and name != path else ""
        raise RenderError(named(f"{path}: cannot write: {exc.strerror or exc}{where}")) from None
    return state_file, pv


def group_image_path(path: str, g: int) -> str:
    """Where ``--group-images`` writes error group g of the frame at ``path``."""
    root, ext = os.path.splitext(path)
    return f"{root}.group{g}{ext or '.exr'}"


def _group_images(job: ShotJob, r_groups, path: str):
    """``--group-images``: each error group's image (pssmlt/cmlt, before the temporal
    normalisation) as its own EXR beside the frame; their file names, or None."""
    if r_groups is None or not getattr(job.st, "keep_group_images", False):
        return None
    names = []
    for g, img in enumerate(np.asarray(r_groups)):
        gp = group_image_path(path, g)
        write_exr(gp, np.ascontiguousarray(img, dtype=np.float32), half=job.opts.half,
                  compression=job.opts.compression, colorspace=None,
                  attributes=job.color_attrs, metadata={"errorGroup": g})
        names.append(os.path.basename(gp))
    return names


def render_frame(job: ShotJob, frame: float, path: str, prepare_temporal) -> Dict[str, Any]:
    """Render ``frame`` of the job's shot to ``path``. ``prepare_temporal()``
    runs once the frame is loaded and the temporal driver exists (it loads the
    state of the frame before when the sequence does not continue in memory).
    Returns the frame's output (``out_image``: the image as written, ``stats``,
    ``state_bytes``, ``state_file``, ``preview``, ``units``: the progress
    total). KeyboardInterrupt means the frame was cancelled, nothing written."""
    opts, core = job.opts, job.core
    t0 = time.perf_counter()
    fs = _load(job, frame)
    phases = {"load": time.perf_counter() - t0}
    width, height = opts.resolution or fs.resolution
    job.st.width, job.st.height = int(width), int(height)
    crop = None
    if opts.crop is not None:
        try:
            crop = check_crop(opts.crop, int(width), int(height))
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    import warnings
    try:
        # the bridge's warnings (an unreadable texture, ...) are the frame's warnings,
        # shown as such, not as Python UserWarning lines
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            scene = job.bridge.update(fs)
        phases["scene update"] = time.perf_counter() - t0 - phases["load"]
    except (core.SceneError, BridgeError) as exc:
        raise RenderError(f"{job.shot}: frame {frame:g}: {exc}") from None
    memory = scene_memory(core, scene)        # the sidecar's: before the render
    bridge_warnings = [str(w.message) for w in caught]
    if bridge_warnings:
        job.warn(list(dict.fromkeys(bridge_warnings)))
        fs.warnings = list(fs.warnings) + [w for w in dict.fromkeys(bridge_warnings)
                                           if w not in fs.warnings]
    if job.temporal is None:
        job.temporal = job.make_temporal(int(width), int(height))
    prepare_temporal()
    effects = frame_effects(fs, scene, core, opts.resolution, job.effects_cache)
    caveat = target_error_caveat(job.resolved, effects)
    if caveat and not any(w.startswith(CAVEAT_PT_TARGET) for w in job.result.warnings):
        job.warn([caveat])              # once per render (the share varies by frame)
    r, stats, image, trec, state_bytes, units = _render(job, scene, frame, width, height)
    if stats.get("direct_alone") and stats.get("paths") != "none" and \
            not getattr(job, "_no_chain_warned", False):
        # the frame planned chains, but its bootstrap found no path for them: say so once
        job._no_chain_warned = True
        job.warn([f"{stats.get('integrator')}: frame {frame:g}: the bootstrap's "
                  f"{int(stats.get('bootstrap_samples', 0))} samples found no path for the chains "
                  f"(--mlt-paths {stats.get('paths')}), so no chain started and the direct pass "
                  f"rendered its own paths with their budget too; the chains' paths add nothing "
                  f"to this frame, as where the chains find none of them (unbiased over frames; "
                  f"a larger --bootstrap-samples may find paths for the chains)"])
    probe = (trec or {}).get("start_probe") or {}
    if stats.get("mlt_too_few_starts") or probe.get("too_few"):
        expected = stats.get("mlt_expected_starts", probe.get("expected_starts", 0.0))
        if not getattr(job, "_few_starts_warned", False):
            # the start probe moved the frame to the chainless integrator: say so once
            job._few_starts_warned = True
            job.warn([f"{job.resolved.integrator}: frame {frame:g}: a probe predicts that "
                      f"{float(expected):.3g} of the bootstrap's samples carry light for the "
                      f"chains (fewer than --mlt-min-starts {int(job.resolved.mlt_min_starts)}), "
                      f"so the frame is rendered without chains (as --mlt-paths none); "
                      f"--mlt-min-starts 0 runs them"])
    aovs = aov_images(core, scene, job.st, r, job.aovs, opts, stats)
    stats["wall_time_s"] = time.perf_counter() - t0
    camera = fs.camera.name if fs.camera is not None else None
    record = {
        "image": os.path.basename(path), "shot": job.shot_abs, "frame": frame,
        "time_code": float(fs.time), "camera": camera,
        "resolution": [int(width), int(height)],
        "settings": job.settings_record, "settings_sources": dict(job.sources),
        "stats": stats, "scene_update": job.bridge.last_update.as_dict(),
        "warnings": list(fs.warnings), "cmlt_version": __version__,
        "core_isa": getattr(core, "isa", None), "temporal": trec,
        "effects": effects,
        "memory": memory,
    }
    metadata = header_metadata(frame, fs, job.shot_abs, camera, job.resolved, stats,
                               temporal=trec)
    out_image = to_output(image, opts.output_colorspace)
    state_file, pv = _write(job, path, frame, image, out_image, crop, record, metadata, aovs,
                            state_bytes, getattr(r, "group_images", None))
    phases.update(render=float(stats.get("time_s", 0.0)), AOVs=stats.get("aov_time_s"),
                  write=time.perf_counter() - t0 - stats["wall_time_s"])
    return {"out_image": out_image, "stats": stats, "state_bytes": state_bytes,
            "state_file": state_file, "preview": pv, "units": units, "record": record,
            "phases": phases}
