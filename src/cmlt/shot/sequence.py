"""The frame loop: open the stage once, then per frame load -> bridge ->
render (+ AOV pass) -> write preview, sidecar, EXR.

Guarantees:

* before the first frame renders, every output name is checked
  (:mod:`cmlt.shot.preflight`: an ``.exr`` that can be created, ``--state-dir`` a
  directory), so a bad ``--out`` fails at once and leaves nothing behind, and the
  temporaries of a killed render in those directories are removed;
* a frame's files (preview, state, sidecar, image) are all written to temporary
  names first and renamed into place only once every one of them is complete,
  the image last: a frame that fails to write leaves the previous frame's files
  as they were, and an image on disk always has its sidecar;
* Ctrl-C cancels the frame being rendered (the core's progress callback
  returns False), does not write it, keeps the finished frames and raises
  :class:`RenderCancelled`; ``resume=True`` then skips frames that are finished
  (the image reads completely, is finite, has this render's size and channels,
  and its sidecar is of that image and frame) and renders any other again;
* one seed for the whole shot, the same for every frame (DESIGN.md §4:
  random streams are keyed by shot seed, not frame, so that noise is
  correlated in time).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Union

from .analyse import resolve_auto_setting, resolve_chainless_setting
from .core_settings import core_settings, resolve
from .errors import RenderCancelled, RenderError, UsageError
from .frame_job import ShotJob, render_frame
from .frames import check_stage_range, default_frames, expand_outputs, parse_frames
from .options import (AOV_NAMES, PREVIEW_FORMATS, RenderOptions, check_aovs_for, default_output,
                      preview_path)
from .output import color_setup, stage_product
from .preflight import (check_output_paths, check_state_dir, finished_frame_problem,
                        remove_stale_temporaries)
from .progress import Reporter, frame_details
from .py_warnings import current_router, routes_python_warnings

__all__ = ["RenderOptions", "SequenceResult", "render_sequence", "default_output",
           "preview_path", "AOV_NAMES", "PREVIEW_FORMATS"]


@dataclass
class SequenceResult:
    frames: List[float] = field(default_factory=list)     # all requested frames
    written: List[str] = field(default_factory=list)      # image paths written now
    skipped: List[str] = field(default_factory=list)      # existing, skipped by resume
    stats: Dict[float, dict] = field(default_factory=dict)
    warnings: List[str] = field(default_factory=list)     # distinct, in order of appearance
    settings: Dict[str, object] = field(default_factory=dict)   # resolved, by name
    sources: Dict[str, str] = field(default_factory=dict)       # where each came from
    previews: List[str] = field(default_factory=list)     # preview paths written now
    elapsed_s: float = 0.0                                # wall time of the whole call
    #: frame-to-frame flicker of the frames rendered now (no reference, DESIGN.md §4;
    #: cmlt.metrics.FrameDifferenceFlicker.as_dict), None until a frame is rendered
    flicker: Optional[Dict[str, object]] = None


def _check_camera(stage, path: str, shot: str) -> None:
    from pxr import Sdf, UsdGeom

    if not Sdf.Path.IsValidPathString(path) or not Sdf.Path(path).IsAbsolutePath():
        raise UsageError(f"--camera {path!r}: not an absolute prim path")
    prim = stage.GetPrimAtPath(path)
    if not prim:
        raise UsageError(f"--camera {path}: no prim at that path in {shot}")
    if not prim.IsA(UsdGeom.Camera):
        raise UsageError(f"--camera {path}: prim is a {prim.GetTypeName() or 'typeless prim'}, "
                         f"not a Camera, in {shot}")


def _temporal_driver(job: ShotJob, width: int, height: int):
    from ..temporal import TemporalDriver

    return TemporalDriver(job.core, job.resolved, job.shot, width, height,
                          state_dir=job.opts.state_dir,
                          fresh_start_on_bad_state=job.opts.fresh_start_on_bad_state,
                          warn=lambda msg: job.warn([msg]))


def _load_previous_state(job: ShotJob, pred: float, frame: float):
    """Read the state of frame ``pred`` for ``frame`` (``--state-dir``); a bad
    file is a RenderError (one line naming it) unless --fresh-start-on-bad-state."""
    from ..temporal import StateError
    from ..temporal.state import state_path

    opts, info = job.opts, job.info
    if not opts.state_dir:
        return None
    try:
        note = job.temporal.load_previous(pred, frame)
    except StateError as exc:
        raise RenderError(f"{exc} (use --fresh-start-on-bad-state to start frame {frame:g} "
                          "fresh)") from None
    if note is None and (info.start is None or pred >= info.start) \
            and not os.path.exists(state_path(opts.state_dir, pred)):
        msg = (f"{state_path(opts.state_dir, pred)}: no state of frame {pred:g}; "
               f"frame {frame:g} starts fresh")
        job.warn([msg])
    return note


#: integrators whose frames depend on the frame before (chain states and/or the
#: smoothed normalisation b, DESIGN.md §4)
TEMPORAL_INTEGRATORS = ("pssmlt", "cmlt")


def _cold_resume_warning(resolved, opts: RenderOptions, todo, predecessor, outputs,
                         frame_list, resume: bool) -> str:
    """--resume of a pssmlt/cmlt sequence without --state-dir: a frame left to
    render follows one rendered by an earlier run (skipped now), whose chain
    states and normalisation history were not saved, so it starts cold. The
    warning names the first such frame ('' if there is none)."""
    if not resume or opts.state_dir or not todo or \
            str(resolved.integrator) not in TEMPORAL_INTEGRATORS:
        return ""
    if not (resolved.carry_states or resolved.smooth_normalization):
        return ""                       # every frame starts fresh anyway
    path_of = dict(zip(frame_list, outputs))
    now = {f for f, _ in todo}
    cold = [f for f, _ in todo if predecessor[f] not in now and predecessor[f] in path_of
            and os.path.isfile(path_of[predecessor[f]])]
    if not cold:
        return ""
    first = cold[0]
    more = f" (and {len(cold) - 1} more frame(s) after a gap)" if len(cold) > 1 else ""
    return (f"--resume without --state-dir: frame {first:g}{more} follows frame "
            f"{predecessor[first]:g} of an earlier run, whose chain states and normalisation "
            f"history were not saved; its {resolved.integrator} chains start fresh (render "
            f"with --state-dir DIR to continue a sequence across runs)")


def _settings_record(resolved, opts, colorspace_name, display, view, aovs) -> dict:
    """The sidecar's ``settings``: the resolved settings and the output options."""
    from ..color import get_config
    record = dict(resolved.as_dict(), threads=int(opts.threads), half=bool(opts.half),
                  compression=opts.compression, output_colorspace=colorspace_name,
                  rendering_space=get_config().rendering_space)
    if aovs:
        record.update(aovs=list(aovs), aov_samples=int(opts.aov_samples))
    if opts.crop is not None:
        record["crop"] = [int(v) for v in opts.crop]
    if opts.preview:
        record.update(preview=opts.preview_format, display=display, view=view)
    if opts.state_dir:
        record["state_dir"] = os.path.abspath(opts.state_dir)
    if opts.variants:
        record["variants"] = [str(v) for v in opts.variants]
    return record


