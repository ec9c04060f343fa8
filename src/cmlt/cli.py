"""The ``cmlt`` command line.

::

    cmlt render SHOT [--frames SPEC [--force-frames] | -f START [-n COUNT] [-i STEP]]
                     [--out|-o PATTERN]
                     [--spp N] [-R|--settings PRIM] [--list-cameras] [--exposure STOPS]
                     [--integrator pt|bdpt|pssmlt|cmlt]
                     [--sigma S] [--large-step-probability P] [--chains N]
                     [--bootstrap-samples N] [--tries K] [--inner-length M]
                     [--inner seed|mtm|bundle] [--no-packets]
                     [--seed S] [--threads N] [--res WxH | --res W H] [--max-depth N]
                     [--camera PATH] [--variant [/PRIM:]SET=VALUE ...]
                     [--default-light dome|headlight|dome-key] [--purpose LIST] [--half] [--compression zip|piz|dwaa|none]
                     [--output-colorspace NAME] [--ocio-config PATH] [--rendering-space NAME]
                     [--aov albedo,normal,depth,variance] [--aov-samples N]
                     [--crop X0,Y0,X1,Y1] [--preview] [--preview-format png|jpg]
                     [--display NAME] [--view NAME]
                     [--seed-per-frame] [--independent-frames] [--no-smoothing]
                     [--state-dir DIR [--fresh-start-on-bad-state]] [--no-frame-hold]
                     [--dask local:N|tcp://HOST:8786 [--dask-parts N]]
                     [--resume] [--quiet | --log-json] [-v [N] | -vv | -vvv]
    cmlt inspect SHOT [--frames SPEC] [--json] [--variant [/PRIM:]SET=VALUE ...] | --image FILE.exr
    cmlt contact-sheet PATTERN --out SHEET.png [--columns N] [--display NAME] [--view NAME]
    cmlt flicker SEQUENCE [--reference REF] [--json OUT] [--plot PNG] [--cvvdp] [--shot SHOT]
    cmlt compare A B [--json [OUT]]
    cmlt accuracy SHOT [--seconds 1,2,4,8] [--integrators LIST] [--res WxH] ...  (cmlt.accuracy.cli)
    cmlt --version

Exit codes: 0 done; 1 the shot or the render failed; 2 a bad flag or path;
130 interrupted (Ctrl-C; finished frames stay, ``--resume`` continues).
Errors are one line on stderr (``cmlt: error: ...``), never a traceback,
unless ``CMLT_DEBUG=1`` is set in the environment. ``CMLT_CORE_ISA`` (``auto``,
``baseline``, ``x86-64-v4``) picks the build of the core (_core_select.py); ``--version``
names the one loaded.
"""
from __future__ import annotations

import argparse
import os
import shlex
import sys
from typing import List, Optional, Sequence

from ._core_select import CoreSelectError
from ._version import __version__
from .cli_args import (EXIT_INTERRUPTED, EXIT_OK, EXIT_RENDER, EXIT_USAGE, _error, _int_at_least, _Parser,
                       parse_aovs, parse_crop, parse_purposes, parse_resolution, parse_variant_flag)
from .cli_images import _cmd_contact_sheet, _cmd_inspect_image

__all__ = ["main", "build_parser", "parse_resolution"]


