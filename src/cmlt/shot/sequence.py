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

import math
import os
import threading
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import __version__
from ..color import ColorError
from ..io.exr import AOV_CHANNELS, COMPRESSIONS, check_crop, write_exr
from ..io.preview import write_preview
from ..io.sidecar import write_sidecar
from .bridge import BridgeError, SceneBridge
from .errors import RenderCancelled, RenderError, UsageError
from .frames import default_frames, expand_outputs, parse_frames
from .progress import Reporter

__all__ = ["RenderOptions", "SequenceResult", "render_sequence", "default_output",
           "preview_path", "AOV_NAMES", "PREVIEW_FORMATS"]

#: ``--aov`` names, in channel order
AOV_NAMES = tuple(AOV_CHANNELS)
#: ``--preview-format`` choices
PREVIEW_FORMATS = ("png", "jpg")


def preview_path(image_path: str, fmt: str = "png") -> str:
    """The preview beside an image: ``shot.0001.exr`` -> ``shot.0001.png``."""
    return os.path.splitext(image_path)[0] + "." + fmt

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
    #: seconds per frame (the frame runs this long; with spp also given, whichever
    #: comes first); None = the stage's cmlt:timeBudget, else 0 (off)
    time_budget: Optional[float] = None
    integrator: Optional[str] = None
    seed: Optional[int] = None
    max_depth: Optional[int] = None
    #: Metropolis (pssmlt) settings; None = the stage's value, else the default
    sigma: Optional[float] = None
    large_step_probability: Optional[float] = None
    chains: Optional[int] = None
    bootstrap_samples: Optional[int] = None
    #: coherent MLT (cmlt) settings; None = the stage's value, else the default
    tries: Optional[int] = None
    inner_length: Optional[int] = None
    inner: Optional[str] = None
    #: Metropolis importance and the fixed passes (pssmlt, cmlt)
    importance: Optional[str] = None
    direct_fraction: Optional[float] = None
    pilot_spp: Optional[int] = None
    #: cmlt: trace a bundle's rays as Embree packets (machine, not shot: the
    #: image is bit-identical either way)
    packets: bool = True
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
    #: extra EXR channels: any of AOV_NAMES (albedo, normal, depth, variance)
    aovs: Tuple[str, ...] = ()
    #: camera rays per pixel of the AOV pass (albedo, normal, depth)
    aov_samples: int = 4
    #: data window (x0, y0, x1, y1), half-open, inside the full frame
    crop: Optional[Tuple[int, int, int, int]] = None
    #: write a display-referred preview beside each EXR (png or jpg)
    preview: bool = False
    preview_format: str = "png"
    #: OCIO display / view of previews (None: sRGB display, its default view)
    display: Optional[str] = None
    view: Optional[str] = None
    #: temporal (DESIGN.md §4; None = the stage's cmlt:temporal:* value, else the
    #: default): start each frame's chains from the previous frame's, smooth b,
    #: fold the frame number into the seed (for comparison)
    carry_states: Optional[bool] = None
    smooth_normalization: Optional[bool] = None
    seed_per_frame: Optional[bool] = None
    #: write DIR/state.####.bin per frame and continue from the previous frame's
    state_dir: Optional[str] = None
    #: a bad state file: warn and start fresh instead of failing
    fresh_start_on_bad_state: bool = False

    def check(self) -> None:
        """Flag-level checks that need neither the stage nor the core."""
        if self.spp is not None and int(self.spp) < 1:
            raise UsageError(f"--spp {self.spp}: must be at least 1")
        if self.time_budget is not None and not (float(self.time_budget) >= 0.0
                                                 and math.isfinite(float(self.time_budget))):
            raise UsageError(f"--time {self.time_budget}: must be 0 (off) or more seconds")
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
        for name in self.aovs:
            if name not in AOV_NAMES:
                raise UsageError(f"--aov {name!r}: unknown AOV; choose from "
                                 f"{', '.join(AOV_NAMES)}")
        if int(self.aov_samples) < 1:
            raise UsageError(f"--aov-samples {self.aov_samples}: must be at least 1")
        if self.preview_format not in PREVIEW_FORMATS:
            raise UsageError(f"--preview-format {self.preview_format!r}: choose one of "
                             f"{', '.join(PREVIEW_FORMATS)}")
        if self.crop is not None:
            c = tuple(self.crop)
            if len(c) != 4 or c[0] < 0 or c[1] < 0 or c[2] <= c[0] or c[3] <= c[1]:
                raise UsageError(f"--crop {','.join(str(v) for v in c)}: expected x0,y0,x1,y1 "
                                 "with 0 <= x0 < x1 and 0 <= y0 < y1 (x1, y1 exclusive)")

    def overrides(self) -> dict:
        """Flag values by setting name, for :func:`cmlt.settings.resolve_settings`."""
        return {"integrator": self.integrator, "spp": self.spp, "seed": self.seed,
                "time_budget": self.time_budget, "importance": self.importance,
                "direct_fraction": self.direct_fraction, "pilot_spp": self.pilot_spp,
                "max_depth": self.max_depth, "resolution": self.resolution,
                "camera": self.camera, "sigma": self.sigma,
                "large_step_probability": self.large_step_probability,
                "chains": self.chains, "bootstrap_samples": self.bootstrap_samples,
                "tries": self.tries, "inner_length": self.inner_length, "inner": self.inner,
                "carry_states": self.carry_states,
                "smooth_normalization": self.smooth_normalization,
                "seed_per_frame": self.seed_per_frame}


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