def _finished_frame_expectation(resolved, opts: RenderOptions, aovs, layers=()) -> dict:
    """What a finished frame of this render holds (``finished_frame_problem``'s
    keywords): its size, its channels (beauty and AOVs, or the render product's
    layers) and its data window."""
    from ..io.exr import AOV_CHANNELS

    channels = ["R", "G", "B"]
    for layer in layers:
        channels += layer.channels()
    for name in aovs if not layers else ():
        prefix, suffixes = AOV_CHANNELS[name]
        channels += [prefix] if suffixes is None else [f"{prefix}.{c}" for c in suffixes]
    size = tuple(int(v) for v in (opts.resolution or resolved.resolution))
    return {"size": size, "channels": channels,
            "crop": tuple(int(v) for v in opts.crop) if opts.crop is not None else None}


def _frame_list(frames, info) -> List[float]:
    if frames is None:
        return default_frames(info.start)
    if isinstance(frames, str):
        return parse_frames(frames, info.start, info.end, info.has_authored_time_range)
    return [float(f) for f in frames]


def _open(shot: str, core, variants=(), render_settings=None):
    """(stage, info, core) of a shot that exists; the core imported if not given."""
    if not os.path.exists(shot):
        raise UsageError(f"{shot}: no such file")
    if os.path.isdir(shot):
        raise UsageError(f"{shot}: is a directory, not a USD file")
    from ..usd import UsdLoadError, open_stage, stage_info
    from ..usd.variants import VariantError
    if core is None:
        try:
            import cmlt._core as core
        except ImportError as exc:
            raise RenderError(f"the C++ core cmlt._core is not built: {exc}") from None
    try:
        stage = open_stage(shot, variants=variants, render_settings=render_settings)
        info = stage_info(stage)
    except VariantError as exc:
        raise UsageError(str(exc)) from None
    except UsdLoadError as exc:
        raise RenderError(str(exc)) from None
    return stage, info, core


