"""Motion blur over the camera shutter: only when the shutter is open and
something moves; the blurred edge matches the analytic linear ramp."""
import numpy as np
import pytest

import cmlt._core as core

from cmlt.scene import Camera, FrameScene, Instance, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage, stage_info

W, H = 40, 16
SHIFT = 0.5            # the quad moves +X by this much while the shutter is open


def _settings(spp, seed=5):
    st = core.RenderSettings()
    st.pixel_filter = "box"    # per-pixel analytic expectation: the one-pixel box
    st.width, st.height, st.spp, st.seed, st.threads, st.max_depth = W, H, spp, seed, 2, 2
    st.integrator = "pt"
    return st


def _trans(x):
    m = np.eye(4)
    m[0, 3] = x
    return m


def _frame(moving: bool):
    """An emissive quad x in [-3, 0] (its right edge at the image centre),
    seen by an orthographic camera 2 units wide (pixel = 0.05) on black."""
    quad = Mesh("/quad", padded_points([(-3, -3, 0), (0, -3, 0), (0, 3, 0), (-3, 3, 0)]),
                np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                material_ids=np.zeros(2, np.uint32))
    inst = Instance("/quad", 0, _trans(0.0), animated=True,
                    motion_transforms=[_trans(0.0), _trans(SHIFT)] if moving else None)
    cam = Camera("/cam", _trans(0.0) @ np.diag([1, 1, 1, 1.0]), projection="orthographic",
                 horizontal_aperture=20.0, vertical_aperture=8.0)
    cam.transform = cam.transform.copy()
    cam.transform[2, 3] = 5.0
    return FrameScene(time=1, meshes=[quad], instances=[inst],
                      materials=[Material("/e", diffuse=(0, 0, 0), emission=(1, 1, 1))],
                      camera=cam, resolution=(W, H), meters_per_unit=1.0)


def _column_centres():
    return -1.0 + (np.arange(W) + 0.5) * (2.0 / W)


def _expected_coverage():
    """Analytic: at x the quad covers a fraction clamp(1 - x / SHIFT, 0, 1) of
    the shutter (right edge moving 0 -> SHIFT); averaged over each pixel."""
    xs = -1.0 + (np.arange(W)[:, None] + (np.arange(2000)[None, :] + 0.5) / 2000) * (2.0 / W)
    return np.clip(1.0 - xs / SHIFT, 0.0, 1.0).mean(axis=1)


def test_01_moving_quad_blurs_as_a_linear_ramp():
    bridge = SceneBridge(core)
    scene = bridge.update(_frame(True))
    assert scene.motion_blur and bridge.last_update.motion_blurred == 1
    img = np.array(core.render(scene, _settings(64)).image)[..., 0]     # (H, W)
    expect = _expected_coverage()
    # pixel groups: each column over the H rows (same expectation); 99.9 % CI
    # from the spread between rows, Bonferroni over the columns
    mean = img.mean(axis=0)
    se = img.std(axis=0, ddof=1) / np.sqrt(H)
    z = 3.29 + np.log(W) * 0.25
    ramp = (expect > 0.02) & (expect < 0.98)
    assert ramp.sum() >= 8                           # the edge really is spread out
    tol = z * np.maximum(se, 1e-3) + 1e-3
    bad = np.abs(mean - expect) > tol
    assert not bad.any(), (mean[bad], expect[bad], tol[bad])
    # fully covered / uncovered columns are exact
    np.testing.assert_allclose(mean[expect >= 0.999], 1.0, atol=1e-6)
    np.testing.assert_allclose(mean[expect <= 0.0], 0.0, atol=1e-6)


def test_02_closed_shutter_gives_a_sharp_edge():
    scene = SceneBridge(core).update(_frame(False))
    assert not scene.motion_blur
    img = np.array(core.render(scene, _settings(16)).image)[..., 0]
    x = _column_centres()
    assert (img[:, x < -0.03] == 1.0).all() and (img[:, x > 0.03] == 0.0).all()


