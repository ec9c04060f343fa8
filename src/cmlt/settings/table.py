"""The settings table, read from the core, and the one check of a value.

The table is written once, in C++ (``src/core/integrators/common/render_settings.h``):
each setting's name, type, default, range, stage attribute, flag and doc. The core
builds ``RenderSettings`` and its ``validate()`` from it and exports it as
``cmlt._core.settings_table()``; this module turns the rows into
:class:`SettingField` and checks values against them (:func:`check_value`), for
the stage, the flags and :class:`cmlt.shot.RenderOptions` alike.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

__all__ = ["SettingsError", "SettingField", "TABLE", "BY_NAME", "FIELDS", "BY_ATTR",
           "MACHINE_FIELDS", "SCHEMA_NAME", "DEFAULT_RESOLUTION", "RESOLUTION_RANGE",
           "check_value", "flag_name"]

#: the applied API schema holding the cmlt: attributes
SCHEMA_NAME = "CmltRenderSettingsAPI"


class SettingsError(ValueError):
    """A render setting that is unknown, of the wrong type or out of range.
    The message names the prim and attribute, or the flag."""


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


@dataclass(frozen=True)
class SettingField:
    """One row of the settings table."""

    name: str                       # Python keyword and C++ field, snake_case
    attr: Optional[str]             # stage attribute (None: not a stage setting)
    kind: str                       # the USD value type: token, int, uint64, double, bool
    default: Any
    lo: Optional[float] = None      # inclusive lower bound (exclusive if lo_open)
    hi: Optional[float] = None      # inclusive upper bound (None: unbounded)
    lo_open: bool = False
    tokens: Tuple[str, ...] = ()    # allowed tokens
    doc: str = ""
    flag: Optional[str] = None      # the `cmlt render` flag (None: none)
    aliases: Tuple[str, ...] = ()   # other spellings of the flag
    metavar: Optional[str] = None
    core: bool = True               # a field of the core's RenderSettings

    def allowed(self) -> str:
        """The valid values, in words."""
        if self.kind == "token":
            return "one of " + ", ".join(self.tokens)
        if self.kind == "bool":
            return "true or false"
        lo = "" if self.lo is None else f"{'>' if self.lo_open else '>='} {_num(self.lo)}"
        hi = "" if self.hi is None else f"<= {_num(self.hi)}"
        return "a number " + " and ".join(p for p in (lo, hi) if p) if (lo or hi) else "a number"


def _field(row: Dict[str, Any]) -> SettingField:
    flag, aliases, metavar = None, (), None
    if row["flag"]:
        spellings, _, metavar = row["flag"].partition(" ")
        flag, *rest = spellings.split("|")
        aliases, metavar = tuple(rest), (metavar or None)
    return SettingField(name=row["name"], attr=row["attribute"], kind=row["kind"],
                        default=row["default"], lo=row["min"], hi=row["max"],
                        lo_open=bool(row["min_open"]), tokens=tuple(row["tokens"]),
                        doc=row["doc"], flag=flag, aliases=aliases, metavar=metavar,
                        core=bool(row["core"]))


def _load() -> Tuple[SettingField, ...]:
    from .. import _core
    return tuple(_field(row) for row in _core.settings_table())


#: every row, in the table's order
TABLE: Tuple[SettingField, ...] = _load()
BY_NAME: Dict[str, SettingField] = {f.name: f for f in TABLE}
#: the stage settings (a CmltRenderSettingsAPI attribute each), in the table's order
FIELDS: Tuple[SettingField, ...] = tuple(f for f in TABLE if f.attr)
BY_ATTR: Dict[str, SettingField] = {f.attr: f for f in FIELDS}
#: settings of the machine, not the shot: a flag but no stage attribute (threads,
#: packets); they never change the estimator (threads not even the image)
MACHINE_FIELDS: Tuple[SettingField, ...] = tuple(f for f in TABLE if f.flag and not f.attr)
#: the core's default image size: the resolution without any settings prim
DEFAULT_RESOLUTION: Tuple[int, int] = (BY_NAME["width"].default, BY_NAME["height"].default)
#: width and height each lie in [lo, hi]
RESOLUTION_RANGE: Tuple[int, int] = (BY_NAME["width"].lo, BY_NAME["width"].hi)

#: UsdRender.Settings' own properties that act as settings, and their flags
_EXTRA_FLAGS = {"resolution": "--res", "camera": "--camera"}


def flag_name(name: str) -> str:
    """The command-line flag of a setting: ``max_depth`` -> ``--max-depth``,
    ``resolution`` -> ``--res``; a name that is no setting gets the flag it
    would have."""
    f = BY_NAME.get(name)
    if f is not None and f.flag:
        return f.flag
    return _EXTRA_FLAGS.get(name, "--" + name.replace("_", "-"))


def _is_int(value) -> bool:
    try:
        import numpy as np
        if isinstance(value, np.integer):
            return True
    except ImportError:                                  # pragma: no cover
        pass
    return isinstance(value, int)


def check_value(f: SettingField, value: Any, where: str) -> Any:
    """``value`` coerced to the setting's type and checked against its range;
    ``where`` (``"/Render/settings: cmlt:spp"``, ``"flag --spp"``, ``"--spp"``)
    starts the :class:`SettingsError`. Strings are parsed (a flag's text)."""
    kind = f.kind
    if kind == "token":
        if not isinstance(value, str) or value not in f.tokens:
            raise SettingsError(f"{where} = {value!r} is not an allowed value; "
                                f"allowed: {', '.join(f.tokens)}")
        return str(value)
    if kind == "bool":
        if isinstance(value, str) and value.lower() in ("true", "false", "1", "0", "on", "off"):
            return value.lower() in ("true", "1", "on")
        if not isinstance(value, bool):
            raise SettingsError(f"{where} = {value!r} must be true or false")
        return value
    if isinstance(value, bool):
        raise SettingsError(f"{where} = {value!r} must be {f.allowed()}")
    if kind in ("int", "uint64"):
        if isinstance(value, str):
            try:
                value = int(value)
            except ValueError:
                raise SettingsError(f"{where} = {value!r} must be an integer, "
                                    f"{f.allowed()}") from None
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not _is_int(value):
            raise SettingsError(f"{where} = {value!r} must be an integer, {f.allowed()}")
        value = int(value)
    else:
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise SettingsError(f"{where} = {value!r} must be {f.allowed()}") from None
        if not math.isfinite(value):
            raise SettingsError(f"{where} = {value!r} must be finite, {f.allowed()}")
    low_bad = f.lo is not None and (value <= f.lo if f.lo_open else value < f.lo)
    high_bad = f.hi is not None and value > f.hi
    if low_bad or high_bad:
        raise SettingsError(f"{where} = {value!r} is out of range; must be {f.allowed()}")
    return value
