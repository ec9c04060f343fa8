"""Stage problems become one-line cmlt warnings naming the layer, prim or
attribute, never raw USD output, and `cmlt inspect` shows them (issues 2, 6):
USD's own diagnostics under --quiet / --log-json, an unresolved payload, a
render-settings camera that does not exist, prims of unregistered types, a
colorManagementSystem other than OpenColorIO, and the OCIO config in force."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from pxr import Tf

from cmlt.cli import main
from cmlt.color import load_config, set_config
from cmlt.usd import load_frame, open_stage, stage_info
from cmlt.usd.diagnostics import capture_usd_diagnostics, parse_tf_diagnostics, tf_message

FAST = ["--spp", "2", "--res", "16x12", "--threads", "2"]

BROKEN_ARCS = ('def Xform "Ref" (\n    references = @gone_ref.usda@\n)\n{\n}\n'
               'def Xform "Pay" (\n    payload = @gone_payload.usda@\n)\n{\n}\n'
               'def Scope "Render"')


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _run(args, cwd):
    return subprocess.run([sys.executable, "-m", "cmlt", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


# ---------------------------------------------------------------- USD diagnostics

def test01_tf_diagnostic_text_becomes_one_line():
    text = ("Warning: in _ReportErrors at line 3326 of /opt/USD/pxr/usd/usd/stage.cpp -- "
            "In </P>: Could not open asset @p.usda@ for payload introduced by @s.usda@</P>. "
            "(instantiating stage on stage @s.usda@ <0x55950465a910>)\n"
            "some other output\n"
            "Coding Error: in Foo at line 1 of x.cpp -- bad\n  continued\n")
    diags, other = parse_tf_diagnostics(text)
    assert diags == ["In </P>: Could not open asset @p.usda@ for payload introduced by "
                     "@s.usda@</P>. (instantiating stage on stage @s.usda@)",
                     "coding error: bad continued"]
    assert other == ["some other output"]
    assert tf_message("Warning: in f at line 2 of g.cpp -- a\n b") == "a b"


def test02_capture_takes_usd_output_and_gives_the_rest_back(capfd):
    with capture_usd_diagnostics() as diags:
        Tf.Warn("cmlt test warning")
        os.write(2, b"not from USD\n")
    out, err = capfd.readouterr()
    assert diags == ["cmlt test warning"]
    assert "not from USD" in err and "cmlt test warning" not in err


def test03_unresolved_reference_and_payload_warn_naming_the_layer(tmp_path, capfd):
    p = tmp_path / "arcs.usda"
    p.write_text('#usda 1.0\n' + BROKEN_ARCS.replace('def Scope "Render"', '') +
                 'def Sphere "ok"\n{\n}\n')
    stage = open_stage(str(p))
    assert capfd.readouterr().err == ""           # nothing raw on stderr
    info = stage_info(stage)
    pay = [w for w in info.warnings if "gone_payload.usda" in w]
    ref = [w for w in info.warnings if "gone_ref.usda" in w]
    assert len(pay) == 1 and "payload" in pay[0] and "arcs.usda" in pay[0]
    assert len(ref) == 1 and "reference" in ref[0] and "arcs.usda" in ref[0]
    scene = load_frame(stage, 0)
    assert any("gone_payload.usda" in w and "arcs.usda" in w for w in scene.warnings)
    assert [i.name for i in scene.instances] == ["/ok"]      # the rest loads


def test04_quiet_and_log_json_keep_usd_output_off_stderr(make_shot, tmp_path):
    shot = make_shot("arcs.usda", {'def Scope "Render"': BROKEN_ARCS})
    proc = _run(["render", shot, "--out", str(tmp_path / "q.exr"), *FAST, "--quiet"], tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert proc.stdout == ""
    proc = _run(["render", shot, "--out", str(tmp_path / "j.exr"), *FAST, "--log-json"],
                tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    warnings = [e["message"] for e in events if e["event"] == "warning"]
    assert any("gone_ref.usda" in w and "arcs.usda" in w for w in warnings), warnings
    assert any("gone_payload.usda" in w and "arcs.usda" in w for w in warnings), warnings
    assert not any("_ReportErrors" in w or "stage.cpp" in w for w in warnings)
    proc = _run(["render", shot, "--out", str(tmp_path / "n.exr"), *FAST], tmp_path)
    assert proc.returncode == 0
    assert "_ReportErrors" not in proc.stderr and "stage.cpp" not in proc.stderr
    assert "cmlt: warning:" in proc.stderr and "gone_payload.usda" in proc.stderr


# ---------------------------------------------------------------- render-settings camera

def test05_settings_camera_that_does_not_exist(make_shot, tmp_path, capsys):
    shot = make_shot("nocam.usda", {"rel camera = </World/Cam>": "rel camera = </World/Nope>"})
    scene = load_frame(open_stage(shot), 1)
    msg = "/Render/Settings: camera /World/Nope does not exist; rendering from another camera"
    assert msg in scene.warnings
    assert not any("is not a Camera" in w for w in scene.warnings)
    assert scene.camera.name == "/World/Cam"          # the stage's camera instead
    assert main(["inspect", shot]) == 0
    out = capsys.readouterr().out
    warnings = out.split("warnings (", 1)[1].split("settings in force:")[0]
    assert msg in warnings
    cam_row = next(line for line in out.splitlines() if line.strip().startswith("camera "))
    assert "/World/Nope" in cam_row and "NOT USED: does not exist" in cam_row


def test06_settings_camera_that_is_not_a_camera(make_shot, tmp_path, capsys):
    shot = make_shot("meshcam.usda", {"rel camera = </World/Cam>":
                                      "rel camera = </World/Floor>"})
    scene = load_frame(open_stage(shot), 1)
    assert ("/Render/Settings: camera /World/Floor is a Mesh, not a Camera; rendering from "
            "another camera") in scene.warnings
    # --camera makes the settings' camera moot: no warning about it
    assert main(["render", shot, "--camera", "/World/Cam", "--out", str(tmp_path / "c.exr"),
                 *FAST]) == 0
    assert "/World/Floor" not in capsys.readouterr().err


# ---------------------------------------------------------------- unregistered types

def test07_unregistered_prim_types_warn_once_per_type(make_shot, tmp_path, capsys):
    shot = make_shot("weird.usda", {'def Scope "Looks"':
                                    'def FooBarType "Weird" {\n}\n'
                                    '        def FooBarType "Weirder" {\n'
                                    '            def Sphere "Inside" {\n            }\n        }\n'
                                    '        def BazType "Odd" {\n}\n'
                                    '        def Scope "Looks"'})
    scene = load_frame(open_stage(shot), 1)
    foo = [w for w in scene.warnings if "FooBarType" in w]
    assert len(foo) == 1, scene.warnings
    assert "/World/Weird" in foo[0] and "/World/Weirder" in foo[0] and "2 prim(s)" in foo[0]
    assert "not a registered prim type" in foo[0]
    assert sum("BazType" in w for w in scene.warnings) == 1
    assert "/World/Weirder/Inside" in {i.name for i in scene.instances}   # children render
    info = stage_info(open_stage(shot))
    ignored = {(p, t) for p, t, _ in info.ignored}
    assert {("/World/Weird", "FooBarType"), ("/World/Weirder", "FooBarType"),
            ("/World/Odd", "BazType")} <= ignored
    assert main(["inspect", shot]) == 0
    out = capsys.readouterr().out
    section = out.split("ignored (", 1)[1]
    assert "/World/Weird [FooBarType]: FooBarType is not a registered prim type" in section
    # rendering prints it once, however many frames
    assert main(["render", shot, "--frames", "1:2", "--out", str(tmp_path / "w.#.exr"),
                 *FAST]) == 0
    assert capsys.readouterr().err.count("of type FooBarType") == 1


# ---------------------------------------------------------------- colour management

def test08_inspect_prints_the_ocio_config_in_force(tiny_shot, capsys):
    assert main(["inspect", tiny_shot]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("colour: "))
    assert "OpenColorIO" in line and "built-in: ocio://studio-config-latest" in line
    assert "rendering space 'ACEScg'" in line


def test09_inspect_names_the_environment_config(tiny_shot, capsys, monkeypatch):
    monkeypatch.setenv("OCIO", "ocio://cg-config-latest")
    assert main(["inspect", tiny_shot]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("colour: "))
    assert "($OCIO: ocio://cg-config-latest)" in line


@pytest.mark.parametrize("cms,warned", [("Arnold", True), ("OpenColorIO", False),
                                        ("OCIO", False)])
def test10_other_color_management_system_warns(make_shot, tmp_path, capsys, cms, warned):
    shot = make_shot(f"cms_{cms}.usda", {"upAxis = \"Y\"":
                                         f"upAxis = \"Y\"\n    colorManagementSystem = \"{cms}\""})
    info = stage_info(open_stage(shot))
    hits = [w for w in info.warnings if "colorManagementSystem" in w]
    if not warned:
        assert hits == []
        return
    assert len(hits) == 1
    assert hits[0].startswith(os.path.realpath(shot) + ":") or shot in hits[0]
    assert "'Arnold', not OpenColorIO" in hits[0]
    assert main(["render", shot, "--out", str(tmp_path / "c.exr"), *FAST]) == 0
    assert "colorManagementSystem is 'Arnold'" in capsys.readouterr().err
