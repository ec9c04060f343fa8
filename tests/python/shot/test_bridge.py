"""The FrameScene -> core.Scene bridge: incremental updates must give the
same image as a fresh build (same seed), and must really update."""
import numpy as np
import pytest

import cmlt._core as core   # the real core: an ImportError is a failure, not a skip

from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage
from support.scenes import look_down_camera, plane, rot_x, tent, tent_frame


def _settings(w=32, h=24, spp=4, seed=11):
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.seed, st.threads, st.max_depth = w, h, spp, seed, 2, 8
    st.integrator = "pt"
    return st


def _render(scene, st):
    r = core.render(scene, st)
    assert not r.cancelled
    img = np.array(r.image, copy=True)
    assert np.isfinite(img).all()
    return img


def test_01_incremental_equals_fresh_on_usd_shot(tiny_shot):
    stage = open_stage(tiny_shot)
    f1, f2 = load_frame(stage, 1), load_frame(stage, 2)
    st = _settings(*f1.resolution)

    incremental = SceneBridge(core)
    img1 = _render(incremental.update(f1), st)
    assert incremental.last_update.rebuilt
    img2_inc = _render(incremental.update(f2), st)
    rep = incremental.last_update
    assert not rep.rebuilt and rep.transforms_updated == 1 and rep.meshes_updated == 0

    img2_fresh = _render(SceneBridge(core).update(f2), st)
    assert not np.array_equal(img1, img2_fresh)        # the frames do differ...
    np.testing.assert_allclose(img2_inc, img2_fresh, rtol=1e-5, atol=1e-6)  # ...and agree


def test_02_deforming_mesh_and_transform_incremental_equals_fresh():
    a, b = tent_frame(1, 0.3, 0.0), tent_frame(2, 1.2, 0.4)
    st = _settings()
    bridge = SceneBridge(core)
    img_a = _render(bridge.update(a), st)
    img_b_inc = _render(bridge.update(b), st)
    rep = bridge.last_update
    assert not rep.rebuilt and rep.meshes_updated == 1 and rep.transforms_updated == 1
    img_b_fresh = _render(SceneBridge(core).update(b), st)
    assert not np.array_equal(img_a, img_b_fresh)
    np.testing.assert_allclose(img_b_inc, img_b_fresh, rtol=1e-5, atol=1e-6)


def test_03_unchanged_frame_updates_nothing():
    bridge = SceneBridge(core)
    bridge.update(tent_frame(1, 0.3, 0.0))
    bridge.update(tent_frame(2, 0.3, 0.0))
    rep = bridge.last_update
    assert (rep.rebuilt, rep.meshes_updated, rep.transforms_updated) == (False, 0, 0)


def test_04_topology_change_rebuilds():
    bridge = SceneBridge(core)
    st = _settings()
    bridge.update(tent_frame(1, 0.3, 0.0))
    changed = tent_frame(2, 0.3, 0.0)
    changed.meshes[1] = Mesh("/tent", changed.meshes[1].points,
                             changed.meshes[1].indices[:2].copy(), deforming=True)
    img_inc = _render(bridge.update(changed), st)
    assert bridge.last_update.rebuilt and "indices" in bridge.last_update.reason
    np.testing.assert_array_equal(img_inc, _render(SceneBridge(core).update(changed), st))
    # an added instance also rebuilds
    more = tent_frame(3, 0.3, 0.0)
    more.meshes[1] = changed.meshes[1]
    more.instances.append(Instance("/tent2", 1, np.eye(4)))
    bridge.update(more)
    assert bridge.last_update.rebuilt and "instance count" in bridge.last_update.reason


def test_05_material_change_is_sent():
    bridge = SceneBridge(core)
    st = _settings()
    img_white = _render(bridge.update(tent_frame(1, 0.3, 0.0)), st)
    red = tent_frame(2, 0.3, 0.0)
    red.materials = [Material("/white", diffuse=(0.7, 0.1, 0.1))]
    img_red = _render(bridge.update(red), st)
    assert bridge.last_update.materials_updated and not bridge.last_update.rebuilt
    assert img_red[..., 1].mean() < 0.5 * img_white[..., 1].mean()
    np.testing.assert_allclose(img_red, _render(SceneBridge(core).update(red), st),
                               rtol=1e-5, atol=1e-6)
