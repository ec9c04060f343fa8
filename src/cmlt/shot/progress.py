"""What the user sees while a sequence renders.

:class:`Reporter` draws two rich progress bars on stderr — the sequence
(frames) and the current frame (core progress units, rays/s, ETA) — and
prints one line per finished frame above them. Without a terminal (CI, logs)
the bars are off and only the per-frame lines are printed. ``quiet`` keeps
warnings only. Loader warnings are printed once per distinct text, however
many frames repeat them.

The core's progress callback runs on a render thread; it only stores numbers
(:meth:`Reporter.frame_progress`), and rich redraws from its own thread.
"""
from __future__ import annotations

import sys
import time
from typing import Iterable, Optional, Set

__all__ = ["Reporter", "format_rate"]


def format_rate(rays_per_s: Optional[float]) -> str:
    if rays_per_s is None or rays_per_s <= 0:
        return "- rays/s"
    for scale, unit in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if rays_per_s >= scale:
            return f"{rays_per_s / scale:.2f} {unit}rays/s"
    return f"{rays_per_s:.0f} rays/s"


class Reporter:
    def __init__(self, *, show_progress: bool = True, quiet: bool = False, console=None):
        from rich.console import Console

        self.console = console or Console(stderr=True, highlight=False)
        self.quiet = quiet
        self.show_progress = show_progress and not quiet and self.console.is_terminal
        self._seen_warnings: Set[str] = set()
        self._progress = None
        self._seq_task = None
        self._frame_task = None
        self._frame_t0 = 0.0
        self._rays_per_unit: Optional[float] = None   # from the previous frame

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

    def warn(self, text: str) -> None:
        self.console.print(f"cmlt: warning: {text}", markup=False, highlight=False,
                           style="yellow", soft_wrap=True)

    def warnings(self, texts: Iterable[str]) -> int:
        """Print warnings not printed before; returns how many were new."""
        new = 0
        for t in texts:
            if t not in self._seen_warnings:
                self._seen_warnings.add(t)
                self.warn(t)
                new += 1
        return new

    # -- bars ------------------------------------------------------------
    def start_sequence(self, total: int, skipped: int = 0) -> None:
        if self._progress is not None:
            self._seq_task = self._progress.add_task("sequence", total=total, rate="")

    def start_frame(self, frame: float) -> None:
        self._frame_t0 = time.perf_counter()
        if self._progress is not None:
            if self._frame_task is not None:
                self._progress.remove_task(self._frame_task)
            self._frame_task = self._progress.add_task(f"frame {frame:g}", total=None, rate="")

    def frame_progress(self, done: float, total: float) -> None:
        """Called from the render thread: store numbers only."""
        if self._progress is None or self._frame_task is None:
            return
        rate = ""
        elapsed = time.perf_counter() - self._frame_t0
        if self._rays_per_unit and elapsed > 0 and done > 0:
            rate = "~" + format_rate(self._rays_per_unit * done / elapsed)
        self._progress.update(self._frame_task, completed=done, total=total, rate=rate)

    def end_frame(self, frame: float, path: str, stats: dict, units_total: Optional[float]) -> None:
        rays = stats.get("rays")
        if rays and units_total:
            self._rays_per_unit = float(rays) / float(units_total)
        if self._progress is not None:
            if self._frame_task is not None:
                self._progress.remove_task(self._frame_task)
                self._frame_task = None
            if self._seq_task is not None:
                self._progress.update(self._seq_task, advance=1,
                                      rate=format_rate(stats.get("rays_per_s")))
        t = stats.get("time_s")
        t_text = f"{float(t):.2f} s" if t is not None else "-"
        self.info(f"frame {frame:g}: {t_text}, {format_rate(stats.get('rays_per_s'))} -> {path}")

    def abort_frame(self) -> None:
        if self._progress is not None and self._frame_task is not None:
            self._progress.remove_task(self._frame_task)
            self._frame_task = None
