"""What the user sees while a sequence renders.

:class:`Reporter` draws two rich progress bars on stderr — the sequence
(frames) and the current frame (core progress units, a live rate, ETA) — and
prints one line per finished frame above them. Without a terminal (CI, logs)
the bars are off and only the per-frame lines are printed. ``quiet`` prints
nothing (errors are the caller's, on stderr). Loader warnings are printed
once per distinct text, however many frames repeat them.

The core's progress callback runs on a render thread; it only stores numbers
(:meth:`Reporter.frame_progress`), and rich redraws from its own thread.

:class:`JsonReporter` (``--log-json``) has the same interface and prints one
JSON object per line per event on stdout, nothing else: ``sequence_start``,
``frame_start``, ``frame_done`` (time, rays, rays/s, path, relMSE estimate), ``warning``,
``info``, ``frame_aborted``, ``sequence_done`` (frames, time, mean time per
frame, rays/s, flicker: see :func:`sequence_summary`). Every object has
``event`` and ``t`` (Unix time).

:func:`summary_table` is the table printed when a sequence completes.
"""
from __future__ import annotations

import json
import math
import sys
import time
from typing import Any, Dict, Iterable, Optional, Set

__all__ = ["Reporter", "JsonReporter", "format_rate", "format_flicker", "summary_table",
           "sequence_summary", "VERBOSITY", "frame_details"]

#: ``-v`` levels (husk style): what each adds on stderr (or as ``detail`` events
#: with ``--log-json``)
VERBOSITY = {0: "quiet: errors only", 1: "normal: warnings, a line per frame, the summary",
             2: "verbose: the render's set-up and a details line per frame (size, camera, "
                "samples, time per phase, what changed in the scene)",
             3: "debug: also the settings with their sources, each frame's scene update and "
                "effects, and a traceback on an internal error"}


def frame_details(frame: float, done: Dict[str, Any]):
    """``(level, text)`` lines describing a finished frame for ``-v`` 2 and 3
    (``done``: what :func:`cmlt.shot.frame_job.render_frame` returned)."""
    rec, st = done.get("record") or {}, done.get("stats") or {}
    w, h = rec.get("resolution") or (0, 0)
    settings = rec.get("settings") or {}
    spp = f"{st['mutations']} mutations" if st.get("mutations") else \
        f"{settings.get('spp', '?')} spp"
    phases = ", ".join(f"{k} {float(v):.3f} s" for k, v in (done.get("phases") or {}).items()
                       if v is not None)
    upd = rec.get("scene_update") or {}
    change = (f"rebuilt ({upd.get('reason')})" if upd.get("rebuilt") else
              f"{upd.get('transforms_updated', 0)} transform(s), "
              f"{upd.get('meshes_updated', 0)} mesh(es), "
              f"{upd.get('materials_updated', 0)} material(s) updated")
    yield 2, (f"frame {frame:g}: {w}x{h}, camera {rec.get('camera') or '(framing)'}, "
              f"{settings.get('integrator', '?')} {spp}, {st.get('rays', 0)} rays; {phases}; "
              f"scene {change}")
    yield 3, f"frame {frame:g}: scene update {json.dumps(_json_safe(upd), sort_keys=True)}"
    yield 3, (f"frame {frame:g}: effects "
              f"{json.dumps(_json_safe(rec.get('effects')), sort_keys=True, default=str)}")


def format_rate(rays_per_s: Optional[float]) -> str:
    if rays_per_s is None or rays_per_s <= 0:
        return "- rays/s"
    for scale, unit in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if rays_per_s >= scale:
            return f"{rays_per_s / scale:.2f} {unit}rays/s"
    return f"{rays_per_s:.0f} rays/s"


class _OnceWarnings:
    """Each distinct warning is shown once (``warn`` shows one)."""

    _seen_warnings: Set[str]

    def warnings(self, texts: Iterable[str]) -> int:
        """Show the warnings not shown before; returns how many were new."""
        new = 0
        for t in texts:
            if t not in self._seen_warnings:
                self._seen_warnings.add(t)
                self.warn(t)
                new += 1
        return new


