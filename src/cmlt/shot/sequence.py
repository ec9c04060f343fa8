"""The frame loop: open the stage once, then per frame load -> bridge ->
render -> write EXR + sidecar.

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
import threading
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import __version__
from ..color import ColorError
from ..io.exr import COMPRESSIONS, write_exr
from ..io.sidecar import write_sidecar
from .bridge import BridgeError, SceneBridge
from .errors import RenderCancelled, RenderError, UsageError
from .frames import default_frames, expand_outputs, parse_frames
from .progress import Reporter

__all__ = ["RenderOptions", "SequenceResult", "render_sequence", "default_output"]

def default_output(shot: str) -> str:
    """``renders/<shot stem>.####.exr`` relative to the working directory."""
    stem = os.path.splitext(os.path.basename(shot))[0] or "shot"
    return os.path.join("renders", f"{stem}.####.exr")


@dataclass
class RenderOptions:
    """What the command line asked for. ``None`` means "flag not given": the
    stage's ``CmltRenderSettingsAPI`` value applies, else the default
    (:mod:`cmlt.settings`; precedence flag > stage > default)."""

    spp: Optional[int] = None
    integrator: Optional[str] = None
    seed: Optional[int] = None
    max_depth: Optional[int] = None
    resolution: Optional[Tuple[int, int]] = None  # (w, h)
    camera: Optional[str] = None                  # prim path
    threads: int = 0                              # 0 = all cores; machine, not shot
    half: bool = False
    compression: str = "zip"
    #: colour space the EXRs are written in (None = the rendering space,
    #: ACEScg, pixels unchanged); any name/alias/interop ID of the config
    output_colorspace: Optional[str] = None
    #: OpenColorIO config (None: $OCIO, the stage's, else the built-in one)
    ocio_config: Optional[str] = None

    def check(self) -> None:
        """Flag-level checks that need neither the stage nor the core."""
        if self.spp is not None and int(self.spp) < 1:
            raise UsageError(f"--spp {self.spp}: must be at least 1")
        if self.max_depth is not None and int(self.max_depth) < 1:
            raise UsageError(f"--max-depth {self.max_depth}: must be at least 1")
        if int(self.threads) < 0:
            raise UsageError(f"--threads {self.threads}: must be 0 (all cores) or more")
        if self.seed is not None and int(self.seed) < 0:
            raise UsageError(f"--seed {self.seed}: must be 0 or more")
        if self.resolution is not None:
            w, h = self.resolution
            if int(w) < 1 or int(h) < 1:
                raise UsageError(f"--res {w}x{h}: width and height must be at least 1")
        if self.compression not in COMPRESSIONS:
            raise UsageError(f"--compression {self.compression!r}: choose one of "
                             f"{', '.join(COMPRESSIONS)}")

    def overrides(self) -> dict:
        """Flag values by setting name, for :func:`cmlt.settings.resolve_settings`."""
        return {"integrator": self.integrator, "spp": self.spp, "seed": self.seed,
                "max_depth": self.max_depth, "resolution": self.resolution,
                "camera": self.camera}


@dataclass
class SequenceResult:
    frames: List[float] = field(default_factory=list)     # all requested frames
    written: List[str] = field(default_factory=list)      # image paths written now
    skipped: List[str] = field(default_factory=list)      # existing, skipped by resume
    stats: Dict[float, dict] = field(default_factory=dict)
    warnings: List[str] = field(default_factory=list)     # distinct, in order of appearance
    settings: Dict[str, object] = field(default_factory=dict)   # resolved, by name
    sources: Dict[str, str] = field(default_factory=dict)       # where each came from


def _resolve(stage, opts: RenderOptions):
    """Settings in force (flag > stage > default) and their sources. A bad
    flag value is a UsageError, a bad stage value a RenderError."""
    from ..settings import SettingsError, resolve_settings

    try:
        return resolve_settings(stage, cli_overrides=opts.overrides())
    except SettingsError as exc:
        msg = str(exc)
        if msg.startswith("flag "):
            raise UsageError(msg[len("flag "):]) from None
        raise RenderError(msg) from None


def _core_settings(core, resolved, opts: RenderOptions, sources: Dict[str, str]):
    """core.RenderSettings from the resolved settings: every field the core
    knows is set (the MLT fields reach the core as soon as it has them)."""
    st = core.RenderSettings()
    values = dict(resolved.as_dict())
    values["threads"] = int(opts.threads)
    for name, value in values.items():
        if name in ("resolution", "camera") or not hasattr(st, name):
            continue
        try:
            setattr(st, name, value)
        except (core.SettingsError, ValueError, TypeError) as exc:
            raise UsageError(f"{_where(name, value, sources)}: {exc}") from None
    return st


