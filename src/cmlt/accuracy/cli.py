"""``cmlt accuracy``: what accuracy costs in time on a shot (registered by :mod:`cmlt.cli`
with :func:`add_parser`; the parser sets ``handler`` to :func:`run`; ``python -m cmlt
accuracy`` is the same command).

::

    cmlt accuracy SHOT [--frames F] [--res WxH] [--integrators pt,bdpt,pssmlt,cmlt]
                       [--seconds 1,2,4,8] [--reference FILE.exr | --reference-spp N]
                       [--reference-integrator bdpt] [--seeds S] [--threads N]
                       [--out DIR] [--cache DIR] [--peers [mitsuba,luxcore:BIDIRCPU]]
                       [--quiet]

For each frame: a converged reference (``--reference-integrator`` at ``--reference-spp``
samples per pixel, cached in ``--cache`` keyed by shot, frame, resolution, integrator,
spp and a hash of the stage's files; or ``--reference FILE``, a pattern with #### for
several frames), then every integrator at every time budget (the core's own time
budget, as ``cmlt render --time``) with seeds 0..S-1, interleaved (seed, budget,
integrator) so that changes in the machine's load hit all integrators alike. Writes

* ``DIR/accuracy.csv``: one row per (renderer, integrator, budget): mean wall time,
  samples per pixel, relMSE, RMSE and mean brightness ratio over the renders (seeds x
  frames) with their standard errors (columns :data:`cmlt.accuracy.curves.CSV_COLUMNS`);
* ``DIR/runs.csv``: every render;
* ``DIR/accuracy.png``: relMSE against time, log-log, error bars, the 1/t slope;
* ``DIR/accuracy.json``: all of it plus the fits, the references and the command;

and prints the markdown tables (the rows; per integrator the fitted log-log slope and the
time to reach relMSE 0.01 and 0.001) on stdout. Progress bars on stderr.

``--peers``: Mitsuba 3 and/or LuxCore render the same frame (converted by
:mod:`cmlt.accuracy.peers`) at the same budgets in worker processes; their curves are
measured against the same reference. The peers' BSDFs are Lambertian, so with
``--peers`` cmlt's opaque materials are made exactly Lambertian too (ior 1), for cmlt's
renders and its reference alike. A peer that is not installed is reported and left out.

Exit codes: 0 done; 1 a render failed; 2 a bad flag, shot or reference.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from typing import List, Optional

__all__ = ["add_parser", "run"]

EXIT_OK, EXIT_RENDER, EXIT_USAGE = 0, 1, 2


def _resolution(text: str):
    parts = text.lower().split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        w, h = int(parts[0]), int(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT, e.g. 64x64") from None
    if not (1 <= w <= 65536 and 1 <= h <= 65536):
        raise argparse.ArgumentTypeError(f"{text!r}: width and height must be 1..65536")
    return (w, h)


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: must be at least 1")
    return v


def _seconds_list(text: str) -> List[float]:
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of "
                                         "seconds, e.g. 1,2,4,8") from None
    if not vals or any(not (v > 0 and math.isfinite(v)) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: give one or more positive budgets in "
                                         "seconds, e.g. 1,2,4,8")
    return list(dict.fromkeys(vals))


def add_parser(sub) -> argparse.ArgumentParser:
    """Add the ``accuracy`` subcommand to cmlt's subparsers."""
    a = sub.add_parser(
        "accuracy", help="error against time: relMSE of each integrator at time budgets, "
        "against a converged reference (CSV, plot, markdown)",
        description="What accuracy costs in time: render a converged reference of a "
        "shot's frame, then each integrator at each time budget and seed, and write "
        "DIR/accuracy.csv, DIR/accuracy.png (log-log relMSE against time) and the "
        "markdown tables on stdout, with the time each integrator needs for relMSE 0.01 "
        "and 0.001 (along the fitted slope).")
    a.add_argument("shot", metavar="SHOT", help="USD stage")
    a.add_argument("--frames", metavar="SPEC",
                   help="time codes as for `cmlt render` (7, 1:24x6, 1,12); default: the "
                   "stage's start; errors are averaged over frames and seeds")
    a.add_argument("--res", type=_resolution, metavar="WxH",
                   help="resolution (default: the stage's render settings)")
    a.add_argument("--integrators", default="pt,bdpt,pssmlt,cmlt", metavar="LIST",
                   help="comma-separated, each name[:setting=value...], e.g. "
                   "cmlt:tries=4:inner_length=2 (default pt,bdpt,pssmlt,cmlt)")
    a.add_argument("--seconds", type=_seconds_list, default=[1.0, 2.0, 4.0, 8.0],
                   metavar="LIST", help="time budgets per render (default 1,2,4,8)")
    ref = a.add_mutually_exclusive_group()
    ref.add_argument("--reference", metavar="FILE",
                     help="reference image (EXR, ACEScg, the renders' resolution); a pattern "
                     "with #### for several frames")
    ref.add_argument("--reference-spp", type=_positive_int, default=4096, metavar="N",
                     dest="reference_spp",
                     help="samples per pixel of the rendered reference (default 4096)")
    a.add_argument("--reference-integrator", default="bdpt", metavar="NAME",
                   dest="reference_integrator",
                   help="integrator of the rendered reference (default bdpt)")
    a.add_argument("--seeds", type=_positive_int, default=3, metavar="S",
                   help="renders per integrator and budget, seeds 0..S-1 (default 3)")
    a.add_argument("--threads", type=int, default=0, metavar="N",
                   help="worker threads, 0 = all cores (default 0)")
    a.add_argument("--out", metavar="DIR",
                   help="output directory (default renders/accuracy/<shot>)")
    a.add_argument("--cache", metavar="DIR", default=os.path.join("renders", "cache", "accuracy"),
                   help="where rendered references are kept (default renders/cache/accuracy)")
    a.add_argument("--peers", nargs="?", const="mitsuba,luxcore", metavar="LIST",
                   help="also render with peer renderers where installed: mitsuba, luxcore, "
                   "each [:integrator] (default mitsuba:path, luxcore:PATHCPU)")
    a.add_argument("--mitsuba-variant", default="auto", dest="mitsuba_variant",
                   help="Mitsuba variant (auto: llvm_ad_rgb, else scalar_rgb)")
    a.add_argument("--quiet", "-q", action="store_true",
                   help="no progress on stderr (the tables still go to stdout)")
    a.set_defaults(handler=run)
    return a


