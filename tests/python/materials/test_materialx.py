"""MaterialX looks (open_pbr_surface, standard_surface) mapped onto cmlt's
UsdPreviewSurface model: from ``.mtlx`` documents referenced by the stage
(which usd-core cannot compose) and from UsdShade networks of ND_* nodes.
One test per mapped input checks pixel values or statistics; a white
furnace bounds the mapped model's albedo by 1."""
from __future__ import annotations

import os
import shutil

import numpy as np
import pytest
from pxr import Sdf, UsdShade

from cmlt.color import load_config, set_config
from cmlt.usd import load_frame, open_stage

from mtlx_test_stages import (acescg, bind_path, mtlx_document, nd_material, nd_shader,
                              quad, red_blue_png, render, sphere, srgb_to_acescg, stage,
                              stage_with_mtlx, surface_xml, write_png)


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


def _load(path, res=(24, 24)):
    return load_frame(open_stage(path), 0, resolution=res)


def _geo_material(fs):
    mesh = next(m for m in fs.meshes if m.name == "/Geo")
    return fs.materials[int(mesh.material_ids[0])]


BLACK_BASE = {"base_weight": ("float", "0"), "specular_weight": ("float", "0")}
STD_BLACK_BASE = {"base": ("float", "0"), "specular": ("float", "0")}


# ------------------------------------------------------------------ documents

@pytest.mark.parametrize("via", ["scope", "material"])
@pytest.mark.parametrize("category", ["standard_surface", "open_pbr_surface"])
def test01_mtlx_document_base_color_renders_red_not_grey(tmp_path, via, category):
    doc = mtlx_document(surface_xml(category, {"base_color": ("color3", "0.8, 0.05, 0.05")}))
    fs = _load(stage_with_mtlx(tmp_path, doc, via=via))
    m = _geo_material(fs)
    assert m.inputs["materialx"]["category"] == category
    np.testing.assert_allclose(m.diffuse, acescg((0.8, 0.05, 0.05)), rtol=1e-5)
    assert not any("default grey" in w for w in fs.warnings), fs.warnings
    mean = render(fs, depth=2).reshape(-1, 3).mean(0)
    assert mean[0] > 4 * mean[2] and mean[0] > 3 * mean[1] and mean[0] > 0.3, mean


def test02_document_material_missing_names_the_ones_it_has(tmp_path):
    doc = mtlx_document(surface_xml("standard_surface", {}), material="Other")
    fs = _load(stage_with_mtlx(tmp_path, doc))
    assert any("has no material M" in w and "Other" in w for w in fs.warnings), fs.warnings
    assert _geo_material(fs).name == "<default>"


