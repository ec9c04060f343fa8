"""DomeLight / RectLight textures through the bridge: a lat-long EXR on a dome is
seen by escaping camera rays with the UsdLux (OpenEXR latlong, +Y up) orientation,
converted to the rendering space; a textured rect light shows its texture the right
way round from the emitting side; an unreadable light texture warns and keeps the
untextured light."""
import numpy as np
import pytest

import cmlt._core as core

from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge


def _write_exr(path, img):
    import OpenImageIO as oiio
    h, w, c = img.shape
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(w, h, c, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(img, np.float32))
    out.close()


def _rot_y(deg):
    a = np.radians(deg)
    m = np.eye(4)
    m[0, 0], m[0, 2], m[2, 0], m[2, 2] = np.cos(a), np.sin(a), -np.sin(a), np.cos(a)
    return m


def _far_quad():
    # A tiny quad far below the camera (the core wants a mesh; it is never seen).
    pts = padded_points([(-1e-3, -1e3, 0), (1e-3, -1e3, 0), (0, -1e3, 1e-3)])
    return Mesh("/q", pts, np.array([[0, 1, 2]], np.uint32))


def _render(fs, spp=4):
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.max_depth, st.seed, st.threads = spp, 1, 1, 2
    st.integrator = "pt"
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


def _dome_scene(path, cam_yaw):
    # camera looks down its -Z; yaw turns it about +Y (yaw 180: looking along +Z)
    cam = Camera("/cam", _rot_y(cam_yaw), focal_length=500, horizontal_aperture=10,
                 vertical_aperture=10)
    dome = Light("/dome", "dome", np.eye(4), radiance=(2.0, 2.0, 2.0), texture=path)
    return FrameScene(time=1.0, meshes=[_far_quad()], instances=[Instance("/q", 0, np.eye(4))],
                      materials=[Material("/M")], lights=[dome], camera=cam, resolution=(8, 8),
                      meters_per_unit=1.0)


def test01_dome_latlong_orientation(tmp_path):
    from cmlt.usd.color import load_texture
    w, h = 16, 8
    img = np.full((h, w, 3), 0.1, np.float32)
    img[:, 3:5] = (1.0, 0.0, 0.0)    # s ~ 0.25: longitude +pi/2 -> light-space +X
    img[:, 7:9] = (0.0, 1.0, 0.0)    # s ~ 0.5: longitude 0 -> +Z
    img[:, 11:13] = (0.0, 0.0, 1.0)  # s ~ 0.75: -X
    path = str(tmp_path / "env.exr")
    _write_exr(path, img)
    conv = load_texture(path, "auto")   # linear Rec.709 -> ACEScg, as the bridge loads it
    expect = {180: conv[4, 8], -90: conv[4, 4], 90: conv[4, 12]}  # +Z, +X, -X
    for yaw, want in expect.items():
        got = _render(_dome_scene(path, yaw))[4, 4]
        np.testing.assert_allclose(got, 2.0 * want, rtol=1e-3, atol=1e-5, err_msg=f"yaw {yaw}")
    # Looking straight up (+Y) sees the top row.
    assert not np.allclose(conv[4, 8], conv[4, 4])


def test02_rect_light_texture_orientation(tmp_path):
    # Left half of the image (s < 0.5) white: UsdLux puts st min at local (+X, +Y),
    # so a camera on the emitting side (-Z, looking toward +Z) sees white on its left.
    img = np.zeros((8, 8, 3), np.float32)
    img[:, :4] = 1.0
    path = str(tmp_path / "rect.exr")
    _write_exr(path, img)
    xf = np.eye(4)
    xf[2, 3] = -5.0
    cam = Camera("/cam", xf @ _rot_y(180), focal_length=50, horizontal_aperture=10,
                 vertical_aperture=10)
    rect = Light("/rect", "rect", np.eye(4), radiance=(3.0, 3.0, 3.0), width=1.0, height=1.0,
                 texture=path)
    fs = FrameScene(time=1.0, meshes=[_far_quad()], instances=[Instance("/q", 0, np.eye(4))],
                    materials=[Material("/M")], lights=[rect], camera=cam, resolution=(32, 32),
                    meters_per_unit=1.0)
    out = _render(fs)
    # camera at z = -5 looking +Z: image left = world +X = st s small = white
    assert out[16, 13].mean() > 2.0, out[16, 13]
    assert out[16, 18].mean() < 0.5, out[16, 18]


def test03_missing_light_texture_warns(tmp_path):
    with pytest.warns(UserWarning, match=r"/dome.*nope\.exr"):
        out = _render(_dome_scene(str(tmp_path / "nope.exr"), 180), spp=1)
    np.testing.assert_allclose(out[4, 4], 2.0, rtol=1e-5)
