"""The settings table is the one source of every setting: the core's
RenderSettings (fields, defaults, validation), the USD schema files and what USD
reads from them, the flags of ``cmlt render``, RenderOptions, the Python
RenderSettings and the temporal driver's list of chain settings all say what
the table says. Each test fails when one of them drifts from it."""
from __future__ import annotations

import inspect
import math
import os

import pytest

import cmlt  # noqa: F401  (registers plugins/usd before pxr.Usd is used)
import cmlt._core as core
from cmlt.cli import build_parser, main
from cmlt.settings import (BY_NAME, FIELDS, MACHINE_FIELDS, SCHEMA_NAME, TABLE, RenderSettings,
                           SettingsError, check_value, resolve_settings)
from cmlt.settings import usd_schema
from cmlt.shot import RenderOptions
from cmlt.shot.options import SETTING_NAMES

from pxr import Sdf, Usd  # noqa: E402

#: RenderSettings properties that are inputs handed over per frame (by the temporal
#: driver; the part of a frame a Dask task renders), not settings
CORE_INPUTS = {"mlt_initial_states", "pilot", "mlt_bootstrap_f", "film_offset_x", "pixel_keys",
               "film_offset_y", "partial", "part_row_begin", "part_row_end",
               "part_chain_begin", "part_chain_end"}


def _render_parser():
    return build_parser()._subparsers._group_actions[0].choices["render"]


# -- 1. the core -------------------------------------------------------------------------

def test01_core_fields_and_defaults_are_the_tables():
    st = core.RenderSettings()
    props = {n for n in dir(core.RenderSettings) if not n.startswith("_")
             and isinstance(inspect.getattr_static(core.RenderSettings, n), property)}
    assert props - CORE_INPUTS == {f.name for f in TABLE if f.core}
    for f in TABLE:
        if f.core:
            assert getattr(st, f.name) == f.default, f.name
            assert type(getattr(st, f.name)) is type(f.default), f.name
    st.validate()                            # the defaults lie inside the stated ranges


def _inside_and_outside(f):
    """(values the range accepts, values it refuses) at its ends."""
    if f.kind == "token":
        return list(f.tokens), [f.tokens[0] + "x", ""]
    if f.kind == "bool":
        return [True, False], []
    if f.kind == "uint64":
        return [0, 2 ** 64 - 1], []          # the full type: nothing to refuse
    step = 1 if f.kind == "int" else max(1e-9, abs(f.lo) * 1e-9)
    good = [f.hi] if f.hi is not None else [f.lo + 10 * step]
    bad = [f.lo - step] + ([f.hi + step] if f.hi is not None and f.hi < 2 ** 31 - 1 else [])
    if f.lo_open:
        bad.append(f.lo)
    else:
        good.append(f.lo)
    if f.kind == "double":
        bad += [math.inf, math.nan]
    return good, bad


@pytest.mark.parametrize("name", [f.name for f in TABLE if f.core])
def test02_core_validation_and_the_python_check_agree_at_the_ends_of_each_range(name):
    f = BY_NAME[name]
    good, bad = _inside_and_outside(f)
    for value in good:
        st = core.RenderSettings()
        setattr(st, name, value)
        st.validate()
        assert check_value(f, value, name) == value
    for value in bad:
        st = core.RenderSettings()
        setattr(st, name, value)
        with pytest.raises(core.SettingsError, match=rf"^RenderSettings\.{name}:"):
            st.validate()
        with pytest.raises(SettingsError, match=rf"^{name} = "):
            check_value(f, value, name)


def test03_bindings_document_the_tables_range_and_default():
    for f in TABLE:
        if not f.core:
            continue
        doc = inspect.getattr_static(core.RenderSettings, f.name).__doc__
        assert doc.startswith(f.doc), f.name
        shown = (f"'{f.default}'" if f.kind == "token" else
                 f"{f.default:g}" if f.kind == "double" else str(f.default))
        assert f"(default {shown})" in doc, (f.name, doc)


# -- 2. the USD schema ----------------------------------------------------------------------

def test04_schema_files_are_what_the_table_writes():
    stale = usd_schema.stale_files()
    assert not stale, f"{stale}: run python -m cmlt.settings.usd_schema --write"


def test05_usd_reads_the_tables_types_fallbacks_tokens_and_docs():
    prim_def = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(SCHEMA_NAME)
    assert set(prim_def.GetPropertyNames()) == {f.attr for f in FIELDS}
    for f in FIELDS:
        attr_def = prim_def.GetAttributeDefinition(f.attr)
        assert str(attr_def.GetTypeName()) == f.kind, f.attr
        assert attr_def.GetVariability() == Sdf.VariabilityUniform, f.attr
        assert attr_def.GetFallbackValue() == f.default, f.attr
        assert list(prim_def.GetPropertyMetadata(f.attr, "allowedTokens") or []) == \
            list(f.tokens), f.attr
        assert attr_def.GetDocumentation().startswith(f.doc), f.attr
        assert usd_schema.range_words(f) in attr_def.GetDocumentation(), f.attr


