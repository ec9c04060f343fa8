"""``cmlt flicker`` and ``cmlt compare`` (registered by :mod:`cmlt.cli`).

::

    cmlt flicker SEQUENCE [--reference REF [--reference-check REF2]] [--json OUT.json]
                 [--plot OUT.png] [--cvvdp] [--shot SHOT]
    cmlt compare A B [--json [OUT.json]]

SEQUENCE is a frame pattern (``renders/shot.####.exr``, ``$F4``, ``%04d``)
or a glob (quote it). REF is one image (a static shot's reference, used for
every frame) or a pattern/glob with the same frames as SEQUENCE. REF2 is a second
reference like REF, rendered the same way with another seed: the pair measures the
flicker REF's own noise puts under TF and GF (``reference_floor``). ``--json -``
writes the JSON to stdout instead of the table. Exit codes: 0 done, 2 a bad
flag or a missing/mismatched input (one line, ``cmlt: error: ...``).
"""
from __future__ import annotations

import json
import math
import os
import sys
from typing import Optional

from .flicker import FlickerReport, _finite_or_none, compare, flicker, reference_floor
from ..io.frame_pattern import has_frame_token, is_glob
from .sequence import MetricsError, load_image, load_sequence

__all__ = ["COMMANDS", "add_parsers", "run", "plot_report"]

COMMANDS = ("flicker", "compare")
EXIT_OK, EXIT_USAGE = 0, 2


def add_parsers(sub) -> None:
    """Add the ``flicker`` and ``compare`` subcommands to cmlt's subparsers."""
    f = sub.add_parser("flicker", help="temporal/global flicker and relMSE of a rendered "
                       "sequence (DESIGN.md §4)",
                       description="Flicker metrics of an image sequence: temporal flicker "
                       "TF, global flicker GF (population std) and per-frame relMSE against "
                       "a reference; without a reference, the frame-difference measure "
                       "(meaningful for a static shot).")
    f.add_argument("sequence", metavar="SEQUENCE",
                   help="frame pattern (shot.####.exr, $F4, %%04d) or a quoted glob")
    f.add_argument("--reference", "-r", metavar="REF",
                   help="one reference image for every frame (static shot) or a pattern/glob "
                   "with one reference per frame")
    f.add_argument("--reference-check", metavar="REF2",
                   help="a second reference like REF, rendered the same way with another "
                   "seed: reports the TF and GF REF's own noise accounts for (its floor) and "
                   "warns when TF is less than 3x it (the reference is then a large part "
                   "of what TF measures)")
    f.add_argument("--json", metavar="PATH", dest="json_out",
                   help="write the report as JSON (- for stdout, instead of the table)")
    f.add_argument("--plot", metavar="PNG", help="plot the per-frame values (needs matplotlib: the extra cmlt[plot])")
    f.add_argument("--cvvdp", action="store_true",
                   help="also ColorVideoVDP's JOD against the reference (optional package "
                   "cvvdp; says why when it cannot run)")
    f.add_argument("--fps", type=float, default=24.0,
                   help="frame rate the sequence is shown at for --cvvdp (default 24)")
    f.add_argument("--shot", metavar="SHOT",
                   help="the USD shot the frames were rendered from: also the "
                   "motion-compensated TF, each frame's error compared with the next "
                   "frame's where its surface point went (the shot's camera and geometry "
                   "motion at the frames' resolution) — the measure for camera moves")

    c = sub.add_parser("compare", help="compare two images: relMSE, RMSE, mean ratio, "
                       "max abs diff, PSNR",
                       description="Compare image A with reference B.")
    c.add_argument("a", metavar="A", help="image (EXR)")
    c.add_argument("b", metavar="B", help="reference image (EXR)")
    c.add_argument("--json", metavar="PATH", dest="json_out", nargs="?", const="-",
                   help="print JSON instead of the table (or write it to PATH)")


def _error(message: str) -> int:
    sys.stderr.write(f"cmlt: error: {message}\n")
    return EXIT_USAGE


