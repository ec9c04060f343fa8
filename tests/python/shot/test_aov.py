"""AOVs (issue 6): the core's integrator-independent pass and the EXR channels.

A quad facing the camera at a known distance d: depth is d wherever the quad
is seen (distance along the camera axis, not along the ray), normals are unit
length and face the camera, albedo is the material's ACEScg diffuse colour;
misses are 0 in every AOV.
"""
from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest

import cmlt._core as core
from cmlt.cli import main
from cmlt.color import load_config, set_config
from cmlt.color import to_rendering_space as acescg
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage
from support.stages import exr_channels, facing_quad_shot

D = 5.0
DIFFUSE = (0.8, 0.3, 0.1)        # authored, untagged: linear Rec.709

PLANE_SHOT = facing_quad_shot(D, DIFFUSE)
W, H = 48, 32


@pytest.fixture(autouse=True)
def builtin_config(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)


@pytest.fixture
def plane_shot(tmp_path):
    p = tmp_path / "plane.usda"
    p.write_text(PLANE_SHOT)
    return str(p)


def _aovs(shot, samples=4, threads=0, seed=0, pixel_filter="box"):
    """The AOVs; box by default (the per-pixel analytic expectations are of the
    one-pixel box)."""
    fs = load_frame(open_stage(shot), 1, resolution=(W, H))
    scene = SceneBridge(core).update(fs)
    st = core.RenderSettings()
    st.pixel_filter = pixel_filter
    st.width, st.height, st.threads, st.seed = W, H, threads, seed
    return core.render_aovs(scene, st, samples=samples)


def _inside(x, y):
    """Pixel (x, y) entirely on the quad (with a pixel of margin)."""
    # raster -> window (mm at focal 24): x in [-18, 18], y in [-12, 12]
    def wx(px):
        return (px / W - 0.5) * 36.0
    def wy(py):
        return (0.5 - py / H) * 24.0
    lo_x, hi_x = wx(x - 1) * D / 24, wx(x + 2) * D / 24
    lo_y, hi_y = wy(y + 2) * D / 24, wy(y - 1) * D / 24
    return -1.5 < lo_x and hi_x < 1.5 and -1 < lo_y and hi_y < 1


def _outside(x, y):
    def wx(px):
        return (px / W - 0.5) * 36.0 * D / 24
    def wy(py):
        return (0.5 - py / H) * 24.0 * D / 24
    return min(wx(x), wx(x + 1)) > 1.5 or max(wx(x), wx(x + 1)) < -1.5 or \
        min(wy(y), wy(y + 1)) > 1 or max(wy(y), wy(y + 1)) < -1


def test01_shapes_dtypes_and_no_nan(plane_shot):
    a = _aovs(plane_shot)
    assert set(a) == {"albedo", "N", "Z"}
    assert a["albedo"].shape == (H, W, 3) and a["N"].shape == (H, W, 3) and a["Z"].shape == (H, W)
    for v in a.values():
        assert v.dtype == np.float32 and np.isfinite(v).all()


def test02_depth_normals_albedo_of_a_known_plane(plane_shot):
    a = _aovs(plane_shot)
    inside = np.array([[_inside(x, y) for x in range(W)] for y in range(H)])
    outside = np.array([[_outside(x, y) for x in range(W)] for y in range(H)])
    assert inside.sum() > 50 and outside.sum() > 50
    # depth along the camera axis: d everywhere on the plane, also off-centre
    np.testing.assert_allclose(a["Z"][inside], D, rtol=1e-5)
    assert (a["Z"][outside] == 0).all()
    hit = a["Z"] > 0
    n = np.linalg.norm(a["N"], axis=2)
    np.testing.assert_allclose(n[hit], 1.0, atol=1e-5)               # unit where hit
    np.testing.assert_allclose(a["N"][inside], np.broadcast_to([0, 0, 1], (inside.sum(), 3)),
                               atol=1e-6)                             # facing the camera
    assert (a["N"][outside] == 0).all()
    want = np.array(acescg(DIFFUSE, "lin_rec709"), dtype=np.float32)
    assert not np.allclose(want, DIFFUSE, atol=1e-2)                  # really converted
    np.testing.assert_allclose(a["albedo"][inside], np.broadcast_to(want, (inside.sum(), 3)),
                               rtol=1e-6)
    assert (a["albedo"][outside] == 0).all()