def _error(message: str, code: int) -> int:
    sys.stderr.write(f"cmlt: error: {message}\n")
    return code


class _Progress:
    """Two rich bars on stderr (all renders; the current one), or one line per render
    when stderr is not a terminal; nothing with ``quiet``."""

    def __init__(self, total: int, quiet: bool):
        from rich.console import Console

        self.console = Console(stderr=True, highlight=False)
        self.quiet = quiet
        self.bars = None
        if not quiet and self.console.is_terminal:
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                       TimeElapsedColumn, TimeRemainingColumn)
            self.bars = Progress(TextColumn("{task.description}"), BarColumn(),
                                 MofNCompleteColumn(), TimeElapsedColumn(),
                                 TimeRemainingColumn(), console=self.console,
                                 refresh_per_second=8)
            self.bars.__enter__()
            self.all = self.bars.add_task("renders", total=total)
            self.cur = self.bars.add_task("", total=1000)

    def start(self, what: str) -> None:
        if self.bars is not None:
            self.bars.update(self.cur, description=what, completed=0)

    def fraction(self, f: float) -> None:
        if self.bars is not None:
            self.bars.update(self.cur, completed=int(1000 * min(max(f, 0.0), 1.0)))

    def done(self, line: str, count: bool = True) -> None:
        if self.bars is not None:
            if count:
                self.bars.advance(self.all)
            self.bars.console.print(line, markup=False, highlight=False, soft_wrap=True)
        elif not self.quiet:
            self.console.print(line, markup=False, highlight=False, soft_wrap=True)

    def say(self, line: str) -> None:
        if not self.quiet:
            (self.bars.console if self.bars is not None else self.console).print(
                line, markup=False, highlight=False, soft_wrap=True)

    def close(self) -> None:
        if self.bars is not None:
            self.bars.__exit__(None, None, None)
            self.bars = None


