"""The settings in force: defaults < the stage's ``CmltRenderSettingsAPI``
values < flags, and where each came from."""
from __future__ import annotations

import difflib
from dataclasses import field, fields, make_dataclass
from typing import Any, Dict, Iterable, Mapping, Optional, Tuple

from .table import (BY_ATTR, BY_NAME, DEFAULT_RESOLUTION, FIELDS, RESOLUTION_RANGE,
                    SCHEMA_NAME, SettingField, SettingsError, check_value, flag_name)

__all__ = ["RenderSettings", "resolve_settings", "find_settings_prim", "format_settings",
           "check_resolution"]

_PY_TYPES = {"token": str, "int": int, "uint64": int, "double": float, "bool": bool}


class _RenderSettingsBase:
    """Methods of :class:`RenderSettings` (its fields come from the table)."""

    def validate(self) -> "RenderSettings":
        """Raise :class:`SettingsError` if any field is out of range."""
        for f in FIELDS:
            setattr(self, f.name, check_value(f, getattr(self, f.name),
                                              f"RenderSettings.{f.name}"))
        self.resolution = check_resolution(self.resolution, "RenderSettings.resolution")
        return self

    def as_dict(self) -> Dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


#: The settings one render runs with: every stage setting of the table (same name,
#: default), then ``resolution`` (w, h) and ``camera`` (a prim path or None), the
#: UsdRender.Settings prim's own.
RenderSettings = make_dataclass(
    "RenderSettings",
    [(f.name, _PY_TYPES[f.kind], field(default=f.default)) for f in FIELDS]
    + [("resolution", Tuple[int, int], field(default=DEFAULT_RESOLUTION)),
       ("camera", Optional[str], field(default=None))],
    bases=(_RenderSettingsBase,),
    namespace={"__module__": __name__,
               "__doc__": "The settings one render runs with: the stage settings of the "
                          "table (cmlt.settings.FIELDS), resolution and camera."})


def check_resolution(value: Any, where: str) -> Tuple[int, int]:
    """``(w, h)``, ``"WxH"`` -> ``(w, h)`` with each in the table's width/height range."""
    if isinstance(value, str):
        parts = value.lower().split("x")
        try:
            value = tuple(int(p) for p in parts)
        except ValueError:
            value = None
    try:
        w, h = (int(v) for v in value)
    except (TypeError, ValueError):
        raise SettingsError(f"{where} = {value!r} must be WIDTHxHEIGHT") from None
    lo, hi = RESOLUTION_RANGE
    if w < lo or h < lo:
        raise SettingsError(f"{where} = {w}x{h}: width and height must be >= {lo}")
    if w > hi or h > hi:
        raise SettingsError(f"{where} = {w}x{h}: width and height must be <= {hi}")
    return (w, h)


# -- the stage -----------------------------------------------------------------------

def find_settings_prim(stage, settings_prim_path: Optional[str] = None):
    """The ``UsdRender.Settings`` prim to read, or ``None``
    (:func:`cmlt.usd.render_settings.find_settings_prim`); a path that names
    no RenderSettings prim is a :class:`SettingsError`."""
    if stage is None and not settings_prim_path:
        return None
    from ..usd.errors import UsdLoadError
    from ..usd.render_settings import find_settings_prim as find
    try:
        return find(stage, settings_prim_path)
    except UsdLoadError as exc:
        raise SettingsError(str(exc)) from None


def _authored_cmlt_properties(prim) -> Iterable:
    for prop in prim.GetAuthoredProperties():
        if prop.GetName().startswith("cmlt:"):
            yield prop