def test03_deterministic_across_thread_counts_and_seeded(plane_shot):
    a1 = _aovs(plane_shot, threads=1)
    a2 = _aovs(plane_shot, threads=2)
    for k in a1:
        np.testing.assert_array_equal(a1[k], a2[k])
    other = _aovs(plane_shot, seed=7)
    inside = np.array([[_inside(x, y) for x in range(W)] for y in range(H)])
    assert not np.array_equal(other["albedo"], a1["albedo"])   # another jitter at the edges
    np.testing.assert_allclose(other["Z"][inside], a1["Z"][inside], rtol=1e-6)


def test04_bad_arguments():
    scene = core.Scene()
    st = core.RenderSettings()
    with pytest.raises(core.SceneError, match="no camera"):
        core.render_aovs(scene, st)
    with pytest.raises(core.SettingsError, match="samples"):
        core.render_aovs(scene, st, samples=0)


_channels = exr_channels


def test05_cli_writes_aov_channels_with_standard_names(plane_shot, tmp_path, capsys):
    out = str(tmp_path / "r" / "p.####.exr")
    code = main(["render", plane_shot, "--frames", "1", "--out", out, "--spp", "4",
                 "--res", f"{W}x{H}", "--aov", "albedo,normal,depth,variance", "--quiet",
                 "--pixel-filter", "gaussian"])
    assert code == 0, capsys.readouterr().err
    spec, ch = _channels(str(tmp_path / "r" / "p.0001.exr"))
    names = set(spec.channelnames)
    assert {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z",
            "variance.R", "variance.G", "variance.B"} == names
    assert spec.z_channel == list(spec.channelnames).index("Z")
    ref = _aovs(plane_shot, pixel_filter="gaussian")   # the filter asked for
    np.testing.assert_array_equal(ch["Z"], ref["Z"])
    np.testing.assert_array_equal(np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], -1), ref["N"])
    np.testing.assert_array_equal(np.stack([ch["albedo.R"], ch["albedo.G"], ch["albedo.B"]], -1),
                                  ref["albedo"])
    var = np.stack([ch["variance.R"], ch["variance.G"], ch["variance.B"]], -1)
    assert np.isfinite(var).all() and (var >= 0).all() and var.max() > 0


def test06_half_keeps_depth_float(plane_shot, tmp_path, capsys):
    out = str(tmp_path / "h.exr")
    assert main(["render", plane_shot, "--out", out, "--spp", "1", "--res", f"{W}x{H}",
                 "--aov", "depth,normal", "--half", "--quiet"]) == 0
    spec, ch = _channels(out)
    fmts = dict(zip(spec.channelnames, spec.channelformats))
    assert fmts["Z"] == oiio.FLOAT and fmts["R"] == oiio.HALF and fmts["N.X"] == oiio.HALF


@pytest.mark.parametrize("bad", ["foo", "albedo,nrm", ","])
def test07_unknown_aov_is_a_one_line_error_naming_the_flag(plane_shot, tmp_path, capsys, bad):
    code = main(["render", plane_shot, "--out", str(tmp_path / "x.exr"), "--aov", bad])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--aov" in err[0] and err[0].startswith("cmlt: error:")
    assert not (tmp_path / "x.exr").exists()


# ---- textured materials (issue 3: the AOVs use the integrators' textured material) ----

