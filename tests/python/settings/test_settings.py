"""The CmltRenderSettingsAPI schema and render-settings resolution.

USD sees a codeless schema only if its plugin is registered before the
schema registry is first used (shared/NOTES.md). ``import cmlt`` does that,
and conftest imports cmlt before any test touches pxr; test01 also checks it
in a fresh interpreter, where nothing else can have run first.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

import cmlt  # noqa: F401  (registers plugins/usd before pxr.Usd is used)
from cmlt import _plugins
from cmlt.settings import (SCHEMA_NAME, RenderSettings, SettingsError,
                           find_settings_prim, flag_name, format_settings, resolve_settings)

from pxr import Gf, Sdf, Usd, UsdGeom, UsdRender  # noqa: E402
import support

ROOT = str(support.ROOT)


def make_stage(body: str = "", api: bool = True, metadata: bool = True):
    """A stage with /Render/settings holding ``body`` (usda attribute lines)."""
    schemas = f'prepend apiSchemas = ["{SCHEMA_NAME}"]' if api else ""
    meta = 'renderSettingsPrimPath = "/Render/settings"' if metadata else ""
    text = textwrap.dedent('''\
        #usda 1.0
        (
            {meta}
        )
        def Camera "cam" {{}}
        def Scope "Render"
        {{
            def RenderSettings "settings" ({schemas})
            {{
        {body}
            }}
        }}
        ''').format(meta=meta, schemas=schemas, body=textwrap.indent(textwrap.dedent(body), " " * 8))
    layer = Sdf.Layer.CreateAnonymous(".usda")
    assert layer.ImportFromString(text), text
    return Usd.Stage.Open(layer)


# -- 1. the schema -------------------------------------------------------------------

def test01_schema_registers_in_a_fresh_interpreter():
    code = textwrap.dedent(f'''\
        import json, os, sys
        import cmlt
        from pxr import Usd, UsdRender
        reg = Usd.SchemaRegistry()
        stage = Usd.Stage.CreateInMemory()
        prim = UsdRender.Settings.Define(stage, "/Render/settings").GetPrim()
        ok = prim.ApplyAPI("{SCHEMA_NAME}")
        print(json.dumps({{
            "path": os.environ.get("PXR_PLUGINPATH_NAME", ""),
            "found": reg.FindAppliedAPIPrimDefinition("{SCHEMA_NAME}") is not None,
            "applied": bool(ok), "has": prim.HasAPI("{SCHEMA_NAME}"),
            "spp": prim.GetAttribute("cmlt:spp").Get()}}))
        ''')
    env = dict(os.environ)
    env.pop("PXR_PLUGINPATH_NAME", None)
    env["PYTHONPATH"] = os.pathsep.join([os.path.join(ROOT, "src"), env.get("PYTHONPATH", "")])
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["path"].split(os.pathsep)[0] == _plugins.plugin_path()
    assert got == dict(got, found=True, applied=True, has=True, spp=16)


def test02_plugin_path_is_the_source_tree_here():
    path = _plugins.plugin_path()
    assert path == os.path.join(ROOT, "plugins", "usd")
    assert os.path.isfile(os.path.join(path, "plugInfo.json"))
    assert path in os.environ["PXR_PLUGINPATH_NAME"].split(os.pathsep)


def test03_apply_has_and_fallbacks():
    reg = Usd.SchemaRegistry()
    assert reg.FindAppliedAPIPrimDefinition(SCHEMA_NAME) is not None
    assert Usd.SchemaRegistry.GetSchemaKind(SCHEMA_NAME) == Usd.SchemaKind.SingleApplyAPI
    stage = Usd.Stage.CreateInMemory()
    prim = UsdRender.Settings.Define(stage, "/Render/settings").GetPrim()
    assert not prim.HasAPI(SCHEMA_NAME)
    assert prim.ApplyAPI(SCHEMA_NAME)
    assert prim.HasAPI(SCHEMA_NAME)
    assert prim.GetAttribute("cmlt:spp").Get() == 16
    assert prim.GetAttribute("cmlt:integrator").Get() == "auto"
    assert not prim.GetAttribute("cmlt:spp").HasAuthoredValue()
    # only RenderSettings prims take it
    xform = UsdGeom.Xform.Define(stage, "/x").GetPrim()
    assert not xform.CanApplyAPI(SCHEMA_NAME)


# -- 2. resolution order ---------------------------------------------------------------

def test05_defaults_without_stage():
    settings, sources = resolve_settings(None)
    assert settings == RenderSettings()
    assert set(sources.values()) == {"default"}


def test06_stage_value_changes_the_setting_and_a_flag_overrides_it():
    stage = make_stage('''\
        uniform int cmlt:spp = 256
        uniform token cmlt:integrator = "cmlt"
        uniform float cmlt:sigma = 0.05
        uniform bool cmlt:temporal:carryStates = 0
        uniform int2 resolution = (320, 180)
        rel camera = </cam>
        ''')
    settings, sources = resolve_settings(stage)
    assert settings.spp == 256 and sources["spp"] == "stage:/Render/settings"
    assert settings.integrator == "cmlt"
    assert settings.sigma == pytest.approx(0.05)
    assert settings.carry_states is False
    assert settings.resolution == (320, 180)
    assert settings.camera == "/cam" and sources["camera"] == "stage:/Render/settings"
    assert settings.max_depth == 64 and sources["max_depth"] == "default"

    settings, sources = resolve_settings(stage, cli_overrides={
        "spp": 1024, "max_depth": 3, "resolution": "64x32", "seed": None, "integrator": None})
    assert settings.spp == 1024 and sources["spp"] == "flag --spp"
    assert settings.max_depth == 3 and sources["max_depth"] == "flag --max-depth"
    assert settings.resolution == (64, 32) and sources["resolution"] == "flag --res"
    # None = flag not given: the stage value stays
    assert settings.integrator == "cmlt" and sources["integrator"] == "stage:/Render/settings"
    assert settings.seed == 0 and sources["seed"] == "default"


def test07_settings_prim_without_api_and_without_metadata():
    stage = make_stage("uniform int cmlt:chains = 7\n", api=False, metadata=False)
    settings, sources = resolve_settings(stage)
    assert settings.chains == 7
    # unauthored resolution on a settings prim: the UsdRender fallback
    assert settings.resolution == (2048, 1080)
    assert sources["resolution"] == "stage:/Render/settings (UsdRender fallback)"


def test08_explicit_settings_prim_path():
    stage = make_stage("uniform int cmlt:spp = 4\n")
    assert find_settings_prim(stage, "/Render/settings").GetPath() == "/Render/settings"
    with pytest.raises(SettingsError, match="/Render/nope does not exist"):
        resolve_settings(stage, "/Render/nope")
    with pytest.raises(SettingsError, match="/cam is a Camera prim, not RenderSettings"):
        resolve_settings(stage, "/cam")


# -- 3. errors ---------------------------------------------------------------------

def test09_unknown_token_names_prim_attribute_and_allowed_values():
    stage = make_stage('uniform token cmlt:integrator = "foo"\n')
    with pytest.raises(SettingsError) as err:
        resolve_settings(stage)
    msg = str(err.value)
    assert "/Render/settings" in msg and "cmlt:integrator" in msg and "'foo'" in msg
    assert "pt, bdpt, pssmlt, cmlt" in msg
    stage = make_stage('uniform token cmlt:inner = "mcmc"\n')
    with pytest.raises(SettingsError, match=r"cmlt:inner = 'mcmc'.*seed, mtm, bundle"):
        resolve_settings(stage)


def test10_typo_attribute_is_an_error():
    stage = make_stage("uniform int cmlt:maxDept = 3\n")
    with pytest.raises(SettingsError, match=r"/Render/settings: cmlt:maxDept is not a "
                                            r"CmltRenderSettingsAPI attribute; did you mean "
                                            r"cmlt:maxDepth\?"):
        resolve_settings(stage)
    stage = make_stage("rel cmlt:camera = </cam>\n")
    with pytest.raises(SettingsError, match="cmlt:camera"):
        resolve_settings(stage)


@pytest.mark.parametrize("line,pattern", [
    ("uniform int cmlt:spp = 0", r"cmlt:spp = 0 is out of range; must be a number >= 1"),
    ("uniform float cmlt:sigma = 0", r"cmlt:sigma = 0.0 is out of range; must be a number > 0"),
    ("uniform float cmlt:largeStepProbability = 1.5", r"cmlt:largeStepProbability = 1.5"),
    ("uniform int cmlt:tries = 65", r"cmlt:tries = 65 .*<= 64"),
    ("uniform double cmlt:timeBudget = -1", r"cmlt:timeBudget = -1.0"),
    ("uniform int cmlt:seed = -3", r"cmlt:seed = -3"),
    ("uniform float cmlt:spp = 16.5", r"cmlt:spp is authored as float, but the schema "
                                      r"declares int"),
    ("uniform int2 resolution = (0, 10)", r"resolution = 0x10"),
])
def test11_out_of_range_stage_values(line, pattern):
    stage = make_stage(line + "\n", api=False)
    with pytest.raises(SettingsError, match=r"/Render/settings: " + pattern):
        resolve_settings(stage)


@pytest.mark.parametrize("overrides,pattern", [
    ({"spp": 0}, r"flag --spp = 0 is out of range"),
    ({"integrator": "mlt"}, r"flag --integrator = 'mlt' is not an allowed value; "
                            r"allowed: auto, pt, bdpt, pssmlt, cmlt"),
    ({"large_step_probability": 2.0}, r"flag --large-step-probability = 2.0"),
    ({"max_dept": 3}, r"unknown setting 'max_dept' \(flag --max-dept\); did you mean max_depth"),
    ({"resolution": "wide"}, r"flag --res"),
    ({"carry_states": 3}, r"flag --independent-frames = 3 must be true or false"),
])
def test12_bad_flags(overrides, pattern):
    with pytest.raises(SettingsError, match=pattern):
        resolve_settings(make_stage(), cli_overrides=overrides)


# -- 4. what cmlt inspect prints -----------------------------------------------------------

def test13_format_settings():
    stage = make_stage("uniform int cmlt:spp = 256\n")
    settings, sources = resolve_settings(stage, cli_overrides={"seed": 9})
    text = format_settings(settings, sources)
    lines = {line.split()[0]: line for line in text.splitlines()[2:]}
    assert set(lines) == set(RenderSettings().as_dict())
    assert lines["spp"].split()[1:] == ["256", "cmlt:spp", "stage:/Render/settings"]
    assert lines["seed"].split()[1:] == ["9", "cmlt:seed", "flag", "--seed"]
    assert lines["sigma"].split()[1:] == ["0.01", "cmlt:sigma", "default"]
    assert lines["carry_states"].split()[1] == "true"
    assert flag_name("large_step_probability") == "--large-step-probability"


def test14_one_settings_prim_rule_for_the_reader_and_the_settings():
    """renderSettingsPrimPath naming no RenderSettings prim is an error for the
    stage reader as for the settings (it used to fall back to the first prim in
    load_frame only); without metadata both take the first RenderSettings prim."""
    from cmlt.usd import UsdLoadError, load_frame
    stage = make_stage("uniform int cmlt:spp = 4\nuniform int2 resolution = (20, 10)\n")
    stage.SetMetadata("renderSettingsPrimPath", "/Render/nope")
    with pytest.raises(SettingsError, match="render settings /Render/nope does not exist"):
        resolve_settings(stage)
    with pytest.raises(UsdLoadError, match="render settings /Render/nope does not exist"):
        load_frame(stage, 0)
    stage = make_stage("uniform int cmlt:spp = 4\nuniform int2 resolution = (20, 10)\n",
                       metadata=False)
    settings, sources = resolve_settings(stage)
    assert settings.resolution == load_frame(stage, 0).resolution == (20, 10)
    assert sources["resolution"] == "stage:/Render/settings"