def test_03_no_motion_is_bit_identical_and_draws_no_time():
    """A scene that does not move pays nothing: no time steps, no ray time."""
    bridge = SceneBridge(core)
    scene = bridge.update(_frame(False))
    assert not scene.motion_blur and not bridge.last_update.motion_blur
    # a moving frame, then a still one: the instance goes back to one step
    bridge.update(_frame(True))
    assert bridge.scene.motion_blur
    bridge.update(_frame(False))
    assert not bridge.scene.motion_blur and bridge.last_update.motion_blurred == 0
    st = _settings(8)
    a = np.array(core.render(bridge.scene, st).image)
    b = np.array(core.render(SceneBridge(core).update(_frame(False)), st).image)
    assert np.array_equal(a, b)


SHOT = '''#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 3
    metersPerUnit = 1
)
def Xform "W"
{
    def Mesh "Quad"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
        double3 xformOp:translate.timeSamples = {1: (0, 0, 0), 2: (1, 0, 0), 3: (2, 0, 0)}
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def Mesh "Still"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-5, -5, -1), (5, -5, -1), (5, 5, -1), (-5, 5, -1)]
    }
    def Camera "Cam"
    {
        double shutter:open = SHUTTER_OPEN
        double shutter:close = SHUTTER_CLOSE
        double3 xformOp:translate = (0, 0, 10)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''


def _shot(tmp_path, o, c, animated=True):
    text = SHOT.replace("SHUTTER_OPEN", str(o)).replace("SHUTTER_CLOSE", str(c))
    if not animated:
        text = text.replace("xformOp:translate.timeSamples = {1: (0, 0, 0), 2: (1, 0, 0), "
                            "3: (2, 0, 0)}", "xformOp:translate = (0, 0, 0)")
    p = tmp_path / f"s_{o}_{c}_{animated}.usda"
    p.write_text(text)
    return open_stage(str(p))


def test_04_reader_decides_from_the_shutter(tmp_path):
    fs = load_frame(_shot(tmp_path, -0.25, 0.25), 2)
    assert fs.motion_blur and fs.motion_blur_reason.startswith("on:")
    # the authored sample at 2 lies inside [1.75, 2.25]: a third, middle step
    assert fs.motion_times == [1.75, 2.0, 2.25]
    quad = [i for i in fs.instances if i.name == "/W/Quad"][0]
    steps = quad.motion_transforms
    np.testing.assert_allclose([m[0, 3] for m in steps], [0.75, 1.0, 1.25])
    still = [i for i in fs.instances if i.name == "/W/Still"][0]
    assert still.motion_transforms is None and not still.animated
    # no sample strictly inside [2, 2.25]: the two ends
    fs = load_frame(_shot(tmp_path, 0, 0.25), 2)
    assert fs.motion_times == [2.0, 2.25]

    closed = load_frame(_shot(tmp_path, 0, 0), 2)
    assert not closed.motion_blur and "shutter closed" in closed.motion_blur_reason
    assert all(i.motion_transforms is None for i in closed.instances)
    still = load_frame(_shot(tmp_path, -0.25, 0.25, animated=False), 2)
    assert not still.motion_blur and "nothing is animated" in still.motion_blur_reason


def test_05_open_shutter_static_scene_is_bit_identical(tmp_path):
    st = _settings(4)
    st.width, st.height = 24, 16
    a = load_frame(_shot(tmp_path, -0.25, 0.25, animated=False), 2, resolution=(24, 16))
    b = load_frame(_shot(tmp_path, 0, 0, animated=False), 2, resolution=(24, 16))
    ia = np.array(core.render(SceneBridge(core).update(a), st).image)
    ib = np.array(core.render(SceneBridge(core).update(b), st).image)
    assert np.array_equal(ia, ib)


def test_06_inspect_reports_motion_blur(tmp_path):
    on = stage_info(_shot(tmp_path, -0.25, 0.25))
    assert on.motion_blur.startswith("on:") and "motion blur on:" in on.format()
    off = stage_info(_shot(tmp_path, 0, 0))
    assert off.motion_blur.startswith("off: shutter closed")
    assert "motion blur off" in off.format()
