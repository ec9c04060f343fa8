"""The image commands of the ``cmlt`` command line: ``inspect --image`` (an EXR's header)
and ``contact-sheet``."""

from __future__ import annotations

import os
import sys

from .cli_args import EXIT_OK, EXIT_RENDER, EXIT_USAGE, _error


def _cmd_inspect_image(path: str) -> int:
    from .io.exr import format_header, read_header

    if not os.path.isfile(path):
        return _error(f"--image {path}: no such file", EXIT_USAGE)
    try:
        header = read_header(path)
    except OSError as exc:
        why = str(exc)
        why = why[len(path) + 2:] if why.startswith(path + ": ") else why
        return _error(f"--image {path}: {why}", EXIT_RENDER)
    sys.stdout.write(format_header(header))
    return EXIT_OK


def _cmd_contact_sheet(args) -> int:
    from .color import ColorError, load_config
    from .io.contact_sheet import contact_sheet

    patterns = args.pattern
    source = patterns[0] if len(patterns) == 1 else patterns
    try:
        cfg = load_config(args.ocio_config)
    except ColorError as exc:
        return _error(f"--ocio-config {args.ocio_config}: {exc}" if args.ocio_config
                      else str(exc), EXIT_USAGE)
    try:
        cfg.check_display_view(args.display, args.view)
    except ColorError as exc:
        flag = "--display" if str(exc).startswith("unknown display") else "--view"
        return _error(f"{flag}: {exc}", EXIT_USAGE)
    try:
        out = contact_sheet(source, args.out, columns=args.columns, display=args.display,
                            view=args.view, thumb_width=args.thumb_width, config=cfg)
    except FileNotFoundError as exc:
        return _error(str(exc), EXIT_USAGE)
    except ValueError as exc:
        return _error(f"--out {args.out}: {exc}" if "extension" in str(exc) else str(exc),
                      EXIT_USAGE)
    except OSError as exc:
        return _error(str(exc), EXIT_RENDER)
    sys.stderr.write(f"cmlt: contact sheet -> {out}\n")
    return EXIT_OK