def test03_mtlx_and_its_texture_inside_a_usdz(tmp_path):
    src = tmp_path / "src"
    os.makedirs(src / "textures")
    red_blue_png(str(src / "textures" / "rb.png"))
    extra = '''  <image name="img" type="color3">
    <input name="file" type="filename" value="textures/rb.png" colorspace="srgb_texture" />
  </image>'''
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        **BLACK_BASE, "emission_luminance": ("float", "1"),
        "emission_color": ("color3", None, "img")}), extra_xml=extra)
    root = stage_with_mtlx(src, doc)
    pkg = str(tmp_path / "shot.usdz")
    w = Sdf.ZipFileWriter.CreateNew(pkg)
    for rel in ("shot.usda", "look.mtlx", "textures/rb.png"):
        w.AddFile(str(src / rel), rel)
    w.Save()
    shutil.rmtree(src)                                  # only the package is left
    fs = _load(pkg, res=(32, 32))
    rec = _geo_material(fs).inputs["emissiveColor"]
    assert rec["texture"] == pkg + "[textures/rb.png]", rec
    img = render(fs)
    np.testing.assert_allclose(img[16, 8], srgb_to_acescg((1, 0, 0)), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(img[16, 24], srgb_to_acescg((0, 0, 1)), rtol=1e-4, atol=1e-6)


# ------------------------------------------------------------------ UsdShade ND networks

def test04_nd_network_image_place2d_and_colour_space(tmp_path):
    """open_pbr_surface in UsdShade: emission_color <- image (srgb_texture)
    <- place2d (offset 0.5) <- texcoord: the halves of the red|blue texture
    swap and arrive as OCIO's ACEScg values of sRGB red and blue."""
    tex = red_blue_png(str(tmp_path / "rb.png"))
    st = stage()
    q = quad(st, "/Geo")
    tc = nd_shader(st, "/L/M/tc", "ND_texcoord_vector2", {}, "vector2")
    pl = nd_shader(st, "/L/M/pl", "ND_place2d_vector2",
                   {"texcoord": ("vector2", tc, "out"), "offset": ("vector2", (0.5, 0.0))},
                   "vector2")
    img = nd_shader(st, "/L/M/img", "ND_image_color3",
                    {"file": ("filename", tex), "texcoord": ("vector2", pl, "out")})
    img.GetInput("file").GetAttr().SetColorSpace("srgb_texture")
    mat = nd_material(st, "/L/M", "ND_open_pbr_surface_surfaceshader", {
        "base_weight": ("float", 0.0), "specular_weight": ("float", 0.0),
        "emission_luminance": ("float", 2.0), "emission_color": ("color3", img, "out")})
    UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).Bind(mat)
    fs = load_frame(st, 0, resolution=(32, 32))
    m = _geo_material(fs)
    assert m.inputs["emissiveColor"]["st_transform"] == pytest.approx((1, 0, -0.5, 0, 1, 0))
    img_px = render(fs)
    np.testing.assert_allclose(img_px[16, 8], 2 * srgb_to_acescg((0, 0, 1)), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(img_px[16, 24], 2 * srgb_to_acescg((1, 0, 0)), rtol=1e-4, atol=1e-6)


def test05_nd_network_base_color_and_metalness():
    st = stage()
    q = quad(st, "/Geo")
    mat = nd_material(st, "/L/M", "ND_standard_surface_surfaceshader",
                      {"base_color": ("color3", (0.1, 0.7, 0.1)), "metalness": ("float", 0.25),
                       "specular_roughness": ("float", 0.6)})
    UsdShade.MaterialBindingAPI.Apply(q.GetPrim()).Bind(mat)
    fs = load_frame(st, 0, resolution=(16, 16))
    m = _geo_material(fs)
    np.testing.assert_allclose(m.diffuse, acescg((0.1, 0.7, 0.1)), rtol=1e-5)
    assert (m.metallic, m.roughness) == pytest.approx((0.25, 0.6))
    # the one-pixel box: the image mean is the quad's and the background's by area (a
    # wide filter blends the quad's rim with the grey background: G/B 2.50 instead of 2.87)
    mean = render(fs, depth=2, pixel_filter="box").reshape(-1, 3).mean(0)
    # ACEScg (0.30, 0.65, 0.17) albedo, a quarter metal, a white specular: green, not grey
    assert mean[1] > 1.5 * mean[0] and mean[1] > 2.5 * mean[2], mean


# ------------------------------------------------------------------ one input at a time

def test06_metalness_one_is_a_conductor(tmp_path):
    """Metalness 1: no diffuse (a light off the mirror direction leaves a
    smooth metal black while the dielectric is lit), and a reflection tinted
    by base_color (under the white dome the quad's colour ratios are the base
    colour's)."""
    base = (0.9, 0.6, 0.2)
    out = {}
    for metal in ("0", "1"):
        doc = mtlx_document(surface_xml("open_pbr_surface", {
            "base_color": ("color3", "0.9, 0.6, 0.2"), "base_metalness": ("float", metal),
            "specular_roughness": ("float", "0.1")}))
        d = tmp_path / metal
        os.makedirs(d)
        fs = _load(stage_with_mtlx(d, doc, light=45.0), res=(16, 16))
        assert _geo_material(fs).metallic == float(metal)
        out[metal] = render(fs)[4:12, 4:12].mean((0, 1))
    assert out["0"].mean() > 0.1, out
    assert out["1"].max() < 0.01 * out["0"].mean(), out
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        "base_color": ("color3", "0.9, 0.6, 0.2"), "base_metalness": ("float", "1"),
        "specular_roughness": ("float", "0.3")}))
    d = tmp_path / "dome"
    os.makedirs(d)
    dome = render(_load(stage_with_mtlx(d, doc), res=(16, 16)), spp=32)[4:12, 4:12].mean((0, 1))
    want = acescg(base)
    np.testing.assert_allclose(dome / dome[0], want / want[0], rtol=0.1)