class _VersionAction(argparse.Action):
    """``--version``: the package's version and the build of the core loaded here
    (``cmlt._core.isa``: the portable ``x86-64`` or a newer level; _core_select.py)."""

    def __call__(self, parser, namespace, values, option_string=None):
        from . import _core
        sys.stdout.write(f"cmlt {__version__} (core {_core.isa})\n")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    from .io.exr import COMPRESSIONS
    from .settings import DEFAULT_RESOLUTION
    from .settings.flags import SEQUENCE_GROUP, add_setting_flags

    p = _Parser(prog="cmlt", description="Render animated USD shots with coherent "
                "Metropolis light transport.")
    p.add_argument("--version", action=_VersionAction, nargs=0,
                   help="print the version and the build of the core this CPU loads, and exit")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    r = sub.add_parser("render", help="render frames of a shot to OpenEXR",
                       description="Render frames of a USD shot to scene-linear OpenEXR, "
                       "with a JSON statistics sidecar (IMAGE.json) beside each image.")
    r.add_argument("shot", metavar="SHOT", help="USD stage (.usda, .usdc, .usd, .usdz)")
    r.add_argument("--frames", metavar="SPEC",
                   help="time codes: 7, 1.5, 1:24 or 1-24, 1:24x2 (stride), 1,5,9, all "
                   "(the stage's range); default: the stage's start time code. Frames "
                   "outside the stage's time range get a warning, far outside it an error")
    r.add_argument("--force-frames", action="store_true", dest="force_frames",
                   help="render --frames even far outside the stage's time range")
    r.add_argument("--out", "-o", metavar="PATTERN",
                   help="output image; the frame number replaces #### (zero-padded to the "
                   "number of #), ####.### (decimals), $F4/$F or %%04d; fractional frames "
                   "get three decimals (0001.500); default renders/<shot>.####.exr")
    r.add_argument("-f", "--frame", type=float, metavar="START", dest="frame_start",
                   help="husk style: the first frame (with -n/--frame-count and "
                   "-i/--frame-inc; instead of --frames)")
    r.add_argument("-n", "--frame-count", type=_int_at_least(1), metavar="N",
                   dest="frame_count", help="husk style: how many frames from -f (default 1)")
    r.add_argument("-i", "--frame-inc", type=float, metavar="STEP", dest="frame_inc",
                   help="husk style: the step between frames from -f (default 1)")
    t = r.add_argument_group(SEQUENCE_GROUP)
    add_setting_flags(r, sequence_group=t)    # every setting of the table that has a flag
    r.add_argument("--res", type=parse_resolution, metavar="WxH",
                   help="resolution, WxH or W H; default: the stage's render settings, else "
                   f"{DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]}")
    r.add_argument("--camera", metavar="PATH", help="camera prim path (default: the "
                   "render settings' camera, else the stage's camera)")
    r.add_argument("-R", "--settings", metavar="PRIM", dest="render_settings",
                   help="the UsdRender.Settings prim to render with (default: the stage's "
                   "renderSettingsPrimPath, else its first RenderSettings prim)")
    r.add_argument("--purpose", type=parse_purposes, metavar="LIST", default=(),
                   dest="purposes",
                   help="purposes rendered besides default, comma-separated from render, "
                   "proxy, guide (as husk's --purpose; 'geometry' means default); default: "
                   "render, and proxy where no sibling subtree has render")
    r.add_argument("--list-cameras", action="store_true", dest="list_cameras",
                   help="print the stage's cameras (the one a render would use first) and exit")
    r.add_argument("--exposure", type=float, default=0.0, metavar="STOPS",
                   help="scale previews by 2^STOPS (--preview; the EXR is not changed)")
    r.add_argument("--variant", type=parse_variant_flag, action="append", default=[],
                   dest="variants", metavar="[/PRIM:]SET=VALUE",
                   help="variant selection applied in the session layer before the shot is "
                   "read (repeatable, in order): SET=VALUE on every prim with that variant "
                   "set, /PRIM:SET=VALUE on one prim; `cmlt inspect` lists the sets")
    from .usd.lights import DEFAULT_LIGHTS
    r.add_argument("--default-light", choices=DEFAULT_LIGHTS,
                   default="dome", dest="default_light",
                   help="what lights a stage that has no lights and no emissive materials: "
                   "dome (white, radiance 1: a furnace; the default), headlight (a distant "
                   "light along the camera's view, as usdrecord/Storm), dome-key (a dim fill "
                   "dome and a key light from the camera's upper left)")
    r.add_argument("--half", action="store_true", help="write 16-bit half floats")
    r.add_argument("--compression", choices=COMPRESSIONS, default="zip",
                   help="EXR compression (default zip)")
    r.add_argument("--output-colorspace", metavar="NAME", dest="output_colorspace",
                   help="colour space of the written EXRs (an OCIO name, alias or interop "
                   "ID, e.g. lin_rec709); default: the rendering space, ACEScg")
    r.add_argument("--ocio-config", metavar="PATH", dest="ocio_config",
                   help="OpenColorIO config (file or ocio:// URI); default: $OCIO, else the "
                   "stage's colorConfiguration, else the built-in studio config")
    r.add_argument("--rendering-space", metavar="NAME", dest="rendering_space",
                   help="colour space of the OCIO config to render in (default: its "
                   "scene_linear role, ACEScg in the ACES configs)")
    r.add_argument("--aov", type=parse_aovs, metavar="LIST", dest="aov", default=(),
                   help="extra channels in the same EXR: albedo (albedo.R/G/B), normal "
                   "(N.X/Y/Z, world space), depth (Z, along the camera axis; 0 = no hit), "
                   "variance (variance.R/G/B), error (relMSE: the per-pixel relMSE estimate, "
                   "pt and bdpt); comma-separated")
    r.add_argument("--aov-samples", type=_int_at_least(1), default=4, dest="aov_samples",
                   metavar="N", help="camera rays per pixel of the albedo/normal/depth pass "
                   "(default 4)")
    r.add_argument("--crop", type=parse_crop, metavar="X0,Y0,X1,Y1",
                   help="store only this pixel window (X1, Y1 exclusive) as the EXR data "
                   "window; the display window stays the full frame (the full frame is "
                   "rendered)")
    r.add_argument("--preview", action="store_true",
                   help="also write a display-referred preview per frame beside the EXR "
                   "(same name, .png or .jpg)")
    r.add_argument("--preview-format", choices=("png", "jpg"), default="png",
                   dest="preview_format", help="preview file format (default png)")
    r.add_argument("--display", metavar="NAME",
                   help="OCIO display of previews (default 'sRGB - Display')")
    r.add_argument("--view", metavar="NAME",
                   help="OCIO view of previews (default: the display's default view)")
    r.add_argument("--resume", action="store_true",
                   help="skip frames already finished (a complete, finite image of this render's "
                   "size and channels with its sidecar); others are rendered again")
    t.add_argument("--state-dir", metavar="DIR", dest="state_dir",
                   help="write DIR/state.####.bin per frame (chain states, normalisation "
                   "history) and continue from the state of the frame before the first one "
                   "rendered, bit-identically to one job")
    t.add_argument("--fresh-start-on-bad-state", action="store_true",
                   dest="fresh_start_on_bad_state",
                   help="a corrupted, truncated or mismatched state file: warn and start "
                   "fresh instead of failing")
    t.add_argument("--no-frame-hold", action="store_false", dest="hold_frames",
                   help="render every frame, also one whose scene and random numbers are "
                   "the frame before's (by default such a frame, which would render the "
                   "same image bit for bit, takes that frame's render: a held shot costs "
                   "one frame)")
    r.add_argument("--dask", metavar="SCHEDULER",
                   help="render each frame's parts (chain groups of pssmlt/cmlt, row bands "
                   "of pt, whole bdpt frames) as Dask tasks: local:N starts N worker "
                   "processes here, else a scheduler address (tcp://host:8786); the images "
                   "are bit-identical to one process")
    r.add_argument("--dask-parts", metavar="N", type=int, default=0, dest="dask_parts",
                   help="part tasks per frame with --dask (default 0: one per frame, frames side "
                   "by side, while at least as many frames are left as there are workers; "
                   "else one per worker)")
    loud = r.add_mutually_exclusive_group()
    loud.add_argument("--quiet", "-q", action="store_true",
                      help="print nothing but errors")
    r.add_argument("--verbosity", type=int, choices=range(0, 4), default=None,
                   metavar="N", help="-v N / -v / -vv / -vvv: 0 errors only, 1 normal (default), "
                   "2 verbose (set-up and per-frame details), 3 debug (settings with sources, "
                   "scene updates, effects, tracebacks)")
    loud.add_argument("--log-json", action="store_true", dest="log_json",
                      help="for farms: one JSON object per line per event (frame start, "
                      "frame done, warning, sequence done) on stdout, nothing else")

    i = sub.add_parser("inspect", help="describe a shot (time range, cameras, lights, "
                       "settings) or an image's header (--image)")
    i.add_argument("shot", metavar="SHOT", nargs="?", help="USD stage")
    i.add_argument("--variant", type=parse_variant_flag, action="append", default=[],
                   dest="variants", metavar="[/PRIM:]SET=VALUE",
                   help="describe the shot with these variant selections (as cmlt render)")
    i.add_argument("--image", metavar="FILE", help="print the header of an EXR (or any "
                   "image OpenImageIO reads): channels, windows, colour space, cmlt metadata")
    i.add_argument("--frames", metavar="SPEC", help="frames whose effects are analysed "
                   "(as for render; default: the stage's start time code)")
    i.add_argument("--json", action="store_true", help="print the effects analysis and the "
                   "--integrator auto choice as one JSON object instead of the report")

    c = sub.add_parser("contact-sheet", help="tile a sequence of frames into one "
                       "display-referred image with frame numbers",
                       description="Tile EXR frames (a frame pattern like "
                       "renders/shot.####.exr, a glob, or files) into one PNG/JPEG through "
                       "an OCIO display/view, each labelled with its frame number.")
    c.add_argument("pattern", metavar="PATTERN", nargs="+",
                   help="frame pattern (####, %%04d, $F4), glob, or image files")
    c.add_argument("--out", metavar="SHEET", required=True, help="output .png or .jpg")
    c.add_argument("--columns", type=_int_at_least(1), metavar="N",
                   help="thumbnails per row (default: about the square root of the count)")
    c.add_argument("--thumb-width", type=_int_at_least(8), default=256, dest="thumb_width",
                   metavar="PX", help="thumbnail width in pixels (default 256)")
    c.add_argument("--display", metavar="NAME", help="OCIO display (default 'sRGB - Display')")
    c.add_argument("--view", metavar="NAME", help="OCIO view (default: the display's default)")
    c.add_argument("--ocio-config", metavar="PATH", dest="ocio_config",
                   help="OpenColorIO config (default: $OCIO, else the built-in one)")
    from .metrics.cli import add_parsers as _add_metrics_parsers
    _add_metrics_parsers(sub)           # flicker, compare (cmlt.metrics.cli)
    from .accuracy.cli import add_parser as _add_accuracy_parser
    _add_accuracy_parser(sub)           # accuracy (cmlt.accuracy.cli; sets args.handler)
    return p


