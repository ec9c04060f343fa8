"""`cmlt inspect --json` on every sequence in sequences/: the effects each calls for
(sequences/*/notes.md say what they hold) and the integrator auto picks."""
from __future__ import annotations

from pathlib import Path

import pytest

from effect_stages import inspect

SEQUENCES = Path(__file__).resolve().parents[3] / "sequences"

#: effects on at the start frame, and auto's choice for the shot
EXPECTED = {
    # animated boxes, but the shutter is closed; a rect light; diffuse materials
    "cornell": (set(), "pt"),
    # a smooth glass ball lit by a small sphere light: the caustic on the floor
    "caustic_glass": ({"caustics", "transmission"}, "bdpt"),
    # a room lit through the gap of a door: light samples at what the camera sees
    # almost never reach the light
    "door_ajar": (set(), "bdpt"),
    "moving_light": (set(), "pt"),
    "static_flicker": (set(), "pt"),
    # a sun-lit chrome ball is a caustic, but it carries a tiny share of the light
    "textured_dome": ({"caustics", "textures", "dome_light"}, "pt"),
    # the camera moves (a time sample per frame), its shutter is closed; the glossy
    # floor is a dielectric of roughness 0.1 (F0 4 %), not a caustic-capable surface;
    # the small key light half a metre under the ceiling makes a hot spot that lights
    # the room: indirect hot spots (bdpt 3.2x better than pt at equal time)
    "camera_pan": (set(), "bdpt"),
    # a key sphere light (radius 3 cm, not a point) fades under a rect fill
    "fading_light": (set(), "pt"),
}

#: the hard cases (sequences/hard/notes.md): one static frame each; auto's choice
HARD = {
    "scale_unit": (set(), "pt"),
    "scale_1e-4": (set(), "pt"),
    "scale_1e5": (set(), "pt"),
    "degenerate": (set(), "pt"),
    # a 0.5 mm sphere light is tiny, not a delta light (treatAsPoint is off); what it
    # lights nearby lights the rest: indirect hot spots (bdpt 5.7x better than pt)
    "tiny_sphere_light": (set(), "bdpt"),
    "point_light": ({"delta_lights"}, "pt"),
    "caustic_lsdse": ({"caustics", "transmission"}, "bdpt"),
    # the caustic is seen only through the glass slab (L S S D S S E)
    "caustic_sds": ({"caustics", "transmission"}, None),
    "slit": (set(), "bdpt"),
    # the distant light is 0.5 degrees wide: not a delta light
    "grazing": (set(), "pt"),
    # mirrors and a glass ball, no diffuse surface: no L S+ D path, nothing to probe from
    "specular_only": ({"transmission"}, "pt"),
    # the only light is sealed in a box: no light sample reaches it
    "all_black": (set(), "bdpt"),
    # all the light leaves through the glass block around it
    "light_behind_glass": ({"caustics", "transmission"}, "bdpt"),
    # the bulb is seen in a mirror and through a glass slab
    "bulb_room": ({"caustics", "transmission"}, "bdpt"),
}


def test01_every_sequence_is_covered():
    assert sorted(p.name for p in SEQUENCES.iterdir() if (p / "shot.usda").exists()) == \
        sorted(EXPECTED)
    assert sorted(p.parent.name for p in (SEQUENCES / "hard").glob("*/shot.usda")) == \
        sorted(HARD)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test02_effects_and_auto_choice(name):
    rep = inspect(SEQUENCES / name / "shot.usda")
    want, integrator = EXPECTED[name]
    assert {n for n, v in rep["effects"].items() if v} == want
    auto = rep["integrator_auto"]
    assert auto["name"] == integrator, auto["reason"]
    assert auto["frames"] == [1.0, 12.0, 24.0]           # the stage's first, middle, last
    if name == "textured_dome":
        assert rep["details"]["textures"]["inputs"] == ["diffuseColor"]
        assert rep["details"]["dome_light"]["textured"] is True
        assert rep["details"]["caustics"]["flux_share"] < 0.01
    if name == "caustic_glass":
        assert rep["details"]["caustics"]["flux_share"] > 0.01
        assert "caustics" in auto["reason"]
    if name == "camera_pan":
        assert "indirect hot spots" in auto["reason"]
    if name == "door_ajar":
        assert "hard visibility" in auto["reason"]
        v = rep["per_frame"][0]["visibility"]
        assert v["direct_visible"] < 0.05 and v["bounce_visible"] < 0.05


def test03_motion_of_the_cornell_boxes_is_not_blur_with_the_shutter_closed():
    rep = inspect(SEQUENCES / "cornell" / "shot.usda", "--frames", "1:24x23")
    assert rep["frames"] == [1.0, 24.0]
    assert [f["effects"]["motion_blur"] for f in rep["per_frame"]] == [False, False]
    assert "shutter closed" in rep["details"]["motion_blur"]["reason"]


@pytest.mark.parametrize("name", sorted(HARD))
def test04_hard_cases(name):
    rep = inspect(SEQUENCES / "hard" / name / "shot.usda")
    want, integrator = HARD[name]
    assert {n for n, v in rep["effects"].items() if v} == want, rep["details"]
    if integrator is not None:
        assert rep["integrator_auto"]["name"] == integrator, rep["integrator_auto"]["reason"]