@routes_python_warnings
def render_sequence(shot: str, frames: Union[None, str, Sequence[float]] = None,
                    out: Optional[str] = None, options: Optional[RenderOptions] = None, *,
                    resume: bool = False, progress: bool = True, quiet: bool = False,
                    reporter: Optional[Reporter] = None, core=None, verbosity: int = 1,
                    client=None, on_part=None, on_estimate=None,
                    force_frames: bool = False) -> SequenceResult:
    """Render ``frames`` of ``shot`` to ``out`` (a pattern, see
    :mod:`cmlt.shot.frames`).

    ``frames``: None (the stage's start frame), a ``--frames`` spec, or a
    list of time codes. Frames outside the stage's time range are a warning;
    far outside it (:func:`cmlt.shot.frames.check_stage_range`) a UsageError
    unless ``force_frames``. Raises :class:`UsageError`, :class:`RenderError`
    or :class:`RenderCancelled`.

    ``client``: a ``distributed.Client``; the frames' parts then run as Dask tasks
    (:mod:`cmlt.shot.distributed`; ``options.dask`` = ``local:N`` or a scheduler address
    makes one for the call). ``on_part(done, total, futures)``: called after each
    part arrives (with a client). ``on_estimate(work, seconds, relmse)``: with a target
    error (``options.target_error``), called from the render thread with each estimate
    of the frame being rendered (work: passes for pt/bdpt, path evaluations per pixel
    for pssmlt/cmlt; seconds into the frame; the estimated relMSE).
    """
    opts = options or RenderOptions()
    opts.check()
    stage, info, core = _open(shot, core, opts.variants, opts.render_settings)
    resolved, sources = resolve(stage, opts)
    if opts.camera:
        _check_camera(stage, opts.camera, shot)
    frame_list = _frame_list(frames, info)
    effects_cache: dict = {}                # time -> FrameEffects (cmlt.analysis)
    auto = resolve_auto_setting(stage, info, core, frame_list, opts, resolved, sources,
                                effects_cache)
    chainless = resolve_chainless_setting(stage, info, core, frame_list, opts, resolved, sources,
                                          effects_cache)
    st = core_settings(core, resolved, opts, sources)
    color_attrs, colorspace_name, display, view = color_setup(opts, stage)
    product = stage_product(stage, opts, out)
    layers = tuple(product.layers) if product is not None else ()
    aovs = product.aovs() if layers else tuple(n for n in AOV_NAMES if n in opts.aovs)
    check_aovs_for(aovs, resolved.integrator, getattr(resolved, "error_groups", 8))
    t_start = time.perf_counter()
    range_warning = check_stage_range(frame_list, info.start, info.end,
                                      info.has_authored_time_range, force=force_frames,
                                      spec=frames if isinstance(frames, str) else None)
    pattern = out or (product.product_name if product is not None else "") \
        or default_output(shot)
    try:
        outputs = expand_outputs(pattern, frame_list)
    except UsageError as exc:
        if out or product is None or not product.product_name:
            raise
        raise UsageError(str(exc).replace("--out", f"{product.path}: productName", 1)) from None
    # before the first frame: every output can be written as an EXR (no stray sidecar of
    # a frame whose image cannot be), the state directory is one, and the temporaries a
    # killed render left in those directories go
    check_output_paths(pattern, outputs, [preview_path(p, opts.preview_format)
                                          for p in outputs] if opts.preview else ())
    check_state_dir(opts.state_dir)
    removed = remove_stale_temporaries([os.path.dirname(os.path.abspath(p)) for p in outputs]
                                       + ([opts.state_dir] if opts.state_dir else []))

    result = SequenceResult(frames=list(frame_list), sources=dict(sources),
                            settings=_settings_record(resolved, opts, colorspace_name,
                                                      display, view, aovs))
    if "error_groups" in result.settings:       # the groups the core runs (core_settings)
        result.settings["error_groups"] = int(st.error_groups)
    if auto is not None:
        result.settings["integrator_auto"] = auto.as_dict()
    if chainless is not None:
        result.settings["chainless_integrator_auto"] = chainless.as_dict()
    todo, redo = [], []
    if product is not None and product.path:
        result.settings["render_product"] = product.as_dict()
    expect = _finished_frame_expectation(resolved, opts, aovs, layers)
    for f, path in zip(frame_list, outputs):
        if resume and os.path.lexists(path):
            # a frame is skipped only when it is really done: a truncated or empty
            # image, or one without its sidecar, is rendered again
            why = finished_frame_problem(path, f, **expect)
            if why is None:
                result.skipped.append(path)
                continue
            redo.append(f"--resume: {path} is not a finished frame ({why}); rendering "
                        f"frame {f:g} again")
        todo.append((f, path))
    # the frame before each frame (temporal carry-over): the previous one in the
    # list, or for the list's first frame one step back
    step = (frame_list[1] - frame_list[0]) if len(frame_list) > 1 else 1.0
    predecessor = {f: (frame_list[i - 1] if i > 0 else f - step) for i, f in enumerate(frame_list)}
    from ..metrics.flicker import FrameDifferenceFlicker
    flick = FrameDifferenceFlicker()        # frame-to-frame flicker (DESIGN.md §4)

    rep = reporter or Reporter(show_progress=progress, quiet=quiet, verbosity=verbosity)
    job = ShotJob(shot=shot, stage=stage, info=info, opts=opts, core=core, st=st,
                  resolved=resolved, sources=sources, color_attrs=color_attrs, display=display,
                  view=view, aovs=aovs, settings_record=result.settings, reporter=rep,
                  result=result, effects_cache=effects_cache, on_estimate=on_estimate,
                  layers=layers)
    job.make_temporal = lambda w, h: _temporal_driver(job, w, h)
    router = current_router()           # the Python warnings so far, and from now on
    early = router.attach(job.warn) if router is not None else []
    own_client = None
    if client is None and opts.dask:
        client, own_client = _dask_client(opts.dask)
    if client is not None:
        if float(getattr(resolved, "time_budget", 0.0) or 0.0) > 0.0:
            _close(own_client)
            raise UsageError("--dask: a time budget (--time-budget) does not split over "
                             "workers (a timed frame depends on the machine); give --spp")
        if float(getattr(resolved, "target_error", 0.0) or 0.0) > 0.0:
            _close(own_client)
            raise UsageError("--dask: --target-error does not split over workers (each "
                             "part would stop on its own estimate); give --spp")
        from .distributed import DaskRenderer
        job.distributed = DaskRenderer(client, shot, camera=opts.camera,
                                       resolution=opts.resolution, parts=int(opts.dask_parts),
                                       threads=0, on_part=on_part,
                                       address=opts.dask or "",
                                       stage_options={
                                           "variants": tuple(opts.variants),
                                           "render_settings": opts.render_settings,
                                           "default_light": opts.default_light,
                                           "purposes": tuple(opts.purposes),
                                           "ocio_config": opts.ocio_config,
                                           "rendering_space": opts.rendering_space})
        result.settings["dask"] = opts.dask or "client"
        try:
            job.distributed.warm()
        except Exception as exc:         # a worker cannot open the shot: say so once
            _close(own_client)
            raise RenderError(f"{shot}: --dask: a worker cannot open the shot: {exc}") from None
    stage_warnings = early + [w for w in info.warnings
                      if not (opts.camera and w == info.settings_camera_warning)]  # moot
    cold = _cold_resume_warning(resolved, opts, todo, predecessor, outputs, frame_list, resume)
    if range_warning:
        stage_warnings.append(range_warning)
    if removed:
        stage_warnings.append(
            f"removed {len(removed)} temporary file(s) left by a render that was killed: "
            + ", ".join(removed[:3]) + (f", ... ({len(removed) - 3} more)"
                                        if len(removed) > 3 else ""))
    stage_warnings += redo + (product.warnings if product is not None else [])
    if cold:
        stage_warnings.append(cold)
    try:
        _frames(job, rep, result, todo, predecessor, stage_warnings, flick, t_start)
    finally:
        _close(own_client)
    return result