def _unknown_attribute(prim, prop) -> SettingsError:
    name = prop.GetName()
    close = difflib.get_close_matches(name, list(BY_ATTR), n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else ""
    return SettingsError(f"{prim.GetPath()}: {name} is not a {SCHEMA_NAME} attribute{hint} "
                         f"(known: {', '.join(sorted(BY_ATTR))})")


#: authored value types a setting of each kind accepts (an int seed is a uint64 one)
_AUTHORED_TYPES = {"token": ("token", "string"), "int": ("int",),
                   "uint64": ("uint64", "int", "int64", "uint"),
                   "double": ("double", "float", "half"), "bool": ("bool",)}


def _stage_value(f: SettingField, attr, prim, time) -> Any:
    where = f"{prim.GetPath()}: {f.attr}"
    value = attr.Get(time)
    if value is None:
        raise SettingsError(f"{where} is authored without a value")
    # the authored type must be the schema's: a float cmlt:spp must not be truncated
    type_name = str(attr.GetTypeName())
    if type_name not in _AUTHORED_TYPES[f.kind]:
        raise SettingsError(f"{where} is authored as {type_name}, but the schema declares "
                            f"{f.kind}; must be {f.allowed()}")
    return check_value(f, value, where)


def _read_stage(prim, time, values: Dict[str, Any], sources: Dict[str, str]) -> None:
    from pxr import Usd

    from ..usd.render_settings import settings_camera, settings_resolution

    tc = Usd.TimeCode.EarliestTime() if time is None else Usd.TimeCode(time)
    label = f"stage:{prim.GetPath()}"
    for prop in _authored_cmlt_properties(prim):
        f = BY_ATTR.get(prop.GetName())
        if f is None or not isinstance(prop, Usd.Attribute):
            raise _unknown_attribute(prim, prop)
        if prop.HasAuthoredValue():
            values[f.name] = _stage_value(f, prop, prim, tc)
            sources[f.name] = label
    res, authored = settings_resolution(prim, tc)
    if res is not None:
        values["resolution"] = check_resolution(res, f"{prim.GetPath()}: resolution")
        sources["resolution"] = label if authored else f"{label} (UsdRender fallback)"
    camera = settings_camera(prim)
    if camera is not None:
        values["camera"] = str(camera)
        sources["camera"] = label


def check_overrides(overrides: Mapping[str, Any]) -> Dict[str, Any]:
    """Flag values by setting name (``None``: not given) checked against the
    table; returns the given ones, coerced. Errors start ``flag --name``."""
    out: Dict[str, Any] = {}
    for key, value in overrides.items():
        if value is None:
            continue
        if key in BY_NAME:
            out[key] = check_value(BY_NAME[key], value, f"flag {flag_name(key)}")
        elif key == "resolution":
            out[key] = check_resolution(value, f"flag {flag_name(key)}")
        elif key == "camera":
            out[key] = str(value)
        else:
            close = difflib.get_close_matches(key, list(BY_NAME) + ["resolution", "camera"], n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise SettingsError(f"unknown setting {key!r} (flag {flag_name(key)}){hint}")
    return out


def resolve_settings(stage=None, settings_prim_path: Optional[str] = None,
                     cli_overrides: Optional[Mapping[str, Any]] = None, *,
                     time=None) -> Tuple[Any, Dict[str, str]]:
    """Settings in force (a :class:`RenderSettings`) and where each came from.

    Precedence: ``cli_overrides`` (flag values by field name, e.g.
    ``{"spp": 64, "max_depth": None}``; ``None`` means "flag not given")
    over the stage's settings prim over the defaults. ``sources`` maps every
    field to ``"default"``, ``"stage:/Render/settings"`` or ``"flag --spp"``
    (an unauthored resolution on a settings prim is
    ``"stage:/Render/settings (UsdRender fallback)"``). ``time``: the time
    code to read at (default: the earliest, settings being uniform).
    Raises :class:`SettingsError` for unknown fields or ``cmlt:``
    attributes, values of the wrong type, out of range, or tokens outside
    the allowed set.
    """
    values: Dict[str, Any] = {f.name: f.default for f in fields(RenderSettings)}
    sources: Dict[str, str] = {name: "default" for name in values}
    prim = find_settings_prim(stage, settings_prim_path)
    if prim is not None:
        _read_stage(prim, time, values, sources)
    for key, value in check_overrides(cli_overrides or {}).items():
        values[key] = value
        sources[key] = f"flag {flag_name(key)}"
    return RenderSettings(**values), sources


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.7g}"
    if isinstance(value, tuple) and len(value) == 2:
        return f"{value[0]}x{value[1]}"
    return "(none)" if value is None else str(value)


def format_settings(settings, sources: Optional[Mapping[str, str]] = None) -> str:
    """The settings in force and where each came from, one per line, for
    ``cmlt inspect``."""
    sources = sources or {}
    rows = []
    for f in fields(settings):
        attr = BY_NAME[f.name].attr if f.name in BY_NAME else f.name
        rows.append((f.name, _show(getattr(settings, f.name)), attr,
                     sources.get(f.name, "default")))
    w = [max(len(r[i]) for r in rows) for i in range(3)]
    lines = ["settings in force:",
             f"  {'setting':<{w[0]}}  {'value':<{w[1]}}  {'stage attribute':<{w[2]}}  source"]
    lines += [f"  {n:<{w[0]}}  {v:<{w[1]}}  {a:<{w[2]}}  {s}" for n, v, a, s in rows]
    return "\n".join(lines)