def _resume_command(argv: Sequence[str], state_dir: Optional[str] = None) -> str:
    """The command that continues an interrupted render: the same arguments
    plus ``--resume``, and ``--state-dir DIR`` whenever a state directory was
    used (spelt out in full even if the user abbreviated the flag), so that a
    resumed pssmlt/cmlt sequence continues its chains and normalisation
    history instead of starting them cold."""
    args = list(argv)
    if "--resume" not in args:
        args.append("--resume")
    if state_dir and not any(a == "--state-dir" or a.startswith("--state-dir=") for a in args):
        args += ["--state-dir", state_dir]
    return shlex.join(["cmlt", *args])


def _cmd_render(args, argv: Sequence[str]) -> int:
    from .shot import RenderCancelled, RenderError, RenderOptions, UsageError, render_sequence

    from .shot.options import SETTING_NAMES
    opts = RenderOptions(**{name: getattr(args, name) for name in SETTING_NAMES},
                         resolution=args.res, camera=args.camera, half=args.half,
                         compression=args.compression, output_colorspace=args.output_colorspace,
                         ocio_config=args.ocio_config, aovs=tuple(args.aov),
                         rendering_space=args.rendering_space,
                         aov_samples=args.aov_samples, crop=args.crop, preview=args.preview,
                         preview_format=args.preview_format, display=args.display,
                         view=args.view, state_dir=args.state_dir,
                         fresh_start_on_bad_state=args.fresh_start_on_bad_state,
                         hold_frames=args.hold_frames, dask=args.dask, dask_parts=args.dask_parts,
                         variants=tuple(args.variants), default_light=args.default_light,
                         render_settings=args.render_settings, exposure=args.exposure,
                         purposes=tuple(args.purposes))
    log = None
    if args.quiet and args.verbosity not in (None, 0):
        return _error(f"give --quiet or -v {args.verbosity}, not both", EXIT_USAGE)
    verbosity = 0 if args.quiet else (1 if args.verbosity is None else args.verbosity)
    quiet = verbosity == 0 and not args.log_json
    if args.log_json:
        from .shot.progress import JsonReporter
        log = JsonReporter(sys.stdout, verbosity=verbosity)

    def fail(message: str, code: int) -> int:
        if log is not None:
            log.emit("error", message=message, exit_code=code)
        return _error(message, code)

    frames = args.frames
    if args.frame_start is not None or args.frame_count is not None \
            or args.frame_inc is not None:
        if args.frames is not None:
            return fail("give --frames or -f/-n/-i, not both", EXIT_USAGE)
        if args.frame_start is None:
            return fail("-n/--frame-count and -i/--frame-inc need -f/--frame START",
                        EXIT_USAGE)
        inc = 1.0 if args.frame_inc is None else args.frame_inc
        if not inc > 0:
            return fail(f"-i/--frame-inc {args.frame_inc:g}: must be positive", EXIT_USAGE)
        n = args.frame_count or 1
        frames = [args.frame_start + k * inc for k in range(n)]
    if args.list_cameras:
        return _list_cameras(args.shot, opts)
    try:
        res = render_sequence(args.shot, frames, args.out, opts, resume=args.resume,
                              progress=not (quiet or args.log_json), quiet=quiet,
                              reporter=log, force_frames=args.force_frames,
                              verbosity=verbosity)
    except UsageError as exc:
        return fail(str(exc), EXIT_USAGE)
    except RenderError as exc:
        return fail(str(exc), EXIT_RENDER)
    except RenderCancelled as exc:
        resume = _resume_command(argv, opts.state_dir)
        if log is not None:
            log.emit("interrupted", message=str(exc), written=list(exc.written),
                     resume=resume, exit_code=EXIT_INTERRUPTED)
        sys.stderr.write(f"cmlt: {exc}\ncmlt: to continue: {resume}\n")
        return EXIT_INTERRUPTED
    if not (quiet or args.log_json):
        from rich.console import Console
        from .shot.progress import summary_table

        n = len(res.written)
        skipped = f", {len(res.skipped)} skipped (already rendered)" if res.skipped else ""
        auto = res.settings.get("integrator_auto")
        if auto:                            # --integrator auto (cmlt.analysis.auto)
            sys.stderr.write(f"cmlt: integrator auto: {auto['name']} ({auto['reason']})\n")
        sys.stderr.write(f"cmlt: {n} frame(s) written{skipped}\n")
        if n:
            Console(stderr=True, highlight=False).print(summary_table(res))
    return EXIT_OK


