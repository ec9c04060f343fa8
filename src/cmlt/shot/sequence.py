"""The frame loop: open the stage once, then per frame load -> bridge ->
render (+ AOV pass) -> write preview, sidecar, EXR.

Guarantees:

* a frame's image appears under its final name only when it is complete
  (temporary name + rename); its sidecar is written just before it, so an
  image on disk always has its sidecar;
* Ctrl-C cancels the frame being rendered (the core's progress callback
  returns False), does not write it, keeps the finished frames and raises
  :class:`RenderCancelled`; ``resume=True`` then skips frames whose image
  exists;
* one seed for the whole shot, the same for every frame (DESIGN.md §4:
  random streams are keyed by shot seed, not frame, so that noise is
  correlated in time).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Union

from .core_settings import core_settings, resolve
from .errors import RenderCancelled, RenderError, UsageError
from .frame_job import ShotJob, render_frame
from .frames import default_frames, expand_outputs, parse_frames
from .options import (AOV_NAMES, PREVIEW_FORMATS, RenderOptions, check_aovs_for, default_output,
                      preview_path)
from .output import color_setup
from .progress import Reporter

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
    record = dict(resolved.as_dict(), threads=int(opts.threads), half=bool(opts.half),
                  compression=opts.compression, output_colorspace=colorspace_name)
    if aovs:
        record.update(aovs=list(aovs), aov_samples=int(opts.aov_samples))
    if opts.crop is not None:
        record["crop"] = [int(v) for v in opts.crop]
    if opts.preview:
        record.update(preview=opts.preview_format, display=display, view=view)
    if opts.state_dir:
        record["state_dir"] = os.path.abspath(opts.state_dir)
    return record


def _frame_list(frames, info) -> List[float]:
    if frames is None:
        return default_frames(info.start)
    if isinstance(frames, str):
        return parse_frames(frames, info.start, info.end, info.has_authored_time_range)
    return [float(f) for f in frames]


def _open(shot: str, core):
    """(stage, info, core) of a shot that exists; the core imported if not given."""
    if not os.path.exists(shot):
        raise UsageError(f"{shot}: no such file")
    if os.path.isdir(shot):
        raise UsageError(f"{shot}: is a directory, not a USD file")
    from ..usd import UsdLoadError, open_stage, stage_info
    if core is None:
        try:
            import cmlt._core as core
        except ImportError as exc:
            raise RenderError(f"the C++ core cmlt._core is not built: {exc}") from None
    try:
        stage = open_stage(shot)
        info = stage_info(stage)
    except UsdLoadError as exc:
        raise RenderError(str(exc)) from None
    return stage, info, core


def render_sequence(shot: str, frames: Union[None, str, Sequence[float]] = None,
                    out: Optional[str] = None, options: Optional[RenderOptions] = None, *,
                    resume: bool = False, progress: bool = True, quiet: bool = False,
                    reporter: Optional[Reporter] = None, core=None) -> SequenceResult:
    """Render ``frames`` of ``shot`` to ``out`` (a pattern, see
    :mod:`cmlt.shot.frames`).

    ``frames``: None (the stage's start frame), a ``--frames`` spec, or a
    list of time codes. Raises :class:`UsageError`, :class:`RenderError` or
    :class:`RenderCancelled`.
    """
    opts = options or RenderOptions()
    opts.check()
    stage, info, core = _open(shot, core)
    resolved, sources = resolve(stage, opts)
    st = core_settings(core, resolved, opts, sources)
    color_attrs, colorspace_name, display, view = color_setup(opts, stage)
    aovs = tuple(n for n in AOV_NAMES if n in opts.aovs)        # channel order, no duplicates
    check_aovs_for(aovs, resolved.integrator, getattr(resolved, "error_groups", 8))
    t_start = time.perf_counter()
    frame_list = _frame_list(frames, info)
    outputs = expand_outputs(out or default_output(shot), frame_list)
    if opts.camera:
        _check_camera(stage, opts.camera, shot)

    result = SequenceResult(frames=list(frame_list), sources=dict(sources),
                            settings=_settings_record(resolved, opts, colorspace_name,
                                                      display, view, aovs))
    todo = []
    for f, path in zip(frame_list, outputs):
        if resume and os.path.isfile(path):
            result.skipped.append(path)
        else:
            todo.append((f, path))
    # the frame before each frame (temporal carry-over): the previous one in the
    # list, or for the list's first frame one step back
    step = (frame_list[1] - frame_list[0]) if len(frame_list) > 1 else 1.0
    predecessor = {f: (frame_list[i - 1] if i > 0 else f - step) for i, f in enumerate(frame_list)}
    from ..metrics.flicker import FrameDifferenceFlicker
    flick = FrameDifferenceFlicker()        # frame-to-frame flicker (DESIGN.md §4)

    rep = reporter or Reporter(show_progress=progress, quiet=quiet)
    job = ShotJob(shot=shot, stage=stage, info=info, opts=opts, core=core, st=st,
                  resolved=resolved, sources=sources, color_attrs=color_attrs, display=display,
                  view=view, aovs=aovs, settings_record=result.settings, reporter=rep,
                  result=result)
    job.make_temporal = lambda w, h: _temporal_driver(job, w, h)
    stage_warnings = [w for w in info.warnings
                      if not (opts.camera and w == info.settings_camera_warning)]  # moot
    cold = _cold_resume_warning(resolved, opts, todo, predecessor, outputs, frame_list, resume)
    if cold:
        stage_warnings.append(cold)
    last_rendered = None
    with rep:
        rep.warnings(stage_warnings)
        result.warnings.extend(stage_warnings)
        if result.skipped:
            rep.info(f"resume: {len(result.skipped)} frame(s) already rendered, "
                     f"{len(todo)} to go")
        rep.start_sequence(len(todo))
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
            except KeyboardInterrupt:
                rep.abort_frame()
                raise RenderCancelled(frame, result.written, len(todo) - k) from None
        result.elapsed_s = time.perf_counter() - t_start
        rep.end_sequence(result)
    return result