#: the sample budget of a frame rendered to a time budget (a cap it never reaches)
TIME_BUDGET_SPP_CAP = 1 << 24


def _core_settings(core, resolved, opts: RenderOptions, sources: Dict[str, str]):
    """core.RenderSettings from the resolved settings: every field the core
    knows is set (the MLT fields reach the core as soon as it has them)."""
    st = core.RenderSettings()
    values = dict(resolved.as_dict())
    # A time budget replaces the sample budget unless spp was given with the same or a
    # higher precedence (both flags, or both in the stage): then whichever comes first.
    def rank(name: str) -> int:
        src = str(sources.get(name, "default"))
        return 2 if src.startswith("flag") else (1 if src.startswith("stage") else 0)

    if float(values.get("time_budget", 0.0) or 0.0) > 0.0 and rank("spp") < rank("time_budget"):
        values["spp"] = TIME_BUDGET_SPP_CAP
    values["threads"] = int(opts.threads)
    values["packets"] = bool(opts.packets)
    for name, value in values.items():
        if name in ("resolution", "camera") or not hasattr(st, name):
            continue
        try:
            setattr(st, name, value)
        except (core.SettingsError, ValueError, TypeError) as exc:
            raise UsageError(f"{_where(name, value, sources)}: {exc}") from None
    return st


_FLAGS = {"integrator": "--integrator", "spp": "--spp", "max_depth": "--max-depth",
          "seed": "--seed", "threads": "--threads", "width": "--res", "height": "--res",
          "sigma": "--sigma", "large_step_probability": "--large-step-probability",
          "chains": "--chains", "bootstrap_samples": "--bootstrap-samples",
          "tries": "--tries", "inner_length": "--inner-length", "inner": "--inner",
          "time_budget": "--time", "importance": "--importance", "direct_fraction": "--direct-fraction",
          "pilot_spp": "--pilot-spp"}


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
    display = view = None
    if opts.preview:
        try:
            display, view = get_config().check_display_view(opts.display, opts.view)
        except ColorError as exc:
            flag = (f"--display {opts.display!r}" if str(exc).startswith("unknown display")
                    else f"--view {opts.view!r}")
            raise UsageError(f"{flag}: {exc}") from None
    return attrs, name, display, view


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