@pytest.mark.parametrize("category,inputs,scale", [
    ("open_pbr_surface", {"emission_luminance": ("float", "4")}, 4.0),
    ("standard_surface", {"emission": ("float", "2.5")}, 2.5),
])
def test07_emission_is_luminance_times_colour(tmp_path, category, inputs, scale):
    black = BLACK_BASE if category == "open_pbr_surface" else STD_BLACK_BASE
    doc = mtlx_document(surface_xml(category, {**black, **inputs,
                                               "emission_color": ("color3", "1, 0.5, 0.25")}))
    fs = _load(stage_with_mtlx(tmp_path, doc), res=(16, 16))
    assert not any("white dome" in w for w in fs.warnings)      # emissive: no default dome
    img = render(fs)
    np.testing.assert_allclose(img[8, 8], scale * acescg((1, 0.5, 0.25)), rtol=1e-5)


def test08_coat_adds_a_white_reflection(tmp_path):
    means = {}
    for coat in ("0", "1"):
        doc = mtlx_document(surface_xml("open_pbr_surface", {
            **BLACK_BASE, "coat_weight": ("float", coat), "coat_roughness": ("float", "0.1")}))
        d = tmp_path / coat
        os.makedirs(d)
        fs = _load(stage_with_mtlx(d, doc), res=(16, 16))
        m = _geo_material(fs)
        assert (m.clearcoat, m.clearcoat_roughness) == pytest.approx((float(coat), 0.1))
        # the one-pixel box: the frame shows the quad only (a wider filter's footprint
        # reaches past the frame's edge, to what lies beyond it)
        means[coat] = render(fs, spp=32, pixel_filter="box").reshape(-1, 3).mean(0)
    assert means["0"].max() == 0.0                     # black base, no specular: nothing
    assert 0.02 < means["1"].mean() < 0.2, means       # the coat's Fresnel reflection
    assert np.ptp(means["1"]) < 0.05 * means["1"].mean() + 1e-4   # white


def test09_transmission_shows_what_is_behind(tmp_path):
    centre = {}
    for t in ("0", "1"):
        doc = mtlx_document(surface_xml("open_pbr_surface", {
            "transmission_weight": ("float", t), "specular_roughness": ("float", "0")}))
        d = tmp_path / t
        os.makedirs(d)
        fs = _load(stage_with_mtlx(d, doc, backdrop=(1.0, 0.0, 0.0)), res=(16, 16))
        m = _geo_material(fs)
        assert m.opacity == pytest.approx(1.0 - float(t)) and m.ior == pytest.approx(1.5)
        centre[t] = render(fs, depth=4, spp=8)[5:11, 5:11].mean((0, 1))
    red = acescg((1, 0, 0))
    assert centre["0"][0] < 0.05 * red[0], centre       # opaque, unlit front
    assert centre["1"][0] > 0.3 * red[0], centre        # the emitter through the glass
    assert centre["1"][2] < 0.1 * centre["1"][0]


@pytest.mark.parametrize("category,inputs", [
    ("open_pbr_surface", {"geometry_opacity": ("float", "0")}),
    ("standard_surface", {"opacity": ("color3", "0, 0, 0")}),
])
def test10_zero_opacity_is_a_pass_through(tmp_path, category, inputs):
    doc = mtlx_document(surface_xml(category, inputs))
    fs = _load(stage_with_mtlx(tmp_path, doc, backdrop=(1.0, 0.0, 0.0)), res=(16, 16))
    m = _geo_material(fs)
    assert m.opacity == 0.0 and m.ior == 1.0 and m.use_specular_workflow
    img = render(fs, depth=2)
    np.testing.assert_allclose(img[8, 8], acescg((1, 0, 0)), rtol=1e-5, atol=1e-6)