def _fmt(v, spec=".5g") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return format(v, spec)


def _frame(f: float) -> str:
    return f"{int(round(f))}" if abs(f - round(f)) < 1e-6 else f"{f:g}"


def _is_sequence(text: str) -> bool:
    return has_frame_token(text) or is_glob(text)


def _write_json(path: str, data) -> None:
    text = json.dumps(_finite_or_none(data), indent=2) + "\n"
    if path == "-":
        sys.stdout.write(text)
        return
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


def _console():
    from rich.console import Console
    return Console(highlight=False)


def print_report(report: FlickerReport, sequence: str, reference: Optional[str]) -> None:
    from rich.table import Table

    ref = (f"reference {reference}" + (" (one image for every frame)"
                                        if report.static_reference else "")
           if reference else "no reference: frame differences")
    header = f"{sequence}  ·  {report.size[0]}x{report.size[1]}  ·  {ref}"
    t = Table()
    t.add_column("frame", justify="right")
    t.add_column("mean I", justify="right")
    if report.mode == "reference":
        t.add_column("mean R", justify="right")
        t.add_column("I/R", justify="right")
        t.add_column("|ΔE|/R", justify="right")
        t.add_column("relMSE", justify="right")
    else:
        t.add_column("I/mean I", justify="right")
        t.add_column("|ΔI|/I", justify="right")
    for k, f in enumerate(report.frames):
        row = [_frame(f), _fmt(report.mean[k])]
        if report.mode == "reference":
            row += [_fmt(report.reference_mean[k]), _fmt(report.ratio[k], ".4f"),
                    _fmt(report.delta[k]), _fmt(report.rel_mse[k])]
        else:
            row += [_fmt(report.ratio[k], ".4f"), _fmt(report.delta[k])]
        t.add_row(*row)
    con = _console()
    con.print(header, soft_wrap=True, markup=False)
    con.print(t)
    summary = f"TF {_fmt(report.tf)}   GF {_fmt(report.gf)} (population std)"
    if report.mode == "reference":
        summary += f"   mean relMSE {_fmt(report.mean_rel_mse)}"
    con.print(f"{len(report.frames)} frames   " + summary, soft_wrap=True, markup=False)
    for w in report.warnings:
        sys.stderr.write(f"cmlt: warning: {w}\n")


