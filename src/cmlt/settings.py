"""Render settings: defaults, the stage's ``CmltRenderSettingsAPI`` values,
and command-line flags, resolved in that order of increasing precedence.

The stage carries settings on a ``UsdRender.Settings`` prim with the
codeless applied schema ``CmltRenderSettingsAPI`` (``plugins/usd``), as
``cmlt:``-namespaced attributes. One setting has one spelling everywhere
(STYLE.md §3): the schema attribute ``cmlt:largeStepProbability``, the Python
field ``large_step_probability``, the flag ``--large-step-probability``.

========================  ================================  ==============  =====================
field                     stage attribute                   default         valid
========================  ================================  ==============  =====================
integrator                cmlt:integrator                   ``pt``          pt, bdpt, pssmlt, cmlt
spp                       cmlt:spp                          16              >= 1
time_budget               cmlt:timeBudget                   0 (off)         >= 0 seconds
seed                      cmlt:seed                         0               0 .. 2^31-1
max_depth                 cmlt:maxDepth                     64              1 .. 1024
sigma                     cmlt:sigma                        0.01            (0, 1]
tries                     cmlt:tries                        2               1 .. 64
inner_length              cmlt:innerLength                  4               1 .. 1000000
large_step_probability    cmlt:largeStepProbability         0.3             [0, 1]
chains                    cmlt:chains                       1000            >= 1
bootstrap_samples         cmlt:bootstrapSamples             100000          >= 1
inner                     cmlt:inner                        ``bundle``      seed, mtm, bundle
importance                cmlt:importance                   ``pixel``       pixel, luminance
direct_fraction           cmlt:directFraction               0.3             [0, 0.9]
pilot_spp                 cmlt:pilotSpp                     1               1 .. 64
carry_states              cmlt:temporal:carryStates         true
smooth_normalization      cmlt:temporal:smoothNormalization true
seed_per_frame            cmlt:temporal:seedPerFrame        false
resolution                resolution (UsdRender)            640x480         each >= 1
camera                    camera (UsdRender relationship)   none            a prim path
========================  ================================  ==============  =====================

The ``spp`` of the MLT integrators (pssmlt, cmlt) counts mutations per
pixel. ``resolution``: an unauthored ``resolution`` on an existing settings
prim takes the UsdRender fallback, 2048x1080 (as the stage reader does);
640x480 applies only when the stage has no settings prim. Errors
(:class:`SettingsError`) name the prim and attribute, or the flag, and the
allowed values; a ``cmlt:`` attribute the schema does not define (a typo
such as ``cmlt:maxDept``) is an error, never silently ignored.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, fields
from typing import Any, Dict, Iterable, Mapping, Optional, Tuple

__all__ = [
    "SettingsError", "RenderSettings", "SettingField", "FIELDS", "SCHEMA_NAME",
    "resolve_settings", "find_settings_prim", "format_settings", "flag_name",
    "DEFAULT_RESOLUTION",
]

#: the applied API schema holding the cmlt: attributes
SCHEMA_NAME = "CmltRenderSettingsAPI"
#: resolution without any settings prim (the stage reader's default)
DEFAULT_RESOLUTION = (640, 480)
_INT32_MAX = 2 ** 31 - 1


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


class SettingsError(ValueError):
    """A render setting that is unknown, of the wrong type or out of range.
    The message names the prim and attribute, or the flag."""


@dataclass(frozen=True)
class SettingField:
    """One setting: its spellings, type, default and valid range."""

    name: str                       # Python field, snake_case
    attr: Optional[str]             # stage attribute (None: not a cmlt: attribute)
    kind: str                       # "token" | "int" | "float" | "double" | "bool"
    default: Any
    lo: Optional[float] = None      # inclusive lower bound (exclusive if lo_open)
    hi: Optional[float] = None      # inclusive upper bound
    lo_open: bool = False
    tokens: Tuple[str, ...] = ()    # allowed tokens
    doc: str = ""

    @property
    def flag(self) -> str:
        return flag_name(self.name)

    def allowed(self) -> str:
        """The valid values, in words."""
        if self.kind == "token":
            return "one of " + ", ".join(self.tokens)
        if self.kind == "bool":
            return "true or false"
        lo = "" if self.lo is None else f"{'>' if self.lo_open else '>='} {_num(self.lo)}"
        hi = "" if self.hi is None else f"<= {_num(self.hi)}"
        return "a number " + " and ".join(p for p in (lo, hi) if p) if (lo or hi) else "a number"


FIELDS: Tuple[SettingField, ...] = (
    SettingField("integrator", "cmlt:integrator", "token", "pt",
                 tokens=("pt", "bdpt", "pssmlt", "cmlt"),
                 doc="light transport: path tracing, bidirectional, PSSMLT, coherent MLT"),
    SettingField("spp", "cmlt:spp", "int", 16, 1, _INT32_MAX,
                 doc="samples per pixel (pt, bdpt) or mutations per pixel (pssmlt, cmlt)"),
    SettingField("time_budget", "cmlt:timeBudget", "double", 0.0, 0.0, None,
                 doc="wall-clock seconds per frame, 0 = off"),
    SettingField("seed", "cmlt:seed", "int", 0, 0, _INT32_MAX,
                 doc="shot seed; streams keyed by (seed, chain or pixel, dimension)"),
    SettingField("max_depth", "cmlt:maxDepth", "int", 64, 1, 1024,
                 doc="scattering events per path, 1 = direct light only"),
    SettingField("sigma", "cmlt:sigma", "float", 0.01, 0.0, 1.0, lo_open=True,
                 doc="small-step Gaussian perturbation size in primary sample space"),
    SettingField("tries", "cmlt:tries", "int", 2, 1, 64,
                 doc="k, candidates per multiple-try / bundle step"),
    SettingField("inner_length", "cmlt:innerLength", "int", 4, 1, 1_000_000,
                 doc="m, inner-chain steps per outer step"),
    SettingField("large_step_probability", "cmlt:largeStepProbability", "float", 0.3, 0.0, 1.0,
                 doc="probability of an independent (large) step"),
    SettingField("chains", "cmlt:chains", "int", 1000, 1, _INT32_MAX,
                 doc="Markov chains per frame"),
    SettingField("bootstrap_samples", "cmlt:bootstrapSamples", "int", 100_000, 1, _INT32_MAX,
                 doc="large-step samples estimating the normalisation and seeding chains"),
    SettingField("inner", "cmlt:inner", "token", "bundle", tokens=("seed", "mtm", "bundle"),
                 doc="inner-chain rule: seminar 2k splats, multiple-try, multiple-proposal"),
    SettingField("importance", "cmlt:importance", "token", "pixel", tokens=("pixel", "luminance"),
                 doc="Metropolis importance: luminance over the pilot's pixel brightness, or luminance"),
    SettingField("direct_fraction", "cmlt:directFraction", "float", 0.3, 0.0, 0.9,
                 doc="share of MLT path evaluations for the path-traced direct pass (0 = chains render all)"),
    SettingField("pilot_spp", "cmlt:pilotSpp", "int", 1, 1, 64,
                 doc="path-traced samples per pixel of the pixel importance's pilot image"),
    SettingField("carry_states", "cmlt:temporal:carryStates", "bool", True,
                 doc="start each frame's chains from the previous frame's states"),
    SettingField("smooth_normalization", "cmlt:temporal:smoothNormalization", "bool", True,
                 doc="smooth the normalisation over frames while lighting is steady"),
    SettingField("seed_per_frame", "cmlt:temporal:seedPerFrame", "bool", False,
                 doc="fold the frame number into the random streams"),
)
_BY_NAME = {f.name: f for f in FIELDS}
_BY_ATTR = {f.attr: f for f in FIELDS if f.attr}
_EXTRA = ("resolution", "camera")               # UsdRender.Settings' own properties
_FLAGS = {"resolution": "--res"}


def flag_name(name: str) -> str:
    """The command-line flag of a setting: ``max_depth`` -> ``--max-depth``,
    ``resolution`` -> ``--res``."""
    return _FLAGS.get(name, "--" + name.replace("_", "-"))


@dataclass
class RenderSettings:
    """The settings one render runs with. Defaults and ranges: the module
    table (and :data:`FIELDS`); :meth:`validate` checks them."""

    integrator: str = "pt"
    spp: int = 16
    time_budget: float = 0.0
    seed: int = 0
    max_depth: int = 64
    sigma: float = 0.01
    tries: int = 2
    inner_length: int = 4
    large_step_probability: float = 0.3
    chains: int = 1000
    bootstrap_samples: int = 100_000
    inner: str = "bundle"
    importance: str = "pixel"
    direct_fraction: float = 0.3
    pilot_spp: int = 1
    carry_states: bool = True
    smooth_normalization: bool = True
    seed_per_frame: bool = False
    resolution: Tuple[int, int] = DEFAULT_RESOLUTION
    camera: Optional[str] = None

    def validate(self) -> "RenderSettings":
        """Raise :class:`SettingsError` if any field is out of range."""
        for f in FIELDS:
            setattr(self, f.name, _check(f, getattr(self, f.name), f"RenderSettings.{f.name}"))
        self.resolution = _check_resolution(self.resolution, "RenderSettings.resolution")
        return self

    def as_dict(self) -> Dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


# -- checking one value ------------------------------------------------------------

def _check(f: SettingField, value: Any, where: str) -> Any:
    """Coerce ``value`` to the field's type and check its range; ``where``
    (``"/Render/settings: cmlt:spp"`` or ``"flag --spp"``) starts the error."""
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
    if kind == "int":
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
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise SettingsError(f"{where} = {value!r} must be {f.allowed()}") from None
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


def _is_int(value) -> bool:
    try:
        import numpy as np
        if isinstance(value, np.integer):
            return True
    except ImportError:                                  # pragma: no cover
        pass
    return isinstance(value, int)


def _check_resolution(value: Any, where: str) -> Tuple[int, int]:
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
    if w < 1 or h < 1:
        raise SettingsError(f"{where} = {w}x{h}: width and height must be >= 1")
    return (w, h)


# -- the stage -----------------------------------------------------------------------

def find_settings_prim(stage, settings_prim_path: Optional[str] = None):
    """The ``UsdRender.Settings`` prim to read, or ``None``.

    ``settings_prim_path`` must name a RenderSettings prim (else
    :class:`SettingsError`); otherwise the stage's ``renderSettingsPrimPath``
    metadata, else the first RenderSettings prim in traversal order (the
    stage reader's rule).
    """
    from pxr import Sdf, UsdRender

    if stage is None:
        if settings_prim_path:
            raise SettingsError(f"render settings {settings_prim_path}: no stage")
        return None
    if settings_prim_path:
        path = str(settings_prim_path)
        prim = stage.GetPrimAtPath(path) if Sdf.Path.IsValidPathString(path) and \
            Sdf.Path(path).IsAbsolutePath() else None
        if not prim:
            raise SettingsError(f"render settings {path} does not exist in "
                                f"{stage.GetRootLayer().identifier}")
        if not prim.IsA(UsdRender.Settings):
            raise SettingsError(f"render settings {path} is a {prim.GetTypeName() or 'typeless'}"
                                f" prim, not RenderSettings")
        return prim
    meta = stage.GetMetadata("renderSettingsPrimPath") if stage.HasAuthoredMetadata(
        "renderSettingsPrimPath") else ""
    if meta:
        return find_settings_prim(stage, meta)
    for prim in stage.Traverse():
        if prim.IsA(UsdRender.Settings):
            return prim
    return None


def _authored_cmlt_properties(prim) -> Iterable:
    for prop in prim.GetAuthoredProperties():
        if prop.GetName().startswith("cmlt:"):
            yield prop


def _unknown_attribute(prim, prop) -> SettingsError:
    name = prop.GetName()
    close = difflib.get_close_matches(name, list(_BY_ATTR), n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else ""
    return SettingsError(f"{prim.GetPath()}: {name} is not a {SCHEMA_NAME} attribute{hint} "
                         f"(known: {', '.join(sorted(_BY_ATTR))})")


def _stage_value(f: SettingField, attr, prim, time) -> Any:
    where = f"{prim.GetPath()}: {f.attr}"
    value = attr.Get(time)
    if value is None:
        raise SettingsError(f"{where} is authored without a value")
    # the authored type must be the schema's: a float cmlt:spp must not be truncated
    type_name = str(attr.GetTypeName())
    expected = {"token": ("token", "string"), "int": ("int",), "float": ("float", "double", "half"),
                "double": ("double", "float", "half"), "bool": ("bool",)}[f.kind]
    if type_name not in expected:
        raise SettingsError(f"{where} is authored as {type_name}, but the schema declares "
                            f"{f.kind}; must be {f.allowed()}")
    return _check(f, value, where)


def resolve_settings(stage=None, settings_prim_path: Optional[str] = None,
                     cli_overrides: Optional[Mapping[str, Any]] = None, *,
                     time=None) -> Tuple[RenderSettings, Dict[str, str]]:
    """Settings in force and where each came from.

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
    values: Dict[str, Any] = {f.name: getattr(RenderSettings, f.name)
                              for f in fields(RenderSettings)}
    sources: Dict[str, str] = {name: "default" for name in values}

    prim = find_settings_prim(stage, settings_prim_path)
    if prim is not None:
        from pxr import Usd, UsdRender

        tc = Usd.TimeCode.EarliestTime() if time is None else Usd.TimeCode(time)
        label = f"stage:{prim.GetPath()}"
        for prop in _authored_cmlt_properties(prim):
            f = _BY_ATTR.get(prop.GetName())
            if f is None or not isinstance(prop, Usd.Attribute):
                raise _unknown_attribute(prim, prop)
            if prop.HasAuthoredValue():
                values[f.name] = _stage_value(f, prop, prim, tc)
                sources[f.name] = label
        rs = UsdRender.Settings(prim)
        res_attr = rs.GetResolutionAttr()
        res = res_attr.Get(tc)
        if res is not None:
            values["resolution"] = _check_resolution(res, f"{prim.GetPath()}: resolution")
            sources["resolution"] = label if res_attr.HasAuthoredValue() else \
                f"{label} (UsdRender fallback)"
        targets = rs.GetCameraRel().GetForwardedTargets()
        if targets:
            values["camera"] = str(targets[0])
            sources["camera"] = label

    for key, value in (cli_overrides or {}).items():
        if value is None:
            continue
        if key in _BY_NAME:
            values[key] = _check(_BY_NAME[key], value, f"flag {flag_name(key)}")
        elif key == "resolution":
            values[key] = _check_resolution(value, f"flag {flag_name(key)}")
        elif key == "camera":
            values[key] = str(value)
        else:
            close = difflib.get_close_matches(key, list(_BY_NAME) + list(_EXTRA), n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise SettingsError(f"unknown setting {key!r} (flag {flag_name(key)}){hint}")
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


def format_settings(settings: RenderSettings, sources: Optional[Mapping[str, str]] = None) -> str:
    """The settings in force and where each came from, one per line, for
    ``cmlt inspect``."""
    sources = sources or {}
    rows = []
    for f in fields(settings):
        attr = _BY_NAME[f.name].attr if f.name in _BY_NAME else f.name
        rows.append((f.name, _show(getattr(settings, f.name)), attr,
                     sources.get(f.name, "default")))
    w = [max(len(r[i]) for r in rows) for i in range(3)]
    lines = ["settings in force:",
             f"  {'setting':<{w[0]}}  {'value':<{w[1]}}  {'stage attribute':<{w[2]}}  source"]
    lines += [f"  {n:<{w[0]}}  {v:<{w[1]}}  {a:<{w[2]}}  {s}" for n, v, a, s in rows]
    return "\n".join(lines)
