"""The core refuses bad scene arrays with messages that name its call (``add_light:
radiance must be finite and >= 0``); through the bridge they name the prim that holds
the bad value, for scenes built through the Python scene API as well as from USD."""
import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Light
from cmlt.shot.bridge import BridgeError, SceneBridge
from support.scenes import cornell_scene


def _light(**kw):
    xf = np.eye(4)
    xf[:3, 3] = (0, 1.5, 0)
    args = dict(radiance=(1.0, 1.0, 1.0), radius=0.1)
    args.update(kw)
    return Light("/World/Lamp", "sphere", xf, **args)


@pytest.mark.parametrize("kw, fragment", [
    ({"radiance": (-5.0, 1.0, 1.0)}, "radiance"),
    ({"radiance": (float("nan"), 1.0, 1.0)}, "radiance"),
    ({"radius": -0.1}, "radius"),
])
def test01_bad_light_names_the_light(kw, fragment):
    fs = cornell_scene()
    fs.lights = [_light(**kw)]
    with pytest.raises(BridgeError) as err:
        SceneBridge(core).update(fs)
    msg = str(err.value)
    assert msg.startswith("/World/Lamp: light: ") and fragment in msg, msg
    assert "add_light" not in msg


def test02_bad_material_names_the_material():
    fs = cornell_scene()
    fs.materials[3].emission = (-1.0, 0.0, 0.0)
    with pytest.raises(BridgeError) as err:
        SceneBridge(core).update(fs)
    msg = str(err.value)
    assert msg.startswith("/light: material emission"), msg
    assert "set_materials" not in msg


def test03_bad_material_on_a_later_frame_names_it_too():
    fs = cornell_scene()
    bridge = SceneBridge(core)
    bridge.update(fs)
    fs.materials[0].diffuse = (float("inf"), 0.5, 0.5)
    with pytest.raises(BridgeError, match=r"^/white: material diffuse"):
        bridge.update(fs)


def test04_good_scene_still_builds():
    fs = cornell_scene()
    fs.lights = [_light()]
    assert SceneBridge(core).update(fs) is not None