def _pyplot():
    """matplotlib.pyplot on the Agg backend; matplotlib is the optional extra
    ``plot`` (``pip install 'cmlt[plot]'``), so a missing one is a clear error."""
    try:
        import matplotlib
    except ImportError:
        raise MetricsError("--plot needs matplotlib, which is not installed: "
                           "pip install 'cmlt[plot]' (or pip install matplotlib)") from None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def plot_report(report: FlickerReport, path: str, title: str = "") -> str:
    """Per-frame plot: brightness, I/R (GF) and the frame-to-frame change
    (TF), and relMSE when there is a reference."""
    plt = _pyplot()

    rows = 3 if report.mode == "reference" else 2
    fig, axes = plt.subplots(rows, 1, figsize=(8, 2.4 * rows), sharex=True)
    x = report.frames
    ax = axes[0]
    ax.plot(x, report.mean, "o-", ms=3, label="mean I")
    if report.reference_mean is not None:
        ax.plot(x, report.reference_mean, "k--", lw=1, label="mean R")
    ax.set_ylabel("mean brightness")
    ax2 = ax.twinx()
    ratio = [float("nan") if v is None else v for v in report.ratio]
    ax2.plot(x, ratio, "s:", ms=3, color="tab:orange",
             label="I/R" if report.mode == "reference" else "I / mean I")
    ax2.set_ylabel(f"ratio (GF {_fmt(report.gf, '.3g')})")
    ax.legend(loc="upper left", fontsize=8)
    ax2.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    xs = x[1:]
    ax.plot(xs, report.delta[1:], "o-", ms=3, color="tab:red")
    if report.tf is not None:
        ax.axhline(report.tf, color="k", lw=0.8, ls="--", label=f"TF {report.tf:.3g}")
        ax.legend(fontsize=8)
    ax.set_ylabel("|ΔE|/R" if report.mode == "reference" else "|ΔI|/I")
    if rows == 3:
        ax = axes[2]
        ax.plot(x, report.rel_mse, "o-", ms=3, color="tab:green")
        ax.axhline(report.mean_rel_mse, color="k", lw=0.8, ls="--",
                   label=f"mean {report.mean_rel_mse:.3g}")
        ax.set_ylabel("relMSE")
        ax.legend(fontsize=8)
    from matplotlib.ticker import MaxNLocator
    for a in axes:
        a.ticklabel_format(axis="y", useOffset=False)
        a.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes[-1].set_xlabel("frame")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _cmd_flicker(args, screen_flow=None) -> int:
    if args.plot:
        _pyplot()                       # before the work: a missing matplotlib fails fast
    frames, images = load_sequence(args.sequence)
    reference = None
    if getattr(args, "reference_check", None) and not args.reference:
        raise MetricsError("--reference-check needs --reference (it measures that "
                           "reference's own noise)")
    if args.reference:
        reference = _load_reference(args.reference, args.sequence, frames, images)
    report = flicker(images, reference, frames=frames)
    floor, floor_line = None, None
    if getattr(args, "reference_check", None):
        second = _load_reference(args.reference_check, args.sequence, frames, images)
        floor = reference_floor(reference, second, frames)
        floor_line = (f"reference floor (the TF and GF {args.reference}'s own noise accounts "
                      f"for, from {args.reference_check}): TF {_fmt(floor['tf'])}   "
                      f"GF {_fmt(floor['gf'])}")
        if report.tf is not None and floor["tf"] is not None and report.tf < 3.0 * floor["tf"]:
            report.warnings.append(
                f"TF {_fmt(report.tf)} is less than 3x the reference's own floor "
                f"{_fmt(floor['tf'])}: the reference's noise is a large part of it "
                "(render the reference with more samples per pixel)")
    data = report.to_dict()
    data["sequence"] = args.sequence
    data["reference"] = args.reference
    if floor is not None:
        data["reference_floor"] = dict(_finite_or_none(floor), check=args.reference_check)
    mc_line = None
    if getattr(args, "shot", None):
        refs = None if reference is None else (
            reference if isinstance(reference, list) else [reference] * len(images))
        terms = _motion_terms(args.shot, frames, images, refs, screen_flow)
        finite = [t for t in terms if t == t]
        tf_mc = sum(finite) / len(finite) if finite else None
        data["shot"] = args.shot
        data["delta_motion_compensated"] = [None] + [t if t == t else None for t in terms]
        data["tf_motion_compensated"] = tf_mc
        mc_line = (f"TF, motion-compensated along {args.shot}'s screen motion "
                   f"{_fmt(tf_mc)}")
    jod_line = None
    if getattr(args, "cvvdp", False):
        from . import cvvdp
        if reference is None:
            raise MetricsError("--cvvdp needs --reference (ColorVideoVDP is a full-reference "
                               "metric)")
        refs = reference if isinstance(reference, list) else [reference] * len(images)
        why = cvvdp.unavailable()
        if why:
            data["cvvdp"] = {"jod": None, "unavailable": why}
            jod_line = f"ColorVideoVDP: not run: {why}"
        else:
            jod = cvvdp.video_jod(images, refs, fps=args.fps)
            data["cvvdp"] = {"jod": jod, "fps": args.fps}
            jod_line = f"ColorVideoVDP: {jod:.3f} JOD (10 = no visible difference), {args.fps:g} fps"
    if args.json_out != "-":
        print_report(report, args.sequence, args.reference)
        if floor_line:
            _console().print(floor_line, soft_wrap=True, markup=False)
        if mc_line:
            _console().print(mc_line, soft_wrap=True, markup=False)
        if jod_line:
            _console().print(jod_line, soft_wrap=True, markup=False)
    elif jod_line and data["cvvdp"]["jod"] is None:
        sys.stderr.write(f"cmlt: {jod_line}\n")
    if args.json_out:
        _write_json(args.json_out, data)
    if args.plot:
        plot_report(report, args.plot, title=args.sequence
                    + (f" vs {args.reference}" if args.reference else ""))
    return EXIT_OK


