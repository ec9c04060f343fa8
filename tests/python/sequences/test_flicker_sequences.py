"""The flicker sequences (sequences/static_flicker, moving_light, door_ajar) load
frame by frame with the stage reader and animate what they claim to."""
import os

import numpy as np
import pytest

from cmlt.usd import load_frame, open_stage
import support

ROOT = str(support.ROOT)
SEQ = os.path.join(ROOT, "sequences")
FRAMES = (1, 12, 13, 24)


def _stage(name):
    return open_stage(os.path.join(SEQ, name, "shot.usda"))


def _frames(name):
    st = _stage(name)
    assert st.GetStartTimeCode() == 1 and st.GetEndTimeCode() == 24
    assert st.GetFramesPerSecond() == 24
    return {f: load_frame(st, f) for f in FRAMES}


def _by_name(items, suffix):
    found = [x for x in items if x.name.endswith(suffix)]
    assert len(found) == 1, (suffix, [x.name for x in items])
    return found[0]


@pytest.mark.parametrize("name", ["static_flicker", "moving_light", "door_ajar"])
def test_sequence_loads_at_key_frames(name):
    for f, fs in _frames(name).items():
        assert fs.camera is not None and fs.camera.name.endswith("/Camera"), (name, f)
        assert fs.lights and len(fs.meshes) >= 5 and len(fs.instances) >= 5, (name, f)
        assert fs.resolution == (128, 128) and fs.meters_per_unit == 0.01
        assert not any("binding" in w.lower() or "material" in w.lower() for w in fs.warnings), \
            fs.warnings
        assert len(fs.materials) >= 3


def test_static_flicker_is_static():
    fr = _frames("static_flicker")
    a, b = fr[1], fr[24]
    for ia, ib in zip(a.instances, b.instances):
        np.testing.assert_array_equal(ia.transform, ib.transform)
    for la, lb in zip(a.lights, b.lights):
        np.testing.assert_array_equal(la.transform, lb.transform)
        assert la.radiance == lb.radiance
    np.testing.assert_array_equal(a.camera.transform, b.camera.transform)
    st = _stage("static_flicker")
    varying = [f"{p.GetPath()}.{a.GetName()}" for p in st.Traverse()
               for a in p.GetAttributes() if a.ValueMightBeTimeVarying()]
    assert varying == []
    (key,) = a.lights
    assert key.kind == "sphere" and key.radius <= 0.05        # small: hard shadows


def test_moving_light_moves_and_steps_on_at_13():
    fr = _frames("moving_light")
    pos = {f: _by_name(fs.lights, "/Moving").transform[:3, 3] for f, fs in fr.items()}
    assert np.linalg.norm(pos[24] - pos[1]) > 1.0                # metres
    assert np.linalg.norm(pos[13] - pos[12]) > 0.05
    step = {f: np.array(_by_name(fs.lights, "/Step").radiance) for f, fs in fr.items()}
    assert np.all(step[1] == 0) and np.all(step[12] == 0)
    assert np.all(step[13] > 0) and np.allclose(step[13], step[24])
    # the step is held: just before 13 it is still off
    st = _stage("moving_light")
    assert np.all(np.array(_by_name(load_frame(st, 12.99).lights, "/Step").radiance) == 0)


def test_door_ajar_door_swings_and_room_is_closed():
    fr = _frames("door_ajar")
    door = {f: _by_name(fs.instances, "/Door").transform for f, fs in fr.items()}
    assert not np.allclose(door[1], door[12])
    assert not np.allclose(door[12], door[13])
    assert not np.allclose(door[13], door[24])
    # the door's free edge (object z = 94 cm; object space is in scene units) moves
    # outwards (+x, metres) as it opens
    edge = {f: (m @ np.array([0.0, 100.0, 94.0, 1.0]))[:3] for f, m in door.items()}
    xs = [edge[f][0] for f in FRAMES]
    assert xs == sorted(xs) and xs[-1] - xs[0] > 0.5
    assert 0.0 < xs[0] - 2.6 < 0.05                 # frame 1: a slit of a few cm
    # the only light is outside the room (x > 2.6 m)
    (light,) = fr[1].lights
    assert light.transform[0, 3] > 2.6