class Reporter(_OnceWarnings):
    def __init__(self, *, show_progress: bool = True, quiet: bool = False, console=None,
                 verbosity: int = 1):
        from rich.console import Console

        self.console = console or Console(stderr=True, highlight=False)
        self.verbosity = 0 if quiet else int(verbosity)
        self.quiet = self.verbosity <= 0
        self.show_progress = show_progress and not quiet and self.console.is_terminal
        self._seen_warnings: Set[str] = set()
        self._progress = None
        self._seq_task = None
        self._frame_task = None
        self._frame_t0 = 0.0
        self._rays_per_sample: Optional[float] = None  # from the last finished frame
        self._frame_samples: Optional[float] = None   # samples of the frame in progress
        self._frame_estimate = ""                     # the live relMSE estimate's text

    # -- lifecycle -------------------------------------------------------
    def __enter__(self):
        if self.show_progress:
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TaskProgressColumn,
                                       TextColumn, TimeElapsedColumn, TimeRemainingColumn)
            self._progress = Progress(
                TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                MofNCompleteColumn(), TextColumn("{task.fields[rate]}"),
                TimeElapsedColumn(), TimeRemainingColumn(),
                console=self.console, transient=False, refresh_per_second=8)
            self._progress.__enter__()
        return self

    def __exit__(self, *exc):
        if self._progress is not None:
            self._progress.__exit__(*exc)
            self._progress = None
        return False

    # -- messages --------------------------------------------------------
    def info(self, text: str) -> None:
        if not self.quiet:
            self.console.print(text, markup=False, highlight=False, soft_wrap=True)

    def detail(self, text: str, level: int = 2) -> None:
        """A line shown from verbosity ``level`` on (``-v``)."""
        if self.verbosity >= level:
            self.console.print(f"cmlt: {text}", markup=False, highlight=False, style="dim",
                               soft_wrap=True)

    def warn(self, text: str) -> None:
        if self.quiet:                # --quiet: errors only
            return
        self.console.print(f"cmlt: warning: {text}", markup=False, highlight=False,
                           style="yellow", soft_wrap=True)

    # -- bars ------------------------------------------------------------
    def start_sequence(self, total: int, skipped: int = 0) -> None:
        if self._progress is not None:
            self._seq_task = self._progress.add_task("sequence", total=total, rate="")

    def start_frame(self, frame: float) -> None:
        self._frame_t0 = time.perf_counter()
        self._frame_samples = None
        self._frame_estimate = ""
        if self._progress is not None:
            if self._frame_task is not None:
                self._progress.remove_task(self._frame_task)
            self._frame_task = self._progress.add_task(f"frame {frame:g}", total=None, rate="")

    def frame_budget(self, samples: Optional[float]) -> None:
        """The frame about to render takes ``samples`` samples (pixels × spp,
        path evaluations for pssmlt/cmlt) spread evenly over the core's
        progress units; ``None`` when unknown (a time budget counts
        milliseconds). Called before the render starts."""
        self._frame_samples = float(samples) if samples else None

    def live_rate(self, done: float, total: float, elapsed: float) -> str:
        """The rate shown in the frame bar: ``~`` + rays/s, from the samples
        done so far (``done / total`` of the frame's samples) times the rays
        per sample of the last finished frame; before any frame has finished
        (frame 1) the core has not counted rays yet, so samples/s. '' when
        nothing is known yet."""
        if not (elapsed > 0 and done > 0 and total and self._frame_samples):
            return ""
        samples_per_s = self._frame_samples * float(done) / float(total) / elapsed
        if self._rays_per_sample:
            return "~" + format_rate(self._rays_per_sample * samples_per_s)
        return "~" + format_rate(samples_per_s).replace("rays/s", "samples/s")

    def frame_progress(self, done: float, total: float) -> None:
        """Called from the render thread: store numbers only."""
        if self._progress is None or self._frame_task is None:
            return
        rate = self.live_rate(done, total, time.perf_counter() - self._frame_t0)
        if self._frame_estimate:
            rate = f"{rate}  {self._frame_estimate}" if rate else self._frame_estimate
        self._progress.update(self._frame_task, completed=done, total=total, rate=rate)

    def frame_estimate(self, work: float, seconds: float, relmse: float) -> None:
        """Called from the render thread with each estimate of a frame rendering to a
        target error (the core's on_estimate): the frame bar shows the latest."""
        self._frame_estimate = f"relMSE ~{relmse:.2g}" if relmse == relmse else ""

    def end_frame(self, frame: float, path: str, stats: dict, units_total: Optional[float]) -> None:
        rays, samples = stats.get("rays"), stats.get("samples")
        if rays and samples:
            self._rays_per_sample = float(rays) / float(samples)
        if self._progress is not None:
            if self._frame_task is not None:
                self._progress.remove_task(self._frame_task)
                self._frame_task = None
            if self._seq_task is not None:
                self._progress.update(self._seq_task, advance=1,
                                      rate=format_rate(stats.get("rays_per_s")))
        t = stats.get("time_s")
        t_text = f"{float(t):.2f} s" if t is not None else "-"
        from ..metrics.error_estimate import estimate_text
        err = estimate_text(stats.get("error_estimate"))
        self.info(f"frame {frame:g}: {t_text}, {format_rate(stats.get('rays_per_s'))}"
                  f"{', ' + err if err else ''} -> {path}")

    def abort_frame(self) -> None:
        if self._progress is not None and self._frame_task is not None:
            self._progress.remove_task(self._frame_task)
            self._frame_task = None

    def end_sequence(self, result) -> None:
        """The sequence finished (not called when it was interrupted)."""