def run(args) -> int:
    """Run the sweep of ``args`` (the parsed ``accuracy`` flags); returns the exit code."""
    from . import curves
    from .plot import plot_curves
    from .render import (AccuracyError, ShotFrame, load_reference, parse_integrator,
                         render_reference)

    if not os.path.exists(args.shot):
        return _error(f"{args.shot}: no such file", EXIT_USAGE)
    if args.threads < 0:
        return _error(f"--threads {args.threads}: must be 0 (all cores) or more", EXIT_USAGE)
    try:
        specs = [parse_integrator(t) for t in args.integrators.split(",") if t.strip()]
        if not specs:
            raise AccuracyError("--integrators: name at least one integrator")
        ref_spec = parse_integrator(args.reference_integrator)
    except AccuracyError as exc:
        msg = str(exc)
        return _error(msg if msg.startswith("--") else f"--integrators: {msg}", EXIT_USAGE)
    peers = []
    if args.peers:
        from .peers import parse_peers
        try:
            peers = parse_peers(args.peers)
        except ValueError as exc:
            return _error(str(exc), EXIT_USAGE)
    # frames
    from ..shot.frames import FrameSpecError, expand_pattern, has_frame_token, parse_frames
    from ..usd import UsdLoadError, open_stage
    try:
        stage = open_stage(args.shot)
    except UsdLoadError as exc:
        return _error(str(exc), EXIT_USAGE)
    start, end = float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    try:
        frames = (parse_frames(args.frames, start, end, stage.HasAuthoredTimeCodeRange())
                  if args.frames else [start])
    except FrameSpecError as exc:
        return _error(str(exc), EXIT_USAGE)
    del stage
    if args.reference and len(frames) > 1 and not has_frame_token(args.reference):
        return _error(f"--reference {args.reference}: {len(frames)} frames need a pattern "
                      "with #### (one reference per frame)", EXIT_USAGE)

    budgets = list(args.seconds)
    seeds = list(range(args.seeds))
    items = [("cmlt", s.text, s) for s in specs] + [(r, i, None) for r, i in peers]
    total = len(frames) * len(seeds) * len(budgets) * len(items)
    prog = _Progress(total, args.quiet)
    runs: List[curves.Run] = []
    references = []
    session = None
    load0 = os.getloadavg()
    started = time.strftime("%Y-%m-%d %H:%M:%S")
    t_start = time.perf_counter()
    shot_name = None
    res = None
    try:
        for frame in frames:
            try:
                sf = ShotFrame(args.shot, frame, args.res, args.threads, lambert=bool(peers),
                               peer_scene=bool(peers))
            except AccuracyError as exc:
                prog.close()
                return _error(str(exc), EXIT_USAGE)
            shot_name, res = sf.name, sf.resolution
            for w in sf.warnings:
                prog.say(f"cmlt: warning: {w}")
            # ---- the reference
            if args.reference:
                path = expand_pattern(args.reference, frame) if has_frame_token(args.reference) \
                    else args.reference
                try:
                    ref = load_reference(path, sf)
                except AccuracyError as exc:
                    prog.close()
                    return _error(str(exc), EXIT_USAGE)
            else:
                prog.start(f"reference {ref_spec} {args.reference_spp} spp, frame {frame:g}")
                ref = render_reference(sf, ref_spec.text, args.reference_spp, args.cache,
                                       progress=prog.fraction)
                prog.done(f"reference {ref_spec} {args.reference_spp} spp, frame {frame:g}: "
                          + ("cached " + os.path.basename(ref.source) if ref.cached
                             else f"{ref.time_s:.1f} s")
                          + (f"; its own relMSE ~ {ref.relmse_floor:.2g}"
                             if math.isfinite(ref.relmse_floor) else ""), count=False)
                warning = ref.warning()
                if warning:
                    prog.say(f"cmlt: warning: frame {frame:g}: {warning}")
            references.append({"frame": frame, "source": _rel(ref.source), "integrator": ref.integrator,
                               "spp": ref.spp, "time_s": ref.time_s,
                               "relmse_floor": ref.relmse_floor,
                               "relmse_floor_stderr": ref.relmse_floor_stderr,
                               "relmse_floor_variance": ref.relmse_floor_variance,
                               "relmse_floor_halves": ref.relmse_floor_halves,
                               "cached": ref.cached})
            # ---- peers on this frame
            if peers:
                from .peers import PeerSession, small_copy
                if session is None:
                    session = PeerSession([r for r, _ in peers], small_copy(sf.peer_scene),
                                          sf.threads,
                                          os.path.join(_out_dir(args, sf.name), "peer_logs"),
                                          variant=args.mitsuba_variant, say=prog.say)
                    for ren, st in session.status.items():
                        if not st.get("ok"):
                            prog.say(f"cmlt: warning: --peers: {ren} left out: {st['note']}")
                session.load(sf.peer_scene)
            # ---- the sweep, interleaved
            for seed in seeds:
                for budget in budgets:
                    for renderer, label, spec in items:
                        what = f"{label if renderer == 'cmlt' else renderer + ' ' + label} " \
                               f"{budget:g} s, seed {seed}, frame {frame:g}"
                        if renderer != "cmlt" and (session is None or renderer not in session.handles):
                            prog.done(f"{what}: skipped ({renderer} not running)")
                            continue
                        prog.start(what)
                        if renderer == "cmlt":
                            t0 = time.perf_counter()

                            def tick(f, t0=t0, budget=budget):
                                prog.fraction(max(f, (time.perf_counter() - t0) / budget))
                            r = sf.render(spec, seconds=budget, seed=seed, progress=tick)
                            image, dt, samples = r.image, r.time_s, r.samples
                        else:
                            try:
                                out = session.render(renderer, label, budget, seed)
                            except Exception as exc:       # noqa: BLE001 - a peer's failure
                                prog.done(f"{what}: {renderer} failed: {exc}")
                                continue
                            image, dt, samples = out["image"], out["time_s"], out["spp"]
                        m = curves.measure(image, ref.image)
                        runs.append(curves.Run(renderer, label, budget, seed, frame, dt, samples,
                                               m["relmse"], m["rmse"], m["mean_ratio"]))
                        prog.done(f"{what}: {dt:.2f} s, {samples:.1f} samples/px, relMSE "
                                  f"{m['relmse']:.4g}, mean/ref {m['mean_ratio']:.4f}")
    except AccuracyError as exc:
        prog.close()
        return _error(str(exc), EXIT_USAGE)
    finally:
        prog.close()
        if session is not None:
            session.close()
    load1 = os.getloadavg()

    # ---- outputs
    out = _out_dir(args, shot_name)
    os.makedirs(out, exist_ok=True)
    rows = curves.aggregate(runs)
    fit_list = curves.fits(runs)
    curves.write_csv(os.path.join(out, "accuracy.csv"), rows)
    curves.write_runs_csv(os.path.join(out, "runs.csv"), runs)
    floors = [r["relmse_floor"] for r in references if math.isfinite(r["relmse_floor"])]
    floor = max(floors) if floors else None
    w, h = res
    title = f"{shot_name}, {w}x{h}, {len(seeds)} seed(s), {len(frames)} frame(s)"
    plot_curves(rows, os.path.join(out, "accuracy.png"), title=title, floor=floor)
    meta = {"argv": [_rel(a) if os.path.exists(a) else a for a in sys.argv],
            "shot": _rel(args.shot), "frames": frames, "resolution": [w, h],
            "seconds": budgets, "seeds": seeds, "threads": args.threads,
            "integrators": [s.text for s in specs], "peers": [f"{r}:{i}" for r, i in peers],
            "peer_status": session.status if session is not None else {},
            "lambert": bool(peers), "references": references, "started": started,
            "elapsed_s": time.perf_counter() - t_start, "host": platform.node(),
            "cores": os.cpu_count(), "loadavg_start": load0, "loadavg_end": load1,
            "fits": [{"renderer": f.renderer, "integrator": f.integrator, "slope": f.slope,
                      "slope_se": f.slope_se, "intercept": f.intercept, "t_min": f.t_min,
                      "t_max": f.t_max, "renders": f.n,
                      "time_to": {str(k): v for k, v in f.targets.items()},
                      "extrapolated": {str(k): f.extrapolated(v) for k, v in f.targets.items()}}
                     for f in fit_list]}
    with open(os.path.join(out, "accuracy.json"), "w") as fh:
        json.dump(meta, fh, indent=2, default=float)
    floor_note = (f"; the reference's own relMSE is about {floor:.2g}" if floor else "")
    head = (f"### {shot_name}: relMSE against time ({w}x{h}, budgets "
            f"{', '.join(f'{b:g}' for b in budgets)} s, {len(seeds)} seed(s), "
            f"{len(frames)} frame(s); reference "
            + (f"{args.reference}" if args.reference else
               f"{ref_spec} {args.reference_spp} spp") + floor_note + ")")
    sys.stdout.write(curves.markdown_table(rows, fit_list, head))
    sys.stdout.flush()
    if not args.quiet:
        sys.stderr.write(f"cmlt: wrote {os.path.join(out, 'accuracy.csv')}, "
                         f"{os.path.join(out, 'accuracy.png')}\n")
    return EXIT_OK


def _rel(path: str) -> str:
    """``path`` relative to the working directory when inside it (records stay portable)."""
    if not path:
        return path
    ap = os.path.abspath(path)
    return os.path.relpath(ap) if ap.startswith(os.getcwd() + os.sep) else ap


def _out_dir(args, shot_name: Optional[str]) -> str:
    return args.out or os.path.join("renders", "accuracy", shot_name or "shot")

