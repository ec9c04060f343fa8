"""Stage reader, materials and lights: subsets, textures and displayColor; light
radiance, sizes and units; the default dome light."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

from cmlt.usd import load_frame, open_stage
from cmlt.color import from_rendering_space
from support.usd_checks import acescg, assert_clean, data


def test12_materials_subsets_textures_display_color():
    scene = load_frame(open_stage(data("materials.usda")), 0)
    assert_clean(scene)
    mats = scene.materials
    byname = {m.name: i for i, m in enumerate(mats)}
    red = mats[byname["/Looks/red"]]
    assert red.diffuse == pytest.approx(acescg((0.8, 0.1, 0.1)))
    assert (red.roughness, red.metallic, red.ior, red.opacity) == pytest.approx((0.3, 0.25, 1.33, 0.75))
    assert red.use_specular_workflow and red.specular == pytest.approx(acescg((0.5, 0.5, 0.5)))
    tex = mats[byname["/Looks/textured"]]
    d = tex.inputs["diffuseColor"]
    assert d["texture"].endswith(os.path.join("tex", "white.ppm")) and os.path.isabs(d["texture"])
    assert (d["wrapS"], d["wrapT"], d["sourceColorSpace"], d["st_primvar"]) == \
        ("repeat", "mirror", "sRGB", "uvA")
    assert d["scale"] == pytest.approx((2, 2, 2, 1))
    assert tex.diffuse == pytest.approx(acescg((0.2, 0.4, 0.6)))       # the texture's fallback
    assert tex.roughness == pytest.approx(0.4)                 # fallback .g for outputs:g
    meshes = {m.name: m for m in scene.meshes}
    # GeomSubset: face 1 (the triangle) is textured, faces 0 and 2 are red
    ids = meshes["/World/two_faces"].material_ids.tolist()
    r, t = byname["/Looks/red"], byname["/Looks/textured"]
    assert ids == [r, r, t, r, r]
    # the textured material's st primvar (uvA) is the mesh's uv set, not st
    np.testing.assert_allclose(meshes["/World/textured_quad"].uvs,
                               meshes["/World/textured_quad"].points[:, :2])
    painted = mats[meshes["/World/painted"].material_ids[0]]
    assert painted.diffuse == pytest.approx(acescg((0.1, 0.6, 0.2)))
    plain = mats[meshes["/World/plain"].material_ids[0]]
    assert plain.name == "<default>" and plain.diffuse == pytest.approx((0.18, 0.18, 0.18))
    odd = mats[meshes["/World/odd"].material_ids[0]]
    assert odd is plain and sum(m.name == "<default>" for m in mats) == 1
    assert any(w.startswith("/Looks/weird: no UsdPreviewSurface") for w in scene.warnings)
    # emissive material present: no default dome
    assert not any(l.name == "<default dome>" for l in scene.lights)


def test13_light_radiance_sizes_and_units():
    scene = load_frame(open_stage(data("lights_units.usda")), 0)
    L = {l.name.rsplit("/", 1)[-1]: l for l in scene.lights}
    assert set(L) == {"rect", "sphere_old_names", "disk", "sun", "tube", "sky"}
    rect = L["rect"]
    # 2 m x 0.5 m authored (cm), x-scale 2: 4 m x 0.5 m; 10 * 2^2 * colour / 2 m^2
    assert (rect.width, rect.height) == pytest.approx((4.0, 0.5))
    assert rect.radiance == pytest.approx(acescg((20.0, 10.0, 5.0)))
    np.testing.assert_allclose(rect.transform[:3, :3], np.eye(3), atol=1e-12)   # rigid
    np.testing.assert_allclose(rect.transform[:3, 3], [0, 0, 3.0])
    assert rect.texture == "tex/rect.exr" and any("tex/rect.exr cannot be resolved" in w
                                                   for w in scene.warnings)
    sph = L["sphere_old_names"]                      # pre-21 attribute names
    assert sph.radius == pytest.approx(0.5) and sph.treat_as_point
    assert sph.radiance[0] == pytest.approx(3.0 / (4 * math.pi * 0.25))
    assert L["disk"].radius == pytest.approx(1.0) and L["disk"].radiance == pytest.approx((1, 1, 1))
    sun = L["sun"]
    omega = 2 * math.pi * (1 - math.cos(math.radians(0.5)))
    # the temperature colour has Rec.709 luminance 1 before conversion to ACEScg
    rec709 = from_rendering_space(np.array([sun.radiance], dtype=np.float32), "lin_rec709")[0]
    lum = 0.2126 * rec709[0] + 0.7152 * rec709[1] + 0.0722 * rec709[2]
    assert lum == pytest.approx(2.0 / omega, rel=1e-5)
    assert sun.radiance[0] > sun.radiance[1] > sun.radiance[2]  # 3000 K is orange
    assert (L["tube"].length, L["tube"].radius) == pytest.approx((1.0, 0.1))
    assert L["sky"].kind == "dome"
    assert any(w.startswith("/World/lights/portal: PortalLight") for w in scene.warnings)


def test14_default_dome_light_with_warning():
    scene = load_frame(open_stage(data("anim.usda")), 1)
    assert len(scene.lights) == 1 and scene.lights[0].kind == "dome"
    assert scene.lights[0].radiance == (1.0, 1.0, 1.0)
    assert any("no lights and no emissive materials" in w for w in scene.warnings)
    lit = load_frame(open_stage(data("lights_units.usda")), 0)
    assert not any("no lights" in w for w in lit.warnings)