def _list_cameras(shot: str, opts) -> int:
    """``cmlt render SHOT --list-cameras``: the stage's cameras, one per line, the
    one a render would use marked with ``*`` (--camera, else the render settings',
    else the first)."""
    from .usd import UsdLoadError, open_stage
    from .usd.camera import stage_cameras
    from .usd.render_settings import find_settings_prim, settings_camera
    from .usd.variants import VariantError

    if not os.path.exists(shot):
        return _error(f"{shot}: no such file", EXIT_USAGE)
    try:
        stage = open_stage(shot, variants=opts.variants, render_settings=opts.render_settings)
        cams = [str(c.GetPath()) for c in stage_cameras(stage)]
        settings = find_settings_prim(stage)
    except VariantError as exc:
        return _error(str(exc), EXIT_USAGE)
    except UsdLoadError as exc:
        return _error(str(exc), EXIT_RENDER)
    chosen = opts.camera
    sc = settings_camera(settings) if settings is not None else None
    if chosen is None and sc is not None and str(sc) in cams:
        chosen = str(sc)
    if chosen is None and cams:
        chosen = cams[0]
    for c in cams:
        sys.stdout.write(f"{'*' if c == chosen else ' '} {c}\n")
    if not cams:
        sys.stdout.write("(no cameras: a render frames the stage with a camera of its own)\n")
    return EXIT_OK


