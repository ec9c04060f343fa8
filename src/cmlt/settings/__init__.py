"""Render settings: defaults, the stage's ``CmltRenderSettingsAPI`` values,
and command-line flags, resolved in that order of increasing precedence.

Every setting is one row of the settings table in the core
(``src/core/integrators/common/render_settings.h``; here :data:`TABLE`, from
``cmlt._core.settings_table()``): its name, type, default, range, stage
attribute, flag and doc. From it come the core's ``RenderSettings`` and its
validation, the bindings, the flags of ``cmlt render``
(:mod:`cmlt.settings.flags`), :class:`RenderSettings` here, the checks of the
stage's values and of :class:`cmlt.shot.RenderOptions`, and the USD schema
(:mod:`cmlt.settings.usd_schema`). One setting has one spelling everywhere
(STYLE.md §3): the schema attribute ``cmlt:largeStepProbability``, the Python
and C++ field ``large_step_probability``, the flag ``--large-step-probability``.

The stage carries settings on a ``UsdRender.Settings`` prim with the codeless
applied schema ``CmltRenderSettingsAPI`` (``plugins/usd``), as
``cmlt:``-namespaced attributes; a ``cmlt:`` attribute the schema does not
define (a typo such as ``cmlt:maxDept``) is an error, never silently ignored.
``resolution`` and ``camera`` are the settings prim's own UsdRender
properties: an unauthored ``resolution`` on an existing settings prim takes
the UsdRender fallback, 2048x1080 (as the stage reader does); the core's
default, 640x480, applies only when the stage has no settings prim. Errors
(:class:`SettingsError`) name the prim and attribute, or the flag, and the
allowed values.
"""
from .resolve import (RenderSettings, check_overrides, check_resolution, find_settings_prim,
                      format_settings, resolve_settings)
from .table import (BY_NAME, DEFAULT_RESOLUTION, FIELDS, MACHINE_FIELDS, SCHEMA_NAME, TABLE,
                    SettingField, SettingsError, check_value, flag_name)

__all__ = [
    "SettingsError", "RenderSettings", "SettingField", "TABLE", "BY_NAME", "FIELDS",
    "MACHINE_FIELDS", "SCHEMA_NAME", "DEFAULT_RESOLUTION", "resolve_settings",
    "find_settings_prim", "format_settings", "flag_name", "check_value", "check_overrides",
    "check_resolution",
]
