"""From the options to the core: the settings in force, the core's
``RenderSettings``, and the core's settings errors named by flag or attribute."""
from __future__ import annotations

from typing import Dict, Tuple

from ..settings import BY_NAME, MACHINE_FIELDS, SettingsError, flag_name, resolve_settings
from .errors import RenderError, UsageError

__all__ = ["resolve", "core_settings", "settings_message", "where", "TIME_BUDGET_SPP_CAP"]

#: the sample budget of a frame rendered to a time budget (a cap it never reaches)
TIME_BUDGET_SPP_CAP = 1 << 24


def resolve(stage, opts):
    """Settings in force (flag > stage > default) and their sources. A bad
    flag value is a UsageError, a bad stage value a RenderError."""
    try:
        return resolve_settings(stage, cli_overrides=opts.overrides())
    except SettingsError as exc:
        msg = str(exc)
        if msg.startswith("flag "):
            raise UsageError(msg[len("flag "):]) from None
        raise RenderError(msg) from None


def _rank(sources: Dict[str, str], name: str) -> int:
    src = str(sources.get(name, "default"))
    return 2 if src.startswith("flag") else (1 if src.startswith("stage") else 0)


def core_settings(core, resolved, opts, sources: Dict[str, str]):
    """``core.RenderSettings`` from the resolved settings and the machine's
    (threads, packets, keep_group_images): every field of the table the core has."""
    st = core.RenderSettings()
    values = dict(resolved.as_dict())
    # A time budget replaces the sample budget unless spp was given with the same or a
    # higher precedence (both flags, or both in the stage): then whichever comes first.
    if float(values.get("time_budget", 0.0) or 0.0) > 0.0 and \
            _rank(sources, "spp") < _rank(sources, "time_budget"):
        values["spp"] = TIME_BUDGET_SPP_CAP
    for f in MACHINE_FIELDS:        # threads, packets, keep_group_images: the machine's
        values[f.name] = type(f.default)(getattr(opts, f.name))
    for name, value in values.items():
        f = BY_NAME.get(name)
        if f is None or not f.core:
            continue
        try:
            setattr(st, name, value)
        except (core.SettingsError, ValueError, TypeError) as exc:
            raise UsageError(f"{where(name, value, sources)}: {exc}") from None
    groups = plain_error_groups(values, sources)
    if groups is not None:
        st.error_groups = groups
    return st


#: pssmlt/cmlt chain groups of a frame that neither stops at a target error nor writes its
#: group images, when error_groups is not given: the estimate then only goes to the
#: sidecar and the header, and each group is a film layer (48 bytes a pixel: 8 groups
#: cost 398 MB at 1920x1080, 4 groups 199 MB); the image does not depend on the count
PLAIN_ERROR_GROUPS = 4


def plain_error_groups(values: Dict, sources: Dict[str, str]):
    """The error_groups a frame uses in place of the default (PLAIN_ERROR_GROUPS), or
    None to keep the resolved value: given by a flag or the stage, a target error, or
    group images kept (--group-images) keep it."""
    if sources.get("error_groups", "default") != "default":
        return None
    if float(values.get("target_error", 0.0) or 0.0) > 0.0 or values.get("keep_group_images"):
        return None
    current = int(values.get("error_groups", 0) or 0)
    return min(current, PLAIN_ERROR_GROUPS) if current >= 3 else None


def where(name: str, value, sources: Dict[str, str]) -> str:
    """``--spp 0`` for a flag, ``/Render/Settings: cmlt:spp = 0`` for the stage."""
    src = sources.get(name, "default")
    shown = repr(value) if isinstance(value, str) else str(value)
    if src.startswith("stage:"):
        f = BY_NAME.get(name)
        attr = f.attr if f is not None and f.attr else name
        return f"{src[len('stage:'):].split(' ')[0]}: {attr} = {shown}"
    return f"{flag_name(name)} {shown}"


def settings_message(msg: str, resolved, sources: Dict[str, str]) -> Tuple[str, bool]:
    """Name the flag or stage attribute in a core SettingsError
    (``RenderSettings.<field>: ...``); returns (message, is_usage_error)."""
    for name, f in BY_NAME.items():
        prefix = f"RenderSettings.{name}:"
        if not (f.core and msg.startswith(prefix)):
            continue
        key = "resolution" if name in ("width", "height") else name
        value = getattr(resolved, key, None)
        if key == "resolution" and value is not None:
            value = f"{value[0]}x{value[1]}"
        usage = not sources.get(key, "").startswith("stage:")
        return f"{where(key, value, sources)}: {msg[len(prefix):].strip()}", usage
    return msg, True