_FLAGS = {"integrator": "--integrator", "spp": "--spp", "max_depth": "--max-depth",
          "seed": "--seed", "threads": "--threads", "width": "--res", "height": "--res"}


def _where(name: str, value, sources: Dict[str, str]) -> str:
    """``--spp 0`` for a flag, ``/Render/Settings: cmlt:spp = 0`` for the stage."""
    src = sources.get(name, "default")
    shown = repr(value) if isinstance(value, str) else str(value)
    if src.startswith("stage:"):
        from ..settings import FIELDS
        attr = next((f.attr for f in FIELDS if f.name == name), name)
        return f"{src[len('stage:'):].split(' ')[0]}: {attr} = {shown}"
    return f"{_FLAGS.get(name, '--' + name.replace('_', '-'))} {shown}"


def _settings_message(msg: str, resolved, sources: Dict[str, str]):
    """Name the flag or stage attribute in a core SettingsError
    (``RenderSettings.<field>: ...``); returns (message, is_usage_error)."""
    for name in _FLAGS:
        prefix = f"RenderSettings.{name}:"
        if msg.startswith(prefix):
            key = "resolution" if name in ("width", "height") else name
            value = getattr(resolved, key, None)
            if key == "resolution" and value is not None:
                value = f"{value[0]}x{value[1]}"
            usage = not sources.get(key, "").startswith("stage:")
            return f"{_where(key, value, sources)}: {msg[len(prefix):].strip()}", usage
    return msg, True


def _color_setup(opts: RenderOptions, stage):
    """Install ``--ocio-config`` and check ``--output-colorspace`` before any
    frame renders; returns (EXR header attributes, resolved colour space)."""
    from ..color import ColorError, get_config, header_attributes, load_config, set_config

    # One config for the whole shot, installed before any frame is loaded (the
    # reader converts authored colours to ACEScg with it): --ocio-config, else
    # $OCIO, else the stage's colorConfiguration, else the built-in config.
    try:
        cfg = load_config(opts.ocio_config, stage=stage)
    except ColorError as exc:
        if opts.ocio_config:
            raise UsageError(f"--ocio-config {opts.ocio_config}: {exc}") from None
        raise RenderError(str(exc)) from None
    current = get_config()
    if (current.location, current.source) != (cfg.location, cfg.source):
        set_config(cfg)         # keep the current one (and its processor cache) if the same
    try:
        attrs = header_attributes(opts.output_colorspace)
        name = get_config().output_colorspace_name(opts.output_colorspace)
    except ColorError as exc:
        raise UsageError(f"--output-colorspace {opts.output_colorspace!r}: {exc}") from None
    return attrs, name


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


def _to_output(image, output_colorspace):
    if output_colorspace is None:
        return image
    from ..color import from_rendering_space
    return from_rendering_space(np.array(image, dtype=np.float32, copy=True), output_colorspace)


