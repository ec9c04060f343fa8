"""Stages delivered as ``.usdz`` packages: textures and layers inside the
package are read through USD's asset resolver (``cmlt.usd.assets``), so a
packaged textured stage renders exactly as its unpackaged source does, and
not with the fallback grey."""
from __future__ import annotations

import os
import shutil

import numpy as np
import OpenImageIO as oiio
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade, UsdUtils

import cmlt._core as core
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage
from cmlt.usd.assets import AssetError, is_package_path, local_path, read_asset
from cmlt.usd.color import load_texture, texture_wrap_metadata


def _write_png(path, pixels):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(path)
    assert out.open(path, oiio.ImageSpec(w, h, c, oiio.UINT8)), out.geterror()
    assert out.write_image(np.ascontiguousarray(pixels))
    out.close()


def _red_blue_texture(path):
    """8x8, left half pure red, right half pure blue (sRGB 8-bit)."""
    px = np.zeros((8, 8, 3), np.uint8)
    px[:, :4, 0] = 255
    px[:, 4:, 2] = 255
    _write_png(path, px)


def _textured_stage(src_dir):
    """root.usda references geo.usda (a camera-filling quad with st) and binds a
    UsdPreviewSurface whose diffuseColor is textures/rb.png; no lights (the
    reader adds its white dome)."""
    os.makedirs(os.path.join(src_dir, "textures"), exist_ok=True)
    _red_blue_texture(os.path.join(src_dir, "textures", "rb.png"))
    geo = Usd.Stage.CreateNew(os.path.join(src_dir, "geo.usda"))
    UsdGeom.SetStageMetersPerUnit(geo, 1.0)
    quad = UsdGeom.Mesh.Define(geo, "/Geo/Quad")
    quad.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    quad.CreateFaceVertexCountsAttr([4])
    quad.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    quad.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(quad).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex).Set(
        [(0, 0), (1, 0), (1, 1), (0, 1)])
    geo.SetDefaultPrim(geo.GetPrimAtPath("/Geo"))
    geo.GetRootLayer().Save()

    stage = Usd.Stage.CreateNew(os.path.join(src_dir, "root.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    geo_prim = stage.DefinePrim("/World/Geo")
    geo_prim.GetReferences().AddReference("./geo.usda")
    mat = UsdShade.Material.Define(stage, "/World/Looks/M")
    surf = UsdShade.Shader.Define(stage, "/World/Looks/M/Surf")
    surf.CreateIdAttr("UsdPreviewSurface")
    tex = UsdShade.Shader.Define(stage, "/World/Looks/M/Tex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./textures/rb.png")
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    reader = UsdShade.Shader.Define(stage, "/World/Looks/M/St")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI(), "result")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        tex.ConnectableAPI(), "rgb")
    surf.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    quad = stage.GetPrimAtPath("/World/Geo/Quad")
    UsdShade.MaterialBindingAPI.Apply(quad).Bind(mat)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(180.0)          # 36 mm aperture at 10 m: the 2 m quad fills it
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0)
    cam.AddTranslateOp().Set((0, 0, 10))
    stage.GetRootLayer().Save()
    return os.path.join(src_dir, "root.usda")


def _package(tmp_path):
    """The textured stage as a .usdz, moved away from its sources (which are
    then deleted), so that nothing can be read except through the package."""
    src = str(tmp_path / "src")
    root = _textured_stage(src)
    pkg = str(tmp_path / "src" / "shot.usdz")
    assert UsdUtils.CreateNewUsdzPackage(root, pkg)
    os.makedirs(tmp_path / "delivered")
    moved = str(tmp_path / "delivered" / "shot.usdz")
    shutil.move(pkg, moved)
    return src, moved


def _render(fs, spp=16):
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.max_depth, st.seed, st.threads = spp, 2, 7, 2
    st.integrator = "pt"
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


def test01_texture_inside_a_usdz_is_resolved_and_read(tmp_path):
    src, pkg = _package(tmp_path)
    stage = open_stage(pkg)
    fs = load_frame(stage, 0, resolution=(32, 32))
    rec = fs.materials[0].inputs["diffuseColor"]
    assert is_package_path(rec["texture"]), rec["texture"]
    assert rec["texture"].startswith(pkg + "[") and rec["texture"].endswith("rb.png]")
    img = load_texture(rec["texture"], "raw")
    assert img.shape == (8, 8, 3)
    np.testing.assert_array_equal(img[:, :4], np.tile([1.0, 0.0, 0.0], (8, 4, 1)))
    np.testing.assert_array_equal(img[:, 4:], np.tile([0.0, 0.0, 1.0], (8, 4, 1)))
    # the extracted copy is one file per content, reused
    assert local_path(rec["texture"]) == local_path(rec["texture"])
    assert os.path.isfile(local_path(rec["texture"]))
    assert texture_wrap_metadata(rec["texture"]) == (None, None)   # plain PNG: no metadata
    assert not any("cannot" in w for w in fs.warnings), fs.warnings


def test02_packaged_quad_renders_red_and_blue_like_its_source(tmp_path):
    src, pkg = _package(tmp_path)
    packaged = _render(load_frame(open_stage(pkg), 0, resolution=(32, 32)))
    # referenced layer inside the package: the quad is there
    left, right = packaged[:, 2:14], packaged[:, 18:30]
    assert left[..., 0].mean() > 0.3 and left[..., 1:].mean() < 0.1 * left[..., 0].mean() + 0.05
    assert right[..., 2].mean() > 0.3 and right[..., :2].mean() < 0.1 * right[..., 2].mean() + 0.05
    # not the fallback grey: the two halves differ in hue
    assert left[..., 0].mean() > 3 * right[..., 0].mean()
    assert right[..., 2].mean() > 3 * left[..., 2].mean()
    # exactly the image of the unpackaged source (same seed)
    source = _render(load_frame(open_stage(os.path.join(src, "root.usda")), 0,
                                resolution=(32, 32)))
    np.testing.assert_array_equal(packaged, source)


def test03_missing_member_names_the_package_path(tmp_path):
    src, pkg = _package(tmp_path)
    bogus = pkg + "[textures/nope.png]"
    assert is_package_path(bogus)
    with pytest.raises(AssetError, match=r"nope\.png"):
        read_asset(bogus)
    with pytest.raises(OSError, match=r"nope\.png"):
        load_texture(bogus, "raw")
    assert texture_wrap_metadata(bogus) == (None, None)


def test04_plain_paths_pass_through(tmp_path):
    p = str(tmp_path / "plain.png")
    _red_blue_texture(p)
    assert not is_package_path(p)
    assert local_path(p) == p
