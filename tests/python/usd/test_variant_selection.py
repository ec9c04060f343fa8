"""``--variant`` (cmlt render / cmlt inspect): variant selections authored in the
session layer before the shot is read, so that the composed result of the chosen
variant is what renders. The stage is built here: a quad whose variant set
``look`` switches its displayColor between red (the authored selection) and
blue, and whose ``size`` variant ``big`` brings a child with its own ``size``
set (a nested selection); the checks are on the rendered pixels and on the
composed stage."""
from __future__ import annotations

import json

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdLux

from cmlt.cli import main
from cmlt.color import get_config, load_config, set_config
from cmlt.io.exr import read_exr
from cmlt.usd import open_stage, stage_info
from cmlt.usd.variants import VariantError, parse_variant

FAST = ["--spp", "8", "--res", "16x16", "--threads", "2", "--integrator", "pt", "--quiet"]
RED, BLUE = (0.8, 0.05, 0.05), (0.05, 0.05, 0.8)


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("variants") / "variants.usda")
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    world = UsdGeom.Xform.Define(stage, "/World").GetPrim()
    stage.SetDefaultPrim(world)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(180.0)          # 36 mm at 10 m: the 2 m quad fills the frame
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0)
    cam.AddTranslateOp().Set((0, 0, 10))
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")      # along -Z: onto the quad
    sun.CreateIntensityAttr(50000.0)
    quad = UsdGeom.Mesh.Define(stage, "/World/Quad")
    quad.CreatePointsAttr([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    quad.CreateFaceVertexCountsAttr([4])
    quad.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    quad.CreateSubdivisionSchemeAttr("none")

    look = world.GetVariantSets().AddVariantSet("look")
    for name, rgb in (("red", RED), ("blue", BLUE)):
        look.AddVariant(name)
        look.SetVariantSelection(name)
        with look.GetVariantEditContext():
            UsdGeom.Mesh(stage.OverridePrim("/World/Quad")).CreateDisplayColorAttr([rgb])
    look.SetVariantSelection("red")

    size = world.GetVariantSets().AddVariantSet("size")
    size.AddVariant("small")
    size.AddVariant("big")
    size.SetVariantSelection("big")
    with size.GetVariantEditContext():
        inner = stage.DefinePrim("/World/Inner", "Xform")
        iset = inner.GetVariantSets().AddVariantSet("size")
        for n in ("small", "big"):
            iset.AddVariant(n)
        iset.SetVariantSelection("small")
    size.SetVariantSelection("small")
    stage.GetRootLayer().Save()
    return path


def _render(shot, out, *variants):
    args = ["render", shot, "--out", out, *FAST]
    for v in variants:
        args += ["--variant", v]
    assert main(args) == 0
    img, _ = read_exr(out)
    return np.asarray(img, np.float64)[..., :3]


def test01_chosen_variant_renders_its_colour(shot, tmp_path):
    default = _render(shot, str(tmp_path / "a.exr"))
    blue = _render(shot, str(tmp_path / "b.exr"), "look=blue")
    d, b = default.reshape(-1, 3).mean(0), blue.reshape(-1, 3).mean(0)
    # the authored selection (red): red dominates; the chosen one (blue): blue does
    assert d[0] > 2 * d[2] and d[0] > 0.1, d
    assert b[2] > 2 * b[0] and b[2] > 0.1, b
    # the same sun on the same quad (direct light only: nothing else in view): each
    # image is k times its variant's diffuse reflectance (rendering space) plus the
    # same colourless specular of the default preview surface, so the difference of
    # the two images is k times the difference of the reflectances, one k for the red
    # and the blue channel (green differs too little to weigh)
    cfg = get_config()
    refl = {k: np.asarray(cfg.to_rendering_space(np.asarray([v], np.float32), "lin_rec709"),
                          np.float64)[0] for k, v in (("red", RED), ("blue", BLUE))}
    k = (d - b) / (refl["red"] - refl["blue"])
    assert k[0] == pytest.approx(k[2], rel=0.05) and k[0] > 0.5, k
    # the qualified spelling composes the same stage: the same image, bit for bit
    qualified = _render(shot, str(tmp_path / "c.exr"), "/World:look=blue")
    np.testing.assert_array_equal(qualified, blue)
    curly = _render(shot, str(tmp_path / "d.exr"), "/World{look=blue}")
    np.testing.assert_array_equal(curly, blue)
    side = json.loads((tmp_path / "b.exr.json").read_text())
    assert side["settings"]["variants"] == ["look=blue"]


def test02_selections_apply_in_order_the_last_one_wins(shot, tmp_path):
    red_again = _render(shot, str(tmp_path / "a.exr"), "look=blue", "look=red")
    m = red_again.reshape(-1, 3).mean(0)
    assert m[0] > 2 * m[2]


def test03_nested_sets_reached_by_an_unqualified_selection(shot):
    stage = open_stage(shot)
    assert not stage.GetPrimAtPath("/World/Inner")        # authored selection: small
    stage = open_stage(shot, variants=["size=big"])
    inner = stage.GetPrimAtPath("/World/Inner")
    assert inner, "the big variant brings /World/Inner"
    # /World/Inner appears only once /World's selection is made; it has a set of the
    # same name, and the unqualified spec selects it too
    assert inner.GetVariantSets().GetVariantSelection("size") == "big"
    # the shot's own layer is untouched: only the session layer carries them
    assert Sdf.Layer.FindOrOpen(shot).GetPrimAtPath("/World").variantSelections["size"] == "small"
    assert stage.GetSessionLayer().GetPrimAtPath("/World").variantSelections["size"] == "big"
    # qualified: only that prim
    stage = open_stage(shot, variants=["/World:size=big"])
    assert stage.GetPrimAtPath("/World/Inner").GetVariantSets() \
        .GetVariantSelection("size") == "small"


def test04_inspect_lists_sets_and_selections(shot, capsys):
    assert main(["inspect", shot]) == 0
    out = capsys.readouterr().out
    assert "variant sets (2)" in out
    assert "/World: look = red  [blue, red]" in out
    assert "/World: size = small  [big, small]" in out
    assert main(["inspect", shot, "--variant", "look=blue", "--variant", "size=big"]) == 0
    out = capsys.readouterr().out
    assert "variant sets (3), opened with --variant look=blue --variant size=big" in out
    assert "/World: look = blue" in out and "/World/Inner: size = big" in out
    info = stage_info(open_stage(shot, variants=["look=blue"]))
    assert ("/World", "look", "blue", ["blue", "red"]) in info.variant_sets


@pytest.mark.parametrize("spec,exit_code,words", [
    ("colour=blue", 2, ["no prim", "variant set 'colour'", "look, size"]),
    ("look=green", 2, ["/World has no variant 'green'", "blue, red"]),
    ("/Nope:look=blue", 2, ["no prim /Nope"]),
    ("/World/Quad:look=blue", 2, ["/World/Quad has no variant set 'look'", "none"]),
    ("look", 2, ["is not SET=VALUE"]),
    ("/World=blue", 2, ["/PRIM:SET=VALUE"]),
])
def test05_bad_specs_are_usage_errors_naming_them(shot, tmp_path, capsys, spec, exit_code,
                                                    words):
    rc = main(["render", shot, "--out", str(tmp_path / "x.exr"), *FAST, "--variant", spec])
    err = capsys.readouterr().err
    assert rc == exit_code, err
    assert err.startswith("cmlt: error:") and "--variant" in err, err
    for w in words:
        assert w in err, err
    assert not (tmp_path / "x.exr").exists()
    assert main(["inspect", shot, "--variant", spec]) == exit_code
    assert "--variant" in capsys.readouterr().err


def test06_parse_forms():
    assert parse_variant("a=b") == parse_variant(" a=b ")
    s = parse_variant("/World/Set:lod=high")
    assert (s.prim, s.variant_set, s.value) == ("/World/Set", "lod", "high")
    s = parse_variant("/World{lod=low}")
    assert (s.prim, s.variant_set, s.value) == ("/World", "lod", "low")
    for bad in ("=x", "a=", "/World:", "not a path:a=b", "/World{a}"):
        with pytest.raises(ValueError):
            parse_variant(bad)
    with pytest.raises(VariantError, match="instance"):
        _instanced_selection()


def _instanced_selection():
    stage = Usd.Stage.CreateInMemory()
    proto = stage.DefinePrim("/Proto", "Xform")
    child = stage.DefinePrim("/Proto/Child", "Xform")
    vs = child.GetVariantSets().AddVariantSet("lod")
    vs.AddVariant("a")
    vs.AddVariant("b")
    inst = stage.DefinePrim("/Inst", "Xform")
    inst.GetReferences().AddInternalReference(proto.GetPath())
    inst.SetInstanceable(True)
    from cmlt.usd.variants import apply_variants
    apply_variants(stage, ["/Inst/Child:lod=b"])