def _load_reference(path: str, sequence: str, frames, images):
    """One reference image, or a list with one per frame of the sequence (a pattern or
    glob with exactly its frames); MetricsError naming both when they do not match."""
    if _is_sequence(path):
        rframes, refs = load_sequence(path)
        if rframes != frames:
            have, want = set(rframes), set(frames)
            missing = sorted(want - have)
            extra = sorted(have - want)
            parts = []
            if missing:
                parts.append(f"no reference for frame(s) "
                             f"{', '.join(_frame(f) for f in missing[:8])}")
            if extra:
                parts.append(f"reference frame(s) {', '.join(_frame(f) for f in extra[:8])} "
                             f"not in the sequence")
            raise MetricsError(f"{sequence} and {path} have different "
                               f"frames: {'; '.join(parts)}")
        reference = refs
    else:
        reference = load_image(path)
    ref_shape = (reference if not isinstance(reference, list) else reference[0]).shape
    if ref_shape != images[0].shape:
        raise MetricsError(f"{sequence} frames are {images[0].shape[1]}x"
                           f"{images[0].shape[0]} but {path} is "
                           f"{ref_shape[1]}x{ref_shape[0]}")
    return reference


def _motion_terms(shot: str, frames, images, refs, screen_flow):
    """motion_compensated_terms of the frames along the shot's screen motion (the
    frames' numbers are the shot's time codes). ``screen_flow(shot, times, (w, h))``:
    cmlt.shot.motion's, handed in by cmlt.cli (metrics does not import the shot
    package), raising MetricsError for a shot it cannot read."""
    import os

    from .flicker import motion_compensated_terms

    if screen_flow is None:
        raise MetricsError("--shot: no screen motion available (run through `cmlt flicker`)")
    if not os.path.isfile(shot):
        raise MetricsError(f"--shot {shot}: no such file")
    h, w = images[0].shape[:2]
    flow = screen_flow(shot, [float(f) for f in frames], (w, h))
    return motion_compensated_terms(images, refs, flow)


def _cmd_compare(args) -> int:
    res = compare(args.a, args.b)
    data = dict(res, a=args.a, b=args.b)
    if args.json_out:
        _write_json(args.json_out, data)
    if args.json_out != "-":
        from rich.table import Table
        t = Table(show_header=False)
        t.add_column("metric")
        t.add_column("value", justify="right")
        for key, label in (("rel_mse", "relMSE"), ("rmse", "RMSE"),
                           ("mean_ratio", "mean A / mean B"), ("max_abs_diff", "max |A−B|"),
                           ("psnr", "PSNR (dB, peak = max B)"), ("mean_a", "mean A"),
                           ("mean_b", "mean B")):
            t.add_row(label, _fmt(res[key]))
        con = _console()
        con.print(f"{args.a}  vs  {args.b}  ({res['width']}x{res['height']})", soft_wrap=True,
                  markup=False)
        con.print(t)
    return EXIT_OK


def run(args, screen_flow=None) -> int:
    """Run ``flicker`` or ``compare``; MetricsError becomes a one-line error, exit 2.
    ``screen_flow``: what ``flicker --shot`` measures the motion with (cmlt.cli hands in
    the shot package's)."""
    try:
        if args.command == "flicker":
            return _cmd_flicker(args, screen_flow)
        if args.command == "compare":
            return _cmd_compare(args)
    except MetricsError as exc:
        return _error(str(exc))
    except OSError as exc:
        return _error(str(exc))
    return _error(f"unknown command {args.command!r}")