def _dask_client(address: str):
    """(client, (client, cluster)) for ``--dask ADDRESS``; the second closes them."""
    from .distributed import DistributedError, connect
    try:
        client, cluster = connect(address)
    except DistributedError as exc:
        raise UsageError(str(exc)) from None
    return client, (client, cluster)


def _close(own) -> None:
    if own is None:
        return
    client, cluster = own
    client.close()
    if cluster is not None:
        cluster.close()


def _setup_details(job, todo):
    """``(level, text)`` lines describing the render before its first frame (``-v``)."""
    from ..color import get_config
    r, opts = job.resolved, job.opts
    first = todo[0][1] if todo else "-"
    yield 2, (f"{job.shot}: {len(todo)} frame(s) to render, first -> {first}; integrator "
              f"{r.integrator}, {r.spp} spp, max depth {r.max_depth}, seed {r.seed}, "
              f"threads {opts.threads or 'all'}")
    yield 2, f"colour: {get_config().describe()}"
    if job.layers:
        yield 2, "channels: R, G, B, " + ", ".join(c for layer in job.layers
                                                   for c in layer.channels())
    for name, value in sorted(r.as_dict().items()):
        yield 3, f"setting {name} = {value!r} ({job.sources.get(name, 'default')})"


def _frames(job, rep, result, todo, predecessor, stage_warnings, flick, t_start) -> None:
    """The frame loop of render_sequence."""
    with rep:
        rep.warnings(stage_warnings)
        result.warnings.extend(stage_warnings)
        if result.skipped:
            rep.info(f"resume: {len(result.skipped)} frame(s) already rendered, "
                     f"{len(todo)} to go")
        for level, text in _setup_details(job, todo):
            rep.detail(text, level)
        rep.start_sequence(len(todo))
        if job.distributed is not None:     # which frame's tasks go ahead of which
            job.distributed.plan([f for f, _ in todo], predecessor)
        try:
            _frame_loop(job, rep, result, todo, predecessor, flick)
        finally:
            if job.distributed is not None:
                job.distributed.close()
        result.elapsed_s = time.perf_counter() - t_start
        rep.end_sequence(result)