def _write_exr(path, texels):
    out = oiio.ImageOutput.create(path)
    h, w, c = texels.shape
    out.open(path, oiio.ImageSpec(w, h, c, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(texels, dtype=np.float32))
    out.close()


def _textured_plane(tmp_path, inputs):
    """The plane of PLANE_SHOT (3 x 2 m at distance D, facing the camera), with uvs
    (0, 0) .. (1, 1) over it (dp/du = +X) and the given UsdPreviewSurface inputs."""
    from cmlt.scene import Camera, FrameScene, Instance, Material, Mesh, padded_points
    pts = padded_points([(-1.5, -1, -D), (1.5, -1, -D), (1.5, 1, -D), (-1.5, 1, -D)])
    uv = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], np.float32)
    quad = Mesh("/quad", pts, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), uvs=uv,
                material_ids=np.zeros(2, np.uint32))
    cam = Camera("/cam", np.eye(4), focal_length=24, horizontal_aperture=36,
                 vertical_aperture=24)
    mat = Material("/M", diffuse=(0.5, 0.5, 0.5), inputs=inputs)
    fs = FrameScene(time=1.0, meshes=[quad], instances=[Instance("/quad", 0, np.eye(4))],
                    materials=[mat], camera=cam, resolution=(W, H), meters_per_unit=1.0)
    scene = SceneBridge(core).update(fs)
    st = core.RenderSettings()
    st.width, st.height, st.threads, st.seed = W, H, 2, 0
    return core.render_aovs(scene, st, samples=4)


def _raw_texture(path, output="rgb", scale=(1, 1, 1, 1), bias=(0, 0, 0, 0)):
    return {"texture": str(path), "output": output, "wrapS": "clamp", "wrapT": "clamp",
            "scale": scale, "bias": bias, "sourceColorSpace": "raw"}


def test08_albedo_reads_the_diffuse_texture(tmp_path):
    """Left half of the texture red, right half blue (raw values, no conversion): the
    albedo AOV is the texel colour on each side, not the constant grey fallback (which
    it was when the AOV read the material's constant diffuse)."""
    red, blue = (0.9, 0.05, 0.02), (0.03, 0.1, 0.8)
    tex = np.zeros((2, 4, 3), np.float32)
    tex[:, :2] = red
    tex[:, 2:] = blue
    _write_exr(str(tmp_path / "d.exr"), tex)
    a = _textured_plane(tmp_path, {"diffuseColor": _raw_texture(tmp_path / "d.exr")})
    inside = np.array([[_inside(x, y) for x in range(W)] for y in range(H)])
    xs = np.arange(W)[None, :].repeat(H, 0)
    # 1 px = 0.156 m on the plane; a texel is 0.75 m wide, and the bilinear blend of the
    # two colours covers x in [-0.375, 0.375] m (raster x 21.6..26.4): stay outside it by
    # the default gaussian's reach (radius 1.5 px: pixel 20, centre 20.5, takes samples
    # up to x = 22.0, pixel 27 from x = 26.0)
    left = inside & (xs <= W // 2 - 5)
    right = inside & (xs >= W // 2 + 4)
    assert left.sum() > 20 and right.sum() > 20
    np.testing.assert_allclose(a["albedo"][left], np.broadcast_to(red, (left.sum(), 3)), rtol=1e-5)
    np.testing.assert_allclose(a["albedo"][right], np.broadcast_to(blue, (right.sum(), 3)),
                               rtol=1e-5)


def test09_normal_reads_the_normal_map(tmp_path):
    """A constant tangent-space normal map (0.6, 0, 0.8) after scale 2 / bias -1 tilts
    the shading normal toward +X (dp/du): the normal AOV is that normal in world space
    (it was the plane's (0, 0, 1) when the AOV ignored normal maps)."""
    n_tangent = np.array([0.6, 0.0, 0.8])
    tex = np.broadcast_to((n_tangent + 1) / 2, (2, 2, 3)).astype(np.float32)
    _write_exr(str(tmp_path / "n.exr"), tex)
    a = _textured_plane(tmp_path, {"normal": _raw_texture(tmp_path / "n.exr", scale=(2, 2, 2, 1),
                                                          bias=(-1, -1, -1, 0))})
    inside = np.array([[_inside(x, y) for x in range(W)] for y in range(H)])
    assert inside.sum() > 50
    np.testing.assert_allclose(a["N"][inside], np.broadcast_to(n_tangent, (inside.sum(), 3)),
                               atol=1e-5)
    # the albedo stays the constant fallback without a diffuse texture
    np.testing.assert_allclose(a["albedo"][inside], 0.5, rtol=1e-6)