def _aov_images(core, scene, st, r, aovs, opts: RenderOptions,
                stats: dict) -> Dict[str, np.ndarray]:
    """The requested AOVs of one frame, by name (see cmlt.io.exr.AOV_CHANNELS).

    albedo, normal, depth come from the core's integrator-independent AOV
    pass (``core.render_aovs``; first hits of ``aov_samples`` camera rays per
    pixel, the beauty's jitter); albedo is a colour and is written in the
    output colour space like the beauty. variance is the render's per-pixel
    variance of the mean, in the rendering space (ACEScg) whatever
    ``--output-colorspace`` says.
    """
    out: Dict[str, np.ndarray] = {}
    if any(a in aovs for a in ("albedo", "normal", "depth")):
        t = time.perf_counter()
        a = core.render_aovs(scene, st, samples=int(opts.aov_samples))
        stats["aov_time_s"] = time.perf_counter() - t
        if "albedo" in aovs:
            out["albedo"] = _to_output(np.asarray(a["albedo"]), opts.output_colorspace)
        if "normal" in aovs:
            out["normal"] = np.asarray(a["N"])
        if "depth" in aovs:
            out["depth"] = np.asarray(a["Z"])
    if "variance" in aovs:
        out["variance"] = np.asarray(r.variance)
    if "error" in aovs:                 # the per-pixel relMSE estimate (cmlt.accuracy.estimate)
        from ..accuracy.estimate import estimate_render
        out["error"] = estimate_render(r, stats, keep_pixels=True)[0].pixel.astype(np.float32)
    return {name: out[name] for name in aovs}


def _check_error_aov(aovs, integrator: str) -> None:
    from ..accuracy.estimate import VARIANCE_INTEGRATORS
    if "error" in aovs and integrator not in VARIANCE_INTEGRATORS:
        raise UsageError(f"--aov error: a per-pixel error estimate needs integrator "
                         f"{' or '.join(VARIANCE_INTEGRATORS)} (the {integrator} chains' samples "
                         "are correlated; their estimate needs chain groups from the core)")


#: RenderResult.stats keys (MLT integrators) -> cmlt:* header attribute names:
#: normalisation (b) estimates and mutation counts, written when present
_MLT_STATS = {
    "b": "b", "b_stderr": "bStderr", "b_bootstrap": "bBootstrap",
    "b_bootstrap_stderr": "bBootstrapStderr", "bootstrap_samples": "bootstrapSamples",
    "chains": "chains", "mutations": "mutations", "mutations_per_pixel": "mutationsPerPixel",
    "acceptance": "acceptance",
}


#: temporal normalisation record (TemporalDriver.finish) -> cmlt:* header attribute names
_TEMPORAL_RECORD = {
    "b_used": "bUsed", "b_boot": "bFresh", "b_ratio": "bRatio", "b_combined": "bCombined",
    "b_smoothed": "bSmoothed", "change_detected": "changeDetected",
}


def _header_metadata(frame, fs, shot_abs: str, camera, resolved, stats: dict,
                     temporal: Optional[dict] = None) -> Dict[str, object]:
    """``cmlt:*`` EXR header attributes of one frame (issue 6): frame, time code,
    shot, camera, integrator and its parameters, seed, samples / mutations,
    render time, b estimates (when the integrator reports them), version.

    ``temporal``: the frame's temporal record (:meth:`TemporalDriver.finish`).
    When it holds a normalisation (MLT integrators), ``cmlt:b`` is the b the
    image was normalised with (``b_used``: smoothed over frames unless
    ``--no-smoothing``; it scales the chains' part, the direct pass being plain
    Monte Carlo), the core's own estimate is ``cmlt:bCore``, and the
    record goes in as ``cmlt:bUsed``, ``bFresh``, ``bRatio``, ``bCombined``,
    ``bSmoothed``, ``changeDetected``; an estimate that does not exist for
    the frame (NaN, e.g. ``b_ratio`` without carried states) is left out.
    """
    params = {k: v for k, v in resolved.as_dict().items() if k not in ("camera", "resolution")}
    md: Dict[str, object] = {
        "frame": float(frame), "timeCode": float(fs.time), "shot": shot_abs,
        "camera": camera or "", "integrator": resolved.integrator,
        "integratorParameters": params,               # JSON text
        "spp": int(resolved.spp), "maxDepth": int(resolved.max_depth),
        "seed": int(resolved.seed),
        "renderTime": float(stats.get("time_s", stats.get("wall_time_s", 0.0))),
        "samples": int(stats.get("samples", 0)),
        "rays": int(stats.get("rays", 0)),
        "raysPerSecond": float(stats.get("rays_per_s", 0.0)),
        "version": __version__,
    }
    for key, name in _MLT_STATS.items():
        if key in stats and stats[key] is not None:
            md[name] = stats[key]
    from ..accuracy.estimate import estimate_metadata
    md.update(estimate_metadata(stats.get("error_estimate")))   # relMSEEstimate, ...
    rec = temporal or {}
    if rec.get("b_used") is not None and "b" in md:
        md["bCore"] = md["b"]                   # the core's b, before temporal smoothing
        for key, name in _TEMPORAL_RECORD.items():
            value = rec.get(key)
            if isinstance(value, bool):
                md[name] = int(value)
            elif value is not None and math.isfinite(float(value)):
                md[name] = float(value)
        if "bUsed" in md:
            md["b"] = md["bUsed"]               # the b the image was normalised with
    return md


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