def _frame_loop(job, rep, result, todo, predecessor, flick) -> None:
    """Render the frames of ``todo`` in order (render_sequence's loop)."""
    last_rendered = None
    for k, (frame, path) in enumerate(todo):
        pred = predecessor[frame]
        follows = last_rendered is not None and last_rendered == pred

        def prepare_temporal():
            if not follows:
                # not continuing in memory: the state file of the frame before, if any
                job.temporal.forget()
                note = _load_previous_state(job, pred, frame)
                if note:
                    rep.info(note)
        try:
            rep.start_frame(frame)
            done = render_frame(job, frame, path, prepare_temporal)
            # flicker of the full frames in the output colour space, as `cmlt flicker`
            # measures the EXRs (only consecutive frames of the list are paired)
            flick.add(done["out_image"], follows=follows)
            if done["preview"]:
                result.previews.append(done["preview"])
            job.temporal.advance(done["state_bytes"],
                                 done["state_file"] or f"<state of frame {frame:g}>")
            last_rendered = frame
            result.written.append(path)
            result.stats[frame] = done["stats"]
            result.flicker = flick.as_dict()
            rep.end_frame(frame, path, done["stats"], done["units"])
            for level, text in frame_details(frame, done):
                rep.detail(text, level)
        except KeyboardInterrupt:
            rep.abort_frame()
            raise RenderCancelled(frame, result.written, len(todo) - k) from None