def sequence_summary(result) -> Dict[str, Any]:
    """Numbers of a finished sequence (a :class:`~cmlt.shot.SequenceResult`):
    frames written and skipped, total time, mean render time per frame,
    rays/s over the sequence, and the flicker measured while rendering:
    ``flicker`` is the no-reference frame-to-frame measure of DESIGN.md §4,
    ``mean_pairs mean_px |I_{f+1} − I_f| / mean_px I`` over consecutive
    frames rendered now (None with fewer than 2), ``global_flicker`` the
    std of the frames' brightness over its mean, ``flicker_pairs`` how many
    frame pairs were measured (see :class:`cmlt.metrics.FrameDifferenceFlicker`;
    on a moving shot it includes the motion: use ``cmlt flicker --reference``
    for flicker proper)."""
    stats = list(result.stats.values())
    times = [float(st.get("wall_time_s", st.get("time_s", 0.0))) for st in stats]
    render_s = sum(float(st.get("time_s", 0.0)) for st in stats)
    rays = sum(int(st.get("rays", 0)) for st in stats)
    flick = dict(getattr(result, "flicker", None) or {})
    return {
        "frames": len(result.written), "skipped": len(result.skipped),
        "total_time_s": float(getattr(result, "elapsed_s", 0.0) or sum(times)),
        "mean_frame_time_s": (sum(times) / len(times)) if times else 0.0,
        "rays": rays, "rays_per_s": (rays / render_s) if render_s > 0 else 0.0,
        "flicker": flick.get("flicker"),
        "global_flicker": flick.get("global_flicker"),
        "flicker_pairs": int(flick.get("flicker_pairs") or 0),
        "integrator_auto": (getattr(result, "settings", None) or {}).get("integrator_auto"),
    }


def format_flicker(value: Optional[float]) -> str:
    """``0.0123`` as ``1.23 %``; ``-`` when not measured (fewer than 2 frames)."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{100.0 * value:.3g} %"


def summary_table(result):
    """A rich Table: frames, total time, mean time per frame, rays/s, and
    the frame-to-frame flicker (``-`` with fewer than 2 consecutive frames)."""
    from rich.table import Table

    s = sequence_summary(result)
    table = Table(title="cmlt render summary", title_justify="left", show_header=True,
                  caption="flicker = mean |I(f+1) - I(f)| / mean I, consecutive frames"
                  if s["flicker"] is not None else None,
                  caption_justify="left")
    table.add_column("frames", justify="right")
    table.add_column("skipped", justify="right")
    table.add_column("total time", justify="right")
    table.add_column("mean / frame", justify="right")
    table.add_column("rays/s", justify="right")
    table.add_column("flicker", justify="right")
    table.add_row(str(s["frames"]), str(s["skipped"]), f"{s['total_time_s']:.2f} s",
                  f"{s['mean_frame_time_s']:.2f} s", format_rate(s["rays_per_s"]),
                  format_flicker(s["flicker"]))
    return table


def _json_safe(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item") and callable(value.item):        # numpy scalars
        return _json_safe(value.item())
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


class JsonReporter(_OnceWarnings):
    """``--log-json``: one JSON object per line per event on ``stream``
    (stdout), flushed at once so a farm's log collector sees it live."""

    def __init__(self, stream=None, verbosity: int = 1):
        self.stream = stream if stream is not None else sys.stdout
        self.verbosity = int(verbosity)
        self._seen_warnings: Set[str] = set()
        self._frame_t0 = 0.0
        self._index = 0
        self._total = 0

    def emit(self, event: str, **fields: Any) -> None:
        doc = {"event": event, "t": round(time.time(), 3)}
        doc.update(_json_safe(fields))
        self.stream.write(json.dumps(doc, allow_nan=False, sort_keys=False) + "\n")
        self.stream.flush()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def info(self, text: str) -> None:
        self.emit("info", message=text)

    def warn(self, text: str) -> None:
        self.emit("warning", message=text)

    def detail(self, text: str, level: int = 2) -> None:
        if self.verbosity >= level:
            self.emit("detail", level=int(level), message=text)

    def start_sequence(self, total: int, skipped: int = 0) -> None:
        self._total = int(total)
        self.emit("sequence_start", frames=int(total))

    def start_frame(self, frame: float) -> None:
        self._frame_t0 = time.perf_counter()
        self._index += 1
        self.emit("frame_start", frame=float(frame), index=self._index, total=self._total)

    def frame_budget(self, samples: Optional[float]) -> None:
        pass

    def frame_progress(self, done: float, total: float) -> None:
        pass                          # no per-chunk events: one line per frame event

    def frame_estimate(self, work: float, seconds: float, relmse: float) -> None:
        self.emit("frame_estimate", index=self._index, work=float(work),
                  elapsed_s=float(seconds), relmse=float(relmse))

    def end_frame(self, frame: float, path: str, stats: dict, units_total: Optional[float]) -> None:
        self.emit("frame_done", frame=float(frame), path=path,
                  time_s=stats.get("time_s"), wall_time_s=stats.get("wall_time_s"),
                  rays=stats.get("rays"), rays_per_s=stats.get("rays_per_s"),
                  samples=stats.get("samples"), nan_samples=stats.get("nan_samples", 0),
                  error_estimate=stats.get("error_estimate"))

    def abort_frame(self) -> None:
        self.emit("frame_aborted", index=self._index,
                  elapsed_s=time.perf_counter() - self._frame_t0)

    def end_sequence(self, result) -> None:
        self.emit("sequence_done", **sequence_summary(result),
                  written=list(result.written), previews=list(getattr(result, "previews", [])))