# -- 3. the flags, RenderOptions, the Python settings ----------------------------------------

def test06_every_flag_of_the_table_and_no_other_setting_flag():
    actions = {a.dest: a for a in _render_parser()._actions}
    for f in FIELDS + MACHINE_FIELDS:
        if not f.flag:
            continue
        a = actions[f.name]
        assert a.option_strings == [f.flag, *f.aliases], f.name
        assert a.default == (None if f.attr else f.default), f.name
        if f.kind == "bool":
            assert a.const == (not f.default), f.name
        else:
            assert a.help.startswith(f.doc), f.name
    # a flag whose dest is a setting name must come from the table
    table_names = {f.name for f in TABLE}
    for dest in actions:
        if dest in table_names:
            assert BY_NAME[dest].flag, dest


def test07_render_options_and_python_settings_have_the_tables_fields():
    names = {f.name for f in FIELDS}
    opts = RenderOptions()
    assert set(SETTING_NAMES) == names | {f.name for f in MACHINE_FIELDS}
    for f in FIELDS:
        assert getattr(opts, f.name) is None, f.name            # not given
    for f in MACHINE_FIELDS:
        assert getattr(opts, f.name) == f.default, f.name
    settings = RenderSettings()
    assert list(settings.as_dict()) == [f.name for f in FIELDS] + ["resolution", "camera"]
    assert all(getattr(settings, f.name) == f.default for f in FIELDS)
    assert settings.resolution == (BY_NAME["width"].default, BY_NAME["height"].default)


def test08_chain_settings_of_the_temporal_driver_are_the_stage_settings_but_the_seed():
    """A state file is refused when a setting that changes the chains differs
    (temporal/driver.py, CHAIN_SETTINGS); the seed is checked on its own. A new
    stage setting must be added there too, or this fails."""
    from cmlt.temporal.driver import CHAIN_SETTINGS
    assert set(CHAIN_SETTINGS) == {f.name for f in FIELDS} - {"seed"}


# -- 4. the ranges that used to disagree -----------------------------------------------------

@pytest.mark.parametrize("flag,value,words", [
    ("--tries", "65", "--tries = 65 is out of range; must be a number >= 1 and <= 64"),
    ("--pilot-spp", "65", "--pilot-spp = 65 is out of range; must be a number >= 1 and <= 64"),
    ("--max-depth", "1025", "--max-depth = 1025 is out of range"),
    ("--inner-length", "1000001", "--inner-length = 1000001 is out of range"),
    ("--inner", "mcmc", "--inner = 'mcmc' is not an allowed value; allowed: seed, mtm, bundle"),
])
def test09_flags_refuse_what_the_stage_and_the_core_refuse(tiny_shot, tmp_path, capsys,
                                                           flag, value, words):
    out = str(tmp_path / "x.####.exr")
    assert main(["render", tiny_shot, "--out", out, flag, value, "-q"]) == 2
    err = capsys.readouterr().err
    assert words in err, err
    assert not os.listdir(tmp_path) or not any(p.endswith(".exr") for p in os.listdir(tmp_path))


def test10_a_64_bit_seed_from_the_flag_or_the_stage_renders(make_shot, tmp_path):
    from cmlt.io.exr import read_header
    import json
    big = 2 ** 40 + 3
    out = str(tmp_path / "s.exr")
    assert main(["render", make_shot(), "--frames", "1", "--out", out, "--spp", "1",
                 "--res", "8x6", "--seed", str(2 ** 64 - 1), "-q"]) == 0
    assert json.load(open(out + ".json"))["settings"]["seed"] == 2 ** 64 - 1
    shot = make_shot("seed.usda", {"int2 resolution = (32, 24)":
                                   f"int2 resolution = (8, 6)\n            uniform int cmlt:spp = 1"
                                   f"\n            uniform uint64 cmlt:seed = {big}"})
    out2 = str(tmp_path / "t.exr")
    assert main(["render", shot, "--frames", "1", "--out", out2, "-q"]) == 0
    doc = json.load(open(out2 + ".json"))
    assert doc["settings"]["seed"] == big and doc["settings_sources"]["seed"].startswith("stage:")
    assert doc["stats"]["seed"] == big                          # what the core used
    assert int(read_header(out2)["cmlt"]["seed"]) == big       # beyond OIIO's int: as text
    # an int-typed seed (older stages) still reads; a negative one is refused
    settings, _ = resolve_settings(_stage("uniform int cmlt:seed = 5"))
    assert settings.seed == 5
    with pytest.raises(SettingsError, match=r"cmlt:seed = -3 is out of range"):
        resolve_settings(_stage("uniform int cmlt:seed = -3"))


def _stage(line):
    layer = Sdf.Layer.CreateAnonymous(".usda")
    assert layer.ImportFromString('#usda 1.0\ndef RenderSettings "s" (prepend apiSchemas = '
                                  f'["{SCHEMA_NAME}"])\n{{\n    {line}\n}}\n')
    return Usd.Stage.Open(layer)
