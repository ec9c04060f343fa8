"""UsdRender.Settings.aspectRatioConformPolicy: a 36 x 24 mm aperture (3:2) looks at
an emissive card that fills exactly that aperture's field of view, on black; the
image's mean over the card's radiance is the share of the image the card covers,
which each policy decides when the image aspect is not 3:2:

==========================  ===========  ===========
policy                      48x24 (2:1)  24x24 (1:1)
==========================  ===========  ===========
expandAperture (default)    36/48        24/36
cropAperture                1            1
adjustApertureWidth         36/48        1
adjustApertureHeight        1            24/36
==========================  ===========  ===========
"""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdRender, UsdShade

import cmlt._core as core
from cmlt.color import load_config, set_config
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage

E = 2.0


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _stage(path, policy=None):
    st = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    cam = UsdGeom.Camera.Define(st, "/World/Cam")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(24.0)
    cam.AddTranslateOp().Set((0, 0, 10))
    hw, hh = 10 * 18 / 50, 10 * 12 / 50          # the aperture's field at 10 m
    card = UsdGeom.Mesh.Define(st, "/World/Card")
    card.CreatePointsAttr([(-hw, -hh, 0), (hw, -hh, 0), (hw, hh, 0), (-hw, hh, 0)])
    card.CreateFaceVertexCountsAttr([4])
    card.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    card.CreateSubdivisionSchemeAttr("none")
    mat = UsdShade.Material.Define(st, "/World/Glow")
    s = UsdShade.Shader.Define(st, "/World/Glow/S")
    s.CreateIdAttr("UsdPreviewSurface")
    s.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set((E, E, E))
    s.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set((0, 0, 0))
    mat.CreateSurfaceOutput().ConnectToSource(s.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(card.GetPrim()).Bind(mat)
    rs = UsdRender.Settings.Define(st, "/Render/Settings")
    rs.CreateCameraRel().SetTargets([Sdf.Path("/World/Cam")])
    if policy is not None:
        rs.CreateAspectRatioConformPolicyAttr(policy)
    st.GetRootLayer().Save()
    return path


def _coverage(path, res):
    fs = load_frame(open_stage(path), None, resolution=res)
    st = core.RenderSettings()
    st.pixel_filter = "box"    # per-pixel analytic expectation: the one-pixel box
    st.width, st.height = res
    st.spp, st.max_depth, st.seed, st.threads = 4, 1, 1, 2
    st.integrator = "pt"
    img = np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)
    glow = next(m for m in fs.materials if m.name == "/World/Glow")
    return img[..., :3].mean() / float(np.mean(glow.emission)), fs


@pytest.mark.parametrize("policy,wide,square", [
    (None, 36 / 48, 24 / 36),              # not authored: the schema's fallback
    ("expandAperture", 36 / 48, 24 / 36),
    ("cropAperture", 1.0, 1.0),
    ("adjustApertureWidth", 36 / 48, 1.0),
    ("adjustApertureHeight", 1.0, 24 / 36),
])
def test01_policy_decides_what_the_image_shows(tmp_path, policy, wide, square):
    path = _stage(str(tmp_path / "c.usda"), policy)
    cov_wide, fs = _coverage(path, (48, 24))
    assert fs.warnings == []
    assert cov_wide == pytest.approx(wide, abs=0.01)
    cov_square, _ = _coverage(path, (24, 24))
    assert cov_square == pytest.approx(square, abs=0.01)


def test02_matching_aspect_is_unchanged_and_pixel_aspect_warns(tmp_path):
    path = _stage(str(tmp_path / "m.usda"), "adjustPixelAspectRatio")
    cov, fs = _coverage(path, (36, 24))                     # 3:2: every policy agrees
    assert cov == pytest.approx(1.0, abs=0.01)
    assert fs.camera.horizontal_aperture == pytest.approx(36.0)
    assert any("adjustPixelAspectRatio" in w and "/Render/Settings" in w for w in fs.warnings)


def test03_without_render_settings_the_width_is_the_aperture(tmp_path):
    path = _stage(str(tmp_path / "n.usda"))
    stage = open_stage(path)
    stage.RemovePrim("/Render")
    stage.GetRootLayer().Save()
    cov, fs = _coverage(path, (48, 24))                     # ha spans the width: va = 18
    assert cov == pytest.approx(1.0, abs=0.01)
    assert fs.camera.horizontal_aperture == pytest.approx(36.0)