def _husk_argv(argv: Sequence[str]) -> List[str]:
    """husk/usdrecord spellings argparse cannot take as they are: ``--res W H``
    becomes ``--res WxH``; ``-v N`` (or husk's ``-V N``) ``--verbosity N``, ``-v`` 2,
    ``-vv`` 3 (more v's: 3)."""
    out, k = [], 0
    argv = list(argv)
    while k < len(argv):
        a = argv[k]
        if a in ("-v", "-V") and k + 1 < len(argv) and argv[k + 1].isdigit():
            out += ["--verbosity", str(min(int(argv[k + 1]), 3))]
            k += 2
            continue
        if len(a) >= 2 and a[0] == "-" and set(a[1:]) == {"v"}:
            out += ["--verbosity", str(min(len(a), 3))]
            k += 1
            continue
        if a == "--res" and k + 2 < len(argv) and argv[k + 1].isdigit() \
                and argv[k + 2].isdigit():
            out += ["--res", f"{argv[k + 1]}x{argv[k + 2]}"]
            k += 3
            continue
        out.append(a)
        k += 1
    return out


def _cmd_inspect(args) -> int:
    from .settings import SettingsError, format_settings, resolve_settings
    from .usd import UsdLoadError, open_stage, stage_info
    from .usd.variants import VariantError

    if args.image:
        if args.shot:
            return _error("inspect: give a SHOT or --image FILE, not both", EXIT_USAGE)
        return _cmd_inspect_image(args.image)
    if not args.shot:
        return _error("inspect: give a SHOT (USD stage) or --image FILE", EXIT_USAGE)
    if not os.path.exists(args.shot):
        return _error(f"{args.shot}: no such file", EXIT_USAGE)
    try:
        stage = open_stage(args.shot, variants=args.variants)
        info = stage_info(stage)
        report = info.format()
    except VariantError as exc:
        return _error(str(exc), EXIT_USAGE)
    except UsdLoadError as exc:
        return _error(str(exc), EXIT_RENDER)
    from .shot import RenderError, UsageError
    from .shot.analyse import inspect_effects
    from .shot.py_warnings import warnings_to_stderr
    try:                                    # the effects of the frames (cmlt.analysis)
        with warnings_to_stderr():
            effects, table = inspect_effects(stage, info, args.frames)
    except (UsageError, RenderError) as exc:
        return _error(str(exc), EXIT_USAGE if isinstance(exc, UsageError) else EXIT_RENDER)
    if args.json:
        import json
        sys.stdout.write(json.dumps(effects, indent=2) + "\n")
        return EXIT_OK
    sys.stdout.write(report.rstrip("\n") + "\n")
    try:
        settings, sources = resolve_settings(stage)
    except SettingsError as exc:
        sys.stdout.flush()
        return _error(str(exc), EXIT_RENDER)
    if settings.camera and info.settings_camera_warning:
        # the relationship is authored but cannot be used (see the warning above)
        why = info.settings_camera_warning.split(f"camera {settings.camera} ", 1)[-1]
        sources = dict(sources, camera=f"{sources.get('camera', 'stage')} "
                                       f"(NOT USED: {why.split(';')[0]})")
    sys.stdout.write(format_settings(settings, sources).rstrip("\n") + "\n")
    # the OpenColorIO config a render of this shot would use, and where it came from
    # (--ocio-config is a render flag: here $OCIO, the stage's, else the built-in one)
    from .color import ColorError, load_config
    try:
        cfg = load_config(None, stage=stage)
    except ColorError as exc:
        sys.stdout.flush()
        return _error(str(exc), EXIT_RENDER)
    sys.stdout.write(f"colour: {cfg.describe()}\n{table}\n")
    return EXIT_OK