def test11_textured_opacity_is_a_cut_out(tmp_path):
    mask = np.zeros((8, 8, 1), np.uint8)
    mask[:, 4:] = 255
    write_png(str(tmp_path / "mask.png"), mask)
    extra = '''  <image name="mask" type="float">
    <input name="file" type="filename" value="mask.png" />
  </image>'''
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        **BLACK_BASE, "geometry_opacity": ("float", None, "mask")}), extra_xml=extra)
    fs = _load(stage_with_mtlx(tmp_path, doc, backdrop=(1.0, 0.0, 0.0)), res=(32, 32))
    m = _geo_material(fs)
    assert m.opacity_threshold == 0.5 and m.inputs["opacity"]["sourceColorSpace"] == "raw"
    assert any("cut-out at 0.5" in w for w in fs.warnings), fs.warnings
    img = render(fs, depth=2, spp=4)
    np.testing.assert_allclose(img[16, 8], acescg((1, 0, 0)), rtol=1e-5)   # mask 0: through
    assert img[16, 24].max() == 0.0                                         # mask 1: black quad


def test12_normal_map_tilts_the_shading_normal(tmp_path):
    """A normal map tilting the normal 60 degrees toward a distant light 60
    degrees off the quad's normal doubles a Lambertian quad's radiance
    (cos 0 / cos 60)."""
    theta = np.radians(60.0)
    n = np.array([np.sin(theta), 0.0, np.cos(theta)])
    write_png(str(tmp_path / "n.png"), np.tile(np.round((n * 0.5 + 0.5) * 255), (4, 4, 1)))
    extra = '''  <image name="nimg" type="vector3">
    <input name="file" type="filename" value="n.png" />
  </image>
  <normalmap name="nmap" type="vector3">
    <input name="in" type="vector3" nodename="nimg" />
  </normalmap>'''
    lambert = {"base_color": ("color3", "1, 1, 1"), "specular_weight": ("float", "0")}
    vals = {}
    for mapped in (False, True):
        inputs = dict(lambert)
        if mapped:
            inputs["geometry_normal"] = ("vector3", None, "nmap")
        d = tmp_path / str(mapped)
        os.makedirs(d)
        shutil.copy(tmp_path / "n.png", d / "n.png")
        doc = mtlx_document(surface_xml("open_pbr_surface", inputs), extra_xml=extra)
        fs = _load(stage_with_mtlx(d, doc, light=60.0), res=(16, 16))
        if mapped:
            rec = _geo_material(fs).inputs["normal"]
            assert rec["scale"] == pytest.approx((2, 2, 2, 1))
            assert rec["bias"] == pytest.approx((-1, -1, -1, 0))
            assert rec["sourceColorSpace"] == "raw"
        vals[mapped] = render(fs)[4:12, 4:12].mean()
    assert vals[False] > 0
    assert vals[True] / vals[False] == pytest.approx(2.0, rel=0.02), vals


@pytest.mark.parametrize("colorspace,convert", [
    ("srgb_texture", srgb_to_acescg), ("lin_rec709", acescg), (None, acescg),
])
def test13_image_colour_spaces(tmp_path, colorspace, convert):
    write_png(str(tmp_path / "grey.png"), np.full((4, 4, 3), 128, np.uint8))
    cs = f' colorspace="{colorspace}"' if colorspace else ""
    extra = f'''  <image name="img" type="color3">
    <input name="file" type="filename" value="grey.png"{cs} />
  </image>'''
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        **BLACK_BASE, "emission_luminance": ("float", "1"),
        "emission_color": ("color3", None, "img")}), extra_xml=extra)
    fs = _load(stage_with_mtlx(tmp_path, doc), res=(8, 8))
    np.testing.assert_allclose(render(fs)[4, 4], convert((128 / 255,) * 3), rtol=1e-4)


def test14_tiledimage_repeats(tmp_path):
    red_blue_png(str(tmp_path / "rb.png"))
    extra = '''  <tiledimage name="img" type="color3">
    <input name="file" type="filename" value="rb.png" colorspace="lin_rec709" />
    <input name="uvtiling" type="vector2" value="2, 1" />
  </tiledimage>'''
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        **BLACK_BASE, "emission_luminance": ("float", "1"),
        "emission_color": ("color3", None, "img")}), extra_xml=extra)
    img = render(_load(stage_with_mtlx(tmp_path, doc), res=(32, 8)))
    red, blue = acescg((1, 0, 0)), acescg((0, 0, 1))
    for x, want in ((4, red), (12, blue), (20, red), (28, blue)):
        np.testing.assert_allclose(img[4, x], want, rtol=1e-4, atol=1e-6)