def _render_interruptible(core, scene, st, reporter: Reporter):
    """Run core.render on a worker thread so that Ctrl-C reaches the main
    thread promptly; the progress callback then asks the core to stop.
    Returns (result, interrupted, units_total)."""
    cancel = threading.Event()
    box: dict = {}
    last_total = [None]

    def progress(done, total):
        last_total[0] = total
        reporter.frame_progress(done, total)
        return not cancel.is_set()

    finished = threading.Event()

    def work():
        try:
            box["result"] = core.render(scene, st, progress=progress)
        except BaseException as exc:          # re-raised on the main thread
            box["error"] = exc
        finally:
            finished.set()

    worker = threading.Thread(target=work, name="cmlt-render", daemon=True)
    worker.start()
    interrupted = False
    # Wait on an Event, not Thread.join: an interrupted join can leave the
    # thread looking finished while it still runs.
    while not finished.is_set():
        try:
            finished.wait(0.05)
        except KeyboardInterrupt:
            if interrupted:
                reporter.warn("still cancelling; waiting for the render threads to stop")
            interrupted = True
            cancel.set()
    if "error" in box:
        raise box["error"]
    return box["result"], interrupted, last_total[0]


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
    if not os.path.exists(shot):
        raise UsageError(f"{shot}: no such file")
    if os.path.isdir(shot):
        raise UsageError(f"{shot}: is a directory, not a USD file")
    from ..usd import UsdLoadError, load_frame, open_stage, stage_info
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
    resolved, sources = _resolve(stage, opts)
    st = _core_settings(core, resolved, opts, sources)
    color_attrs, colorspace_name = _color_setup(opts, stage)
    settings_record = dict(resolved.as_dict(), threads=int(opts.threads), half=bool(opts.half),
                           compression=opts.compression, output_colorspace=colorspace_name)

    if frames is None:
        frame_list = default_frames(info.start)
    elif isinstance(frames, str):
        frame_list = parse_frames(frames, info.start, info.end, info.has_authored_time_range)
    else:
        frame_list = [float(f) for f in frames]
    outputs = expand_outputs(out or default_output(shot), frame_list)
    if opts.camera:
        _check_camera(stage, opts.camera, shot)

    result = SequenceResult(frames=list(frame_list), settings=settings_record,
                            sources=dict(sources))
    todo = []
    for f, path in zip(frame_list, outputs):
        if resume and os.path.isfile(path):
            result.skipped.append(path)
        else:
            todo.append((f, path))

    rep = reporter or Reporter(show_progress=progress, quiet=quiet)
    bridge = SceneBridge(core)
    shot_abs = os.path.abspath(shot)
    with rep:
        rep.warnings(info.warnings)
        result.warnings.extend(info.warnings)
        if result.skipped:
            rep.info(f"resume: {len(result.skipped)} frame(s) already rendered, "
                     f"{len(todo)} to go")
        rep.start_sequence(len(todo))
        for k, (frame, path) in enumerate(todo):
            try:
                rep.start_frame(frame)
                t0 = time.perf_counter()
                try:
                    fs = load_frame(stage, frame, camera=opts.camera, resolution=opts.resolution)
                except (UsdLoadError, ColorError) as exc:
                    raise RenderError(f"{shot}: frame {frame:g}: {exc}"
                                      if isinstance(exc, ColorError) else str(exc)) from None
                for w in fs.warnings:
                    if w not in result.warnings:
                        result.warnings.append(w)
                rep.warnings(fs.warnings)
                width, height = opts.resolution or fs.resolution
                st.width, st.height = int(width), int(height)
                try:
                    scene = bridge.update(fs)
                except (core.SceneError, BridgeError) as exc:
                    raise RenderError(f"{shot}: frame {frame:g}: {exc}") from None
                try:
                    r, interrupted, units = _render_interruptible(core, scene, st, rep)
                except core.SettingsError as exc:
                    msg, usage = _settings_message(str(exc), resolved, sources)
                    raise (UsageError if usage else RenderError)(msg) from None
                except core.SceneError as exc:
                    raise RenderError(f"{shot}: frame {frame:g}: {exc}") from None
                if interrupted or r.cancelled:
                    raise KeyboardInterrupt
                stats = dict(r.stats)
                stats["wall_time_s"] = time.perf_counter() - t0
                image = np.asarray(r.image)
                if not np.isfinite(image).all():
                    raise RenderError(f"{shot}: frame {frame:g}: the core returned "
                                      f"{int((~np.isfinite(image)).sum())} non-finite pixel values")
                record = {
                    "image": os.path.basename(path), "shot": shot_abs, "frame": frame,
                    "time_code": float(fs.time),
                    "camera": fs.camera.name if fs.camera is not None else None,
                    "resolution": [int(width), int(height)],
                    "settings": settings_record, "settings_sources": dict(sources),
                    "stats": stats,
                    "scene_update": bridge.last_update.as_dict(),
                    "warnings": list(fs.warnings), "cmlt_version": __version__,
                }
                metadata = {
                    "frame": float(frame), "timeCode": float(fs.time), "shot": shot_abs,
                    "camera": record["camera"] or "", "integrator": resolved.integrator,
                    "spp": int(resolved.spp), "maxDepth": int(resolved.max_depth),
                    "seed": int(resolved.seed),
                    "renderTime": float(stats.get("time_s", stats["wall_time_s"])),
                    "samples": int(stats.get("samples", 0)), "version": __version__,
                }
                try:
                    write_sidecar(path, record)
                    write_exr(path, _to_output(image, opts.output_colorspace), half=opts.half,
                              compression=opts.compression, colorspace=None,
                              metadata=metadata, attributes=color_attrs)
                except OSError as exc:
                    where = f" ({exc.filename})" if exc.filename and exc.filename != path else ""
                    raise RenderError(f"{path}: cannot write: {exc.strerror or exc}{where}") \
                        from None
                result.written.append(path)
                result.stats[frame] = stats
                rep.end_frame(frame, path, stats, units)
            except KeyboardInterrupt:
                rep.abort_frame()
                raise RenderCancelled(frame, result.written, len(todo) - k) from None
    return result
