"""`cmlt inspect --json` on small stages built for each effect, with the negative cases:
what a stage holds but no rendered path uses is not an effect."""
from __future__ import annotations

import pytest

from effect_stages import build, inspect, write_texture
from cmlt.analysis import EFFECT_NAMES

GLASS = {"opacity": 0.0, "roughness": 0.0, "ior": 1.5}


@pytest.fixture(scope="module")
def stages(tmp_path_factory):
    d = tmp_path_factory.mktemp("effect_stages")
    tex = write_texture(d / "tex.png")
    cases = {
        "plain": {},
        "move_open": dict(move=True, shutter=(-0.25, 0.25)),
        "move_closed": dict(move=True),
        "still_open": dict(shutter=(-0.25, 0.25)),
        "dof": dict(f_stop=2.8),
        "glass": dict(sphere=GLASS),
        "glass_boxed": dict(sphere=GLASS, enclose_sphere=True),
        "glass_roofed": dict(sphere=GLASS, roof=True),
        "rough_glass": dict(sphere={"opacity": 0.0, "roughness": 0.6, "ior": 1.5}),
        "mirror_ball": dict(sphere={"metallic": 1.0, "roughness": 0.05,
                                    "diffuseColor": (0.9, 0.9, 0.9)}),
        "clearcoat": dict(clearcoat=True),
        "textures": dict(floor_textures={"diffuseColor": tex, "roughness": tex}),
        "unseen_textures": dict(floor_textures={"specularColor": tex},
                                unused_textured_material=tex),
        "normal_map": dict(floor_textures={"normal": tex}),
        "normal_map_no_uvs": dict(floor_textures={"normal": tex}, floor_uvs=False),
        "cutout": dict(cutout={"opacity": 0.2, "opacityThreshold": 0.5}),
        "opaque_threshold": dict(cutout={"opacity": 0.9, "opacityThreshold": 0.5}),
        "dome": dict(dome="plain"),
        "dome_textured": dict(dome=tex),
        "no_lights": dict(rect_light=False),
        "emissive": dict(emissive=True),
        "delta": dict(point_light=True, distant_light=True),
        "volume": dict(volume=True),
    }
    return {name: inspect(build(d / f"{name}.usda", **kw)) for name, kw in cases.items()}


def on(report):
    return {n for n, v in report["effects"].items() if v}


def test01_every_effect_is_reported_as_a_boolean(stages):
    for name, rep in stages.items():
        assert list(rep["effects"]) == list(EFFECT_NAMES), name
        assert all(isinstance(v, bool) for v in rep["effects"].values()), name
        assert set(rep["details"]) == set(EFFECT_NAMES)
        assert rep["integrator_auto"]["name"] in ("pt", "bdpt")
        assert rep["integrator_auto"]["reason"]


def test02_a_plain_diffuse_room_calls_for_nothing(stages):
    assert on(stages["plain"]) == set()
    assert stages["plain"]["integrator_auto"]["name"] == "pt"
    assert stages["plain"]["unsupported"] == []


def test03_motion_blur_needs_an_open_shutter_and_motion_within_it(stages):
    assert on(stages["move_open"]) == {"motion_blur"}
    d = stages["move_open"]["details"]["motion_blur"]
    assert d["instances"] == 1 and d["time_steps"] >= 2
    # a moving object with the shutter closed is not motion blur
    assert "motion_blur" not in on(stages["move_closed"])
    assert "shutter closed" in stages["move_closed"]["details"]["motion_blur"]["reason"]
    # an open shutter over a still scene is not either
    assert "motion_blur" not in on(stages["still_open"])
    assert "nothing is animated" in stages["still_open"]["details"]["motion_blur"]["reason"]


def test04_depth_of_field_needs_a_finite_f_stop(stages):
    assert on(stages["dof"]) == {"depth_of_field"}
    d = stages["dof"]["details"]["depth_of_field"]
    # lens radius = focal length / (2 fStop); USD lens values are tenths of a scene
    # unit (metres here): focalLength 24 is 2.4 m
    assert d["lens_radius"] == pytest.approx(2.4 / 5.6, rel=1e-4)
    assert d["f_stop"] == 2.8 and d["focus_distance"] == 4.0
    assert "pinhole" in stages["plain"]["details"]["depth_of_field"]["reason"]


def test05_a_lit_glass_sphere_makes_caustics(stages):
    rep = stages["glass"]
    assert on(rep) == {"caustics", "transmission"}
    d = rep["details"]["caustics"]
    assert d["probe_paths"] > 10 and d["flux_share"] > 0.001
    assert d["specular_materials"] == ["/World/Looks/Sphere"]
    assert rep["details"]["transmission"]["materials"] == ["/World/Looks/Sphere"]