def test15_unmapped_nodes_and_inputs_warn_naming_them(tmp_path):
    extra = '''  <noise2d name="noisy" type="color3" />'''
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        "base_color": ("color3", None, "noisy"), "subsurface_weight": ("float", "0.5"),
        "fuzz_weight": ("float", "0")}), extra_xml=extra)
    fs = _load(stage_with_mtlx(tmp_path, doc), res=(8, 8))
    assert any("noisy (noise2d)" in w and "base_color" in w for w in fs.warnings), fs.warnings
    assert any("subsurface_weight = 0.5 has no mapping" in w for w in fs.warnings), fs.warnings
    assert not any("fuzz_weight" in w for w in fs.warnings)    # authored at its default
    # base_color falls back to its node-definition default, 0.8 grey
    np.testing.assert_allclose(_geo_material(fs).diffuse, acescg((0.8, 0.8, 0.8)), rtol=1e-5)


def test16_specular_weight_and_colour_fold_into_the_specular_workflow(tmp_path):
    doc = mtlx_document(surface_xml("open_pbr_surface", {
        "base_color": ("color3", "0.5, 0.5, 0.5"), "base_metalness": ("float", "0.5"),
        "specular_weight": ("float", "0.5"), "specular_color": ("color3", "1, 0, 0"),
        "specular_ior": ("float", "1.5")}))
    m = _geo_material(_load(stage_with_mtlx(tmp_path, doc), res=(8, 8)))
    assert m.use_specular_workflow
    f0 = 0.04 * 0.5 * acescg((1, 0, 0))
    base = acescg((0.5, 0.5, 0.5))
    np.testing.assert_allclose(m.specular, 0.5 * f0 + 0.5 * base, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(m.diffuse, 0.5 * base, rtol=1e-5)


# ------------------------------------------------------------------ energy

FURNACE = [
    ("open_pbr_surface", {"base_color": ("color3", "1, 1, 1"), "coat_weight": ("float", "1"),
                          "specular_roughness": ("float", "0.5")}),
    ("open_pbr_surface", {"base_color": ("color3", "1, 1, 1"), "base_metalness": ("float", "1"),
                          "specular_roughness": ("float", "0.2")}),
    ("open_pbr_surface", {"transmission_weight": ("float", "1"),
                          "specular_roughness": ("float", "0")}),
    ("open_pbr_surface", {"base_color": ("color3", "1, 1, 1"), "specular_ior": ("float", "3"),
                          "specular_color": ("color3", "1, 1, 1"),
                          "specular_weight": ("float", "1")}),
    ("open_pbr_surface", {"base_color": ("color3", "1, 1, 1"),
                          "geometry_opacity": ("float", "0.3")}),
    ("standard_surface", {"base_color": ("color3", "1, 1, 1"), "metalness": ("float", "0.5"),
                          "coat": ("float", "1"), "coat_roughness": ("float", "0.3"),
                          "specular": ("float", "0.7")}),
]


@pytest.mark.parametrize("category,inputs", FURNACE)
def test17_white_furnace_albedo_at_most_one(tmp_path, category, inputs):
    """A sphere of the mapped material inside the white dome (radiance 1):
    every pixel's expectation is the sphere's albedo (plus the dome where it
    passes light), at most 1. Mean over the sphere's centre <= 1 within 4
    standard errors, and every mapped parameter is in its valid range."""
    doc = mtlx_document(surface_xml(category, inputs))
    fs = _load(stage_with_mtlx(tmp_path, doc, geometry="sphere"), res=(16, 16))
    m = _geo_material(fs)
    for v in (m.diffuse, m.specular):
        assert all(0.0 <= c <= 1.0 for c in v), m
    for v in (m.metallic, m.roughness, m.clearcoat, m.clearcoat_roughness, m.opacity):
        assert 0.0 <= v <= 1.0, m
    img = render(fs, spp=64, depth=24, seed=11)[5:11, 5:11].reshape(-1, 3)
    mean = img.mean(0)
    se = img.std(0) / np.sqrt(len(img))
    assert np.all(mean <= 1.0 + 4 * se + 1e-3), (mean, se)
    assert np.all(mean > 0.3), mean                     # and it is lit at all