def _screen_flow(shot: str, times, res):
    """The shot's screen motion for ``cmlt flicker --shot`` (cmlt.shot.motion; the
    metrics package does not import the shot package); a shot that cannot be read is
    a MetricsError naming it."""
    from .metrics import MetricsError
    from .shot.motion import screen_flow
    from .usd.errors import UsdLoadError
    try:
        return screen_flow(shot, times, res)
    except UsdLoadError as exc:
        raise MetricsError(f"--shot {shot}: {exc}") from None


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of the ``cmlt`` console script; returns the exit code."""
    argv = _husk_argv(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser()         # imports the core (the settings table)
    except CoreSelectError as exc:      # CMLT_CORE_ISA names a build that cannot load
        return _error(str(exc), EXIT_USAGE)
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:                       # point at the subcommand's own help
            sub = getattr(args, "command", None)
            where = f"cmlt {sub}" if sub else "cmlt"
            sys.stderr.write(f"cmlt: error: unrecognized arguments: {' '.join(extra)} "
                             f"(see `{where} --help`)\n")
            return EXIT_USAGE
    except SystemExit as exc:           # --help, --version, usage errors
        return int(exc.code or 0)
    try:
        if getattr(args, "handler", None) is not None:     # subcommands that bring their own
            return args.handler(args)
        if args.command == "render":
            return _cmd_render(args, argv)
        if args.command == "inspect":
            return _cmd_inspect(args)
        if args.command == "contact-sheet":
            return _cmd_contact_sheet(args)
        if args.command in ("flicker", "compare"):
            from .metrics.cli import run as _run_metrics
            return _run_metrics(args, screen_flow=_screen_flow)
    except KeyboardInterrupt:
        return _error("interrupted", EXIT_INTERRUPTED)
    except Exception as exc:            # a bug: still one line unless asked for more
        if os.environ.get("CMLT_DEBUG") or (getattr(args, "verbosity", None) or 0) >= 3:
            raise
        return _error(f"internal error: {type(exc).__name__}: {exc} "
                      "(set CMLT_DEBUG=1 for a traceback)", EXIT_RENDER)
    return _error(f"unknown command {args.command!r}", EXIT_USAGE)
