"""The ``cmlt render`` flags of the settings, built from the settings table.

A flag converts its text to the setting's type only (``'x' is not an integer``
is a usage error right away); the range is checked, like the stage's values,
by :func:`cmlt.settings.check_value` (through :meth:`RenderOptions.check
<cmlt.shot.RenderOptions.check>`), so that every layer states the same range
in the same words. A bool setting's flag sets the opposite of its default
(``--no-packets``, ``--independent-frames``); a stage setting's flag that is
not given leaves the stage's value (``None``).
"""
from __future__ import annotations

import argparse
from typing import Iterable

from .table import FIELDS, MACHINE_FIELDS, SettingField

__all__ = ["add_setting_flags", "SEQUENCE_GROUP"]

#: the help group of the settings read by the sequence loop (cmlt:temporal:*)
SEQUENCE_GROUP = "sequences (DESIGN.md §4)"


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


_TYPES = {"int": _integer, "uint64": _integer, "double": _number, "token": str}


def _show(f: SettingField) -> str:
    if f.kind == "bool":
        return "on" if f.default else "off"
    return str(f.default)


def _help(f: SettingField) -> str:
    text = f.doc
    if f.kind == "bool":
        text = f"turn {'off' if f.default else 'on'}: {text}"
    if f.attr:
        return f"{text}; default: the stage's {f.attr} if authored, else {_show(f)}"
    return f"{text} (default {_show(f)})"


def _add(parser, f: SettingField) -> None:
    names = [f.flag, *f.aliases]
    # argparse's % formatting: a literal percent sign must be doubled
    help_text = _help(f).replace("%", "%%")
    if f.kind == "bool":
        parser.add_argument(*names, dest=f.name, action="store_const", const=not f.default,
                            default=None if f.attr else f.default, help=help_text)
        return
    metavar = f.metavar or ("{" + ",".join(f.tokens) + "}" if f.tokens else None)
    parser.add_argument(*names, dest=f.name, type=_TYPES[f.kind], metavar=metavar,
                        default=None if f.attr else f.default, help=help_text)


def add_setting_flags(parser: argparse.ArgumentParser, sequence_group=None) -> None:
    """Add a flag for every setting of the table that has one: the stage
    settings (default ``None``: not given), then the machine's (threads,
    packets; default the table's). Settings of the sequence loop
    (``cmlt:temporal:*``) go to ``sequence_group`` if given."""
    for f in _flagged(FIELDS):
        target = sequence_group if (sequence_group is not None and
                                    f.attr.startswith("cmlt:temporal:")) else parser
        _add(target, f)
    for f in _flagged(MACHINE_FIELDS):
        _add(parser, f)


def _flagged(rows: Iterable[SettingField]):
    return [f for f in rows if f.flag]