def _temporal_driver(core, resolved, shot, width, height, opts: RenderOptions, rep, result):
    from ..temporal import TemporalDriver

    def warn(msg):
        rep.warnings([msg])
        if msg not in result.warnings:
            result.warnings.append(msg)

    return TemporalDriver(core, resolved, shot, width, height, state_dir=opts.state_dir,
                          fresh_start_on_bad_state=opts.fresh_start_on_bad_state, warn=warn)


def _load_previous_state(temporal, pred, frame, opts: RenderOptions, info, rep, result):
    """Read the state of frame ``pred`` for ``frame`` (``--state-dir``); a bad
    file is a RenderError (one line naming it) unless --fresh-start-on-bad-state."""
    from ..temporal import StateError
    from ..temporal.state import state_path

    if not opts.state_dir:
        return None
    try:
        note = temporal.load_previous(pred, frame)
    except StateError as exc:
        raise RenderError(f"{exc} (use --fresh-start-on-bad-state to start frame {frame:g} "
                          "fresh)") from None
    if note is None and (info.start is None or pred >= info.start) \
            and not os.path.exists(state_path(opts.state_dir, pred)):
        msg = (f"{state_path(opts.state_dir, pred)}: no state of frame {pred:g}; "
               f"frame {frame:g} starts fresh")
        rep.warnings([msg])
        if msg not in result.warnings:
            result.warnings.append(msg)
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
    color_attrs, colorspace_name, display, view = _color_setup(opts, stage)
    settings_record = dict(resolved.as_dict(), threads=int(opts.threads), half=bool(opts.half),
                           compression=opts.compression, output_colorspace=colorspace_name)
    aovs = tuple(n for n in AOV_NAMES if n in opts.aovs)        # channel order, no duplicates
    _check_error_aov(aovs, resolved.integrator)
    if aovs:
        settings_record.update(aovs=list(aovs), aov_samples=int(opts.aov_samples))
    if opts.crop is not None:
        settings_record["crop"] = [int(v) for v in opts.crop]
    if opts.preview:
        settings_record.update(preview=opts.preview_format, display=display, view=view)
    t_start = time.perf_counter()

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
    if opts.state_dir:
        settings_record["state_dir"] = os.path.abspath(opts.state_dir)
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
    temporal = None
    last_rendered = None
    from ..metrics.flicker import FrameDifferenceFlicker    # (cmlt.metrics imports cmlt.shot)
    flick = FrameDifferenceFlicker()        # frame-to-frame flicker (DESIGN.md §4)

    rep = reporter or Reporter(show_progress=progress, quiet=quiet)
    bridge = SceneBridge(core)
    shot_abs = os.path.abspath(shot)
    stage_warnings = [w for w in info.warnings
                      if not (opts.camera and w == info.settings_camera_warning)]  # moot
    cold = _cold_resume_warning(resolved, opts, todo, predecessor, outputs, frame_list, resume)
    if cold:
        stage_warnings.append(cold)
    with rep:
        rep.warnings(stage_warnings)
        result.warnings.extend(stage_warnings)
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
                crop = None
                if opts.crop is not None:
                    try:
                        crop = check_crop(opts.crop, int(width), int(height))
                    except ValueError as exc:
                        raise UsageError(str(exc)) from None
                try:
                    scene = bridge.update(fs)
                except (core.SceneError, BridgeError) as exc:
                    raise RenderError(f"{shot}: frame {frame:g}: {exc}") from None
                if temporal is None:
                    temporal = _temporal_driver(core, resolved, shot, int(width), int(height),
                                                opts, rep, result)
                pred = predecessor[frame]
                if last_rendered is None or last_rendered != pred:
                    # not continuing in memory: the state file of the frame before, if any
                    temporal.forget()
                    note = _load_previous_state(temporal, pred, frame, opts, info, rep, result)
                    if note:
                        rep.info(note)
                try:
                    trec = temporal.prepare(scene, st, frame)
                except core.SettingsError as exc:
                    msg, usage = _settings_message(str(exc), resolved, sources)
                    raise (UsageError if usage else RenderError)(msg) from None
                budget = getattr(rep, "frame_budget", None)
                if budget is not None:          # the live rate of the frame bar
                    timed = float(getattr(resolved, "time_budget", 0.0) or 0.0) > 0.0
                    budget(None if timed else float(width) * float(height) * float(resolved.spp))
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
                image = np.asarray(r.image)
                if not np.isfinite(image).all():
                    raise RenderError(f"{shot}: frame {frame:g}: the core returned "
                                      f"{int((~np.isfinite(image)).sum())} non-finite pixel values")
                from ..accuracy.estimate import estimate_record
                stats["error_estimate"] = estimate_record(r, stats)     # relMSE without a reference
                image, trec, state_bytes = temporal.finish(r, stats, image, frame, trec)
                aov_images = _aov_images(core, scene, st, r, aovs, opts, stats)
                stats["wall_time_s"] = time.perf_counter() - t0
                record = {
                    "image": os.path.basename(path), "shot": shot_abs, "frame": frame,
                    "time_code": float(fs.time),
                    "camera": fs.camera.name if fs.camera is not None else None,
                    "resolution": [int(width), int(height)],
                    "settings": settings_record, "settings_sources": dict(sources),
                    "stats": stats,
                    "scene_update": bridge.last_update.as_dict(),
                    "warnings": list(fs.warnings), "cmlt_version": __version__,
                    "temporal": trec,
                }
                metadata = _header_metadata(frame, fs, shot_abs, record["camera"], resolved, stats,
                                            temporal=trec)
                out_image = _to_output(image, opts.output_colorspace)
                # flicker of the full frames in the output colour space, as `cmlt flicker`
                # measures the EXRs (only consecutive frames of the list are paired)
                flick.add(out_image, follows=last_rendered is not None and last_rendered == pred)
                try:
                    if opts.preview:
                        # before the EXR: a finished image always has its preview
                        pv = preview_path(path, opts.preview_format)
                        shown = image if crop is None else image[crop[1]:crop[3], crop[0]:crop[2]]
                        write_preview(shown, pv, display, view)
                        record["preview"] = os.path.basename(pv)
                    state_file = None
                    if opts.state_dir:
                        # before the image: a finished frame always has its state
                        from ..temporal.state import state_path, write_state
                        state_file = write_state(state_path(opts.state_dir, frame), state_bytes)
                        trec["state_out"] = os.path.abspath(state_file)
                    write_sidecar(path, record)
                    write_exr(path, out_image, half=opts.half,
                              compression=opts.compression, colorspace=None,
                              metadata=metadata, attributes=color_attrs, aovs=aov_images,
                              crop=crop)
                    if opts.preview:
                        result.previews.append(pv)
                except OSError as exc:
                    where = f" ({exc.filename})" if exc.filename and exc.filename != path else ""
                    raise RenderError(f"{path}: cannot write: {exc.strerror or exc}{where}") \
                        from None
                temporal.advance(state_bytes, state_file or f"<state of frame {frame:g}>")
                last_rendered = frame
                result.written.append(path)
                result.stats[frame] = stats
                result.flicker = flick.as_dict()
                rep.end_frame(frame, path, stats, units)
            except KeyboardInterrupt:
                rep.abort_frame()
                raise RenderCancelled(frame, result.written, len(todo) - k) from None
        result.elapsed_s = time.perf_counter() - t_start
        rep.end_sequence(result)
    return result