def test06_a_glass_sphere_no_light_reaches_is_no_caustic(stages):
    for name in ("glass_boxed", "glass_roofed"):
        rep = stages[name]
        assert "caustics" not in on(rep), name
        assert "no light reaches" in rep["details"]["caustics"]["reason"], name
        assert rep["per_frame"][0]["probes"]["targeted_reached"] == 0
        assert "transmission" in on(rep)          # it still refracts what the camera sees


def test07_rough_glass_is_transmission_but_not_caustic(stages):
    rep = stages["rough_glass"]
    assert on(rep) == {"transmission"}
    assert "no near-specular surface" in rep["details"]["caustics"]["reason"]


def test08_a_mirror_ball_is_a_caustic_but_no_transmission(stages):
    assert on(stages["mirror_ball"]) == {"caustics"}


def test09_clearcoat(stages):
    assert on(stages["clearcoat"]) == {"clearcoat"}
    assert stages["clearcoat"]["details"]["clearcoat"]["materials"] == ["/World/Looks/Coated"]


def test10_textures_name_their_inputs(stages):
    d = stages["textures"]["details"]["textures"]
    assert on(stages["textures"]) == {"textures"}
    assert d["inputs"] == ["diffuseColor", "roughness"]
    assert d["materials"] == {"/World/Looks/Floor": ["diffuseColor", "roughness"]}


def test11_unseen_texture_inputs_are_no_textures(stages):
    """specularColor in the metallic workflow, and a material bound to nothing (the
    reader does not even load it)."""
    rep = stages["unseen_textures"]
    assert "textures" not in on(rep)
    unseen = rep["details"]["textures"]["unseen"]
    assert unseen == ["/World/Looks/Floor: specularColor (metallic workflow "
                      "(useSpecularWorkflow 0) ignores specularColor)"]


def test12_normal_maps_need_texture_coordinates(stages):
    assert on(stages["normal_map"]) == {"textures", "normal_maps"}
    rep = stages["normal_map_no_uvs"]
    assert on(rep) == set()
    assert "no tangent frame" in rep["details"]["normal_maps"]["unseen"][0]


def test13_cutouts(stages):
    assert on(stages["cutout"]) == {"cutouts"}
    assert stages["cutout"]["details"]["cutouts"]["materials"] == ["/World/Looks/Leaf (cut-out)"]
    # opacity above the threshold everywhere: an opaque surface
    assert on(stages["opaque_threshold"]) == set()


def test14_dome_lights_and_whether_textured(stages):
    assert on(stages["dome"]) == {"dome_light"}
    assert stages["dome"]["details"]["dome_light"]["textured"] is False
    assert on(stages["dome_textured"]) == {"dome_light", "textures"}
    d = stages["dome_textured"]["details"]
    assert d["dome_light"]["textured"] is True
    assert d["textures"]["lights"] == ["/World/Dome (dome)"] and d["textures"]["inputs"] == []
    # cmlt adds a white dome to a stage without lights: that dome is simulated
    assert on(stages["no_lights"]) == {"dome_light"}
    assert stages["no_lights"]["details"]["dome_light"]["default"] is True


def test15_emissive_meshes_and_delta_lights(stages):
    assert on(stages["emissive"]) == {"emissive_meshes"}
    assert stages["emissive"]["details"]["emissive_meshes"]["materials"] == ["/World/Looks/Glow"]
    assert on(stages["delta"]) == {"delta_lights"}
    assert sorted(stages["delta"]["details"]["delta_lights"]["lights"]) == \
        ["/World/Point", "/World/Sun"]
    assert "delta_lights" not in on(stages["plain"])       # a rect light has an area


def test16_volumes_are_listed_not_simulated(stages):
    rep = stages["volume"]
    assert on(rep) == set()
    assert any("/World/Smoke" in u and "not supported" in u for u in rep["unsupported"])


def test17_the_text_form_is_the_same_table(tmp_path, capsys):
    from cmlt.cli import main
    shot = build(tmp_path / "glass.usda", sphere=GLASS, f_stop=4.0)
    assert main(["inspect", shot]) == 0
    out = capsys.readouterr().out
    table = out[out.index("effects:"):].splitlines()
    rows = {line.split()[0]: line.split()[1] for line in table[2:2 + len(EFFECT_NAMES)]}
    assert list(rows) == list(EFFECT_NAMES)
    assert {n for n, v in rows.items() if v == "yes"} == {"caustics", "transmission",
                                                          "depth_of_field"}
    assert "integrator auto: bdpt (caustics" in out
