"""Textures through the bridge: an sRGB-authored 8-bit texture on a quad's
emissiveColor arrives as OCIO's ACEScg value of each texel; a missing file
warns naming the material and the file and keeps the fallback."""
import numpy as np
import pytest

import cmlt._core as core

from cmlt.scene import Camera, FrameScene, Instance, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge


def _quad_scene(tex_input, res=(32, 32)):
    pts = padded_points([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    uv = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], np.float32)
    quad = Mesh("/quad", pts, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), uvs=uv)
    xf = np.eye(4)
    xf[2, 3] = 10.0
    # the quad (2 m) exactly fills a 36 mm aperture at 10 m with f = 180 mm
    cam = Camera("/cam", xf, focal_length=180, horizontal_aperture=36, vertical_aperture=36)
    mat = Material("/M", diffuse=(0, 0, 0), emission=(0.25, 0.25, 0.25),
                   use_specular_workflow=True, inputs={"emissiveColor": tex_input})
    return FrameScene(time=1.0, meshes=[quad], instances=[Instance("/quad", 0, np.eye(4))],
                      materials=[mat], camera=cam, resolution=res, meters_per_unit=1.0)


def _render(fs, spp=4):
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.max_depth, st.seed, st.threads = spp, 1, 1, 2
    st.integrator = "pt"
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


def test01_srgb_texture_arrives_as_acescg(tmp_path):
    import OpenImageIO as oiio
    from cmlt.usd.color import load_texture
    texels = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [200, 150, 50]]], np.uint8)
    path = str(tmp_path / "t.png")
    big = np.ascontiguousarray(np.repeat(np.repeat(texels, 4, 0), 4, 1))  # flat 4x4 blocks
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(8, 8, 3, oiio.UINT8))
    out.write_image(big)
    out.close()
    expected = load_texture(path, "sRGB")[::4, ::4]  # OCIO's ACEScg values, row 0 on top
    assert not np.allclose(expected[..., :3], texels / 255.0, atol=1e-3)   # really converted
    rec = {"texture": path, "output": "rgb", "wrapS": "clamp", "wrapT": "clamp",
           "scale": (1, 1, 1, 1), "bias": (0, 0, 0, 0), "sourceColorSpace": "sRGB"}
    img = _render(_quad_scene(rec))
    # the centre of each image quadrant sees one flat texel block
    for (r, c), (y, x) in {(0, 0): (8, 8), (0, 1): (8, 24), (1, 0): (24, 8), (1, 1): (24, 24)}.items():
        np.testing.assert_allclose(img[y, x], expected[r, c, :3], rtol=1e-4, atol=1e-6)


def test02_missing_texture_warns_and_uses_fallback(tmp_path):
    rec = {"texture": str(tmp_path / "nope.png"), "output": "rgb", "sourceColorSpace": "sRGB"}
    with pytest.warns(UserWarning, match=r"/M.*nope\.png"):
        img = _render(_quad_scene(rec), spp=1)
    np.testing.assert_allclose(img[16, 16], 0.25, rtol=1e-5)


def test03_wrap_modes_and_scale_bias():
    s = core.Scene()
    img = np.arange(12, dtype=np.float32).reshape(2, 2, 3)
    assert s.add_texture(img, "mirror", "black", (2, 2, 2, 1), (1, 0, 0, 0)) == 0
    with pytest.raises(ValueError, match="wrap_s"):
        s.add_texture(img, "bogus")
    with pytest.raises(TypeError, match="float32"):
        s.add_texture(img.astype(np.float64))
