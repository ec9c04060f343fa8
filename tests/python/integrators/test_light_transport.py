"""Light-transport gaps of issue 3, each with a check that failed before its fix.

1. Cut-out and ior-1 pass-through surfaces let shadow rays through (PT next-event
   estimation, BDPT connections), as they let camera and BSDF rays through:
   a floor lit by a point light through a cut-out quad, a textured cut-out and a
   partly transparent ior-1 veil against the closed form (direct light only); the
   Cornell box with a fully cut-out quad under its lamp against the box without it.
2. BDPT connects to a thin-lens camera (t = 1): PT and BDPT agree through an open lens;
   a point-light glass caustic (light tracing only) keeps its energy through the lens.
3. BDPT samples one shutter time per sample: PT and BDPT agree on a moving block, and
   so does PSSMLT's BDPT path sampler; coherent MLT's packets stay bit-identical.
4. pt traces lights smaller than a pixel from the light side too: pt and BDPT agree on a
   Cornell box with a 1 mm bulb in view.

Statistics. Closed forms: per 4x4-pixel block, |image - closed form| against the
block's standard error (film variance, independent passes) with z for a family-wise
false-alarm rate of 1e-3 over the blocks of a test. Estimator comparisons: K
independent seeds per estimator, block means compared with Welch's t statistic and
K - 1 degrees of freedom (conservative), Bonferroni over blocks at 1e-3 per test
(a correct renderer fails each such test about once in a thousand runs); the seed
spread is the error estimate, so correlations between pixels of one render
(BDPT's light-tracing splats, MLT chains) are accounted for.
"""
import math
from pathlib import Path

import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge

from support.scenes import cornell_scene, quad as _quad, uv_sphere as _uv_sphere, with_bulb
from support.stats import agree_over_seeds, block_means, t_critical

pytestmark = pytest.mark.statistical

ALPHA = 1e-3
SEEDS = 10


def _z_for(alpha):
    """Two-sided normal quantile by bisection: erfc(z / sqrt 2) = alpha."""
    lo, hi = 0.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if math.erfc(mid / math.sqrt(2)) > alpha else (lo, mid)
    return hi


def _settings(integrator, res, spp, seed, max_depth=5, **kw):
    st = core.RenderSettings()
    st.width, st.height = res
    st.spp, st.seed, st.threads, st.max_depth = spp, seed, 2, max_depth
    st.integrator = integrator
    for k, v in kw.items():
        setattr(st, k, v)
    return st


def _render(scene, integrator, res, spp, seed=1, **kw):
    r = core.render(scene, _settings(integrator, res, spp, seed, **kw))
    assert r.stats["nan_samples"] == 0
    img = np.asarray(r.image, np.float64)
    assert np.isfinite(img).all()
    return img, np.asarray(r.variance, np.float64), r.stats


# ---- 1. pass-through surfaces ---------------------------------------------------------

RES_A = (16, 16)
H_LIGHT = 1.5          # point light above the floor centre
R_LIGHT, L_LIGHT = 0.05, 360.0   # intensity pi r^2 L
ALBEDO = 0.5


def _floor_scene(occluder=None, occluder_inputs=None):
    """A 2.4 m Lambertian floor (albedo 0.5) under a point light at height 1.5, seen straight down
    by a camera at height 0.5 whose image is the floor square [-1, 1]^2 (the camera is
    below the occluder plane y = 1, so it never sees it). `occluder`: Material of a
    1.2 m quad at y = 1 covering every shadow ray of the visible floor (they cross it
    at a third of the floor point's offset), uv (0, 0) .. (1, 1) with u along +x."""
    # specular workflow with specularColor 0: an exact Lambertian (preview_surface.cpp)
    mats = [Material("/floor", diffuse=(ALBEDO,) * 3, use_specular_workflow=True)]
    meshes = [_quad("/floor", (0, 0, 0), (0, 0, 1.2), (1.2, 0, 0), 0)]
    if occluder is not None:
        mats.append(occluder)
        pts = padded_points([(-0.6, 1, -0.6), (0.6, 1, -0.6), (0.6, 1, 0.6), (-0.6, 1, 0.6)])
        uv = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], np.float32)
        meshes.append(Mesh("/occluder", pts, np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                           uvs=uv, material_ids=np.ones(2, np.uint32)))
    light_xf = np.eye(4)
    light_xf[:3, 3] = (0, H_LIGHT, 0)
    cam_xf = np.eye(4)
    cam_xf[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]   # looks down -y, image up = -z
    cam_xf[:3, 3] = (0, 0.5, 0)
    return FrameScene(
        time=1.0, meshes=meshes,
        instances=[Instance(m.name, i, np.eye(4)) for i, m in enumerate(meshes)],
        materials=mats,
        lights=[Light("/point", "sphere", light_xf, radiance=(L_LIGHT,) * 3, radius=R_LIGHT,
                      treat_as_point=True)],
        camera=Camera("/cam", cam_xf, focal_length=9, horizontal_aperture=36,
                      vertical_aperture=36),
        resolution=RES_A, meters_per_unit=1.0)


def _floor_closed_form(transmittance):
    """Per pixel, the mean over its floor square of the direct radiance
    albedo/pi * I cos / d^2 = albedo L r^2 h / d^3, times transmittance(x) (x: floor x)."""
    w, h = RES_A
    n = 32
    out = np.zeros((h, w))
    for py in range(h):
        for px in range(w):
            x = 2 * (px + (np.arange(n) + 0.5) / n) / w - 1
            z = 2 * (py + (np.arange(n) + 0.5) / n) / h - 1
            X, Z = np.meshgrid(x, z)
            d = np.sqrt(X * X + Z * Z + H_LIGHT ** 2)
            e = ALBEDO * L_LIGHT * R_LIGHT ** 2 * H_LIGHT / d ** 3
            out[py, px] = (e * transmittance(X)).mean()
    return out


def _check_closed_form(img, var, expect, what, mask=None):
    """4x4-pixel blocks (channel 0; the scene is grey) within z * stderr (+ a 1e-4
    relative allowance for the closed form's quadrature), family-wise 1e-3."""
    mask = np.ones(expect.shape, bool) if mask is None else mask
    got, v = img[..., 0], var[..., 0]
    n = block_means(mask.astype(float), 4) * 16
    keep = n > 0
    m = block_means(np.where(mask, got, 0), 4)[keep] * 16 / n[keep]
    e = block_means(np.where(mask, expect, 0), 4)[keep] * 16 / n[keep]
    se = np.sqrt(block_means(np.where(mask, v, 0), 4)[keep] * 256) / n[keep]
    z = _z_for(ALPHA / m.size)
    dev = np.abs(m - e) / (se + 1e-4 * e + 1e-12)
    print(f"[{what}] image mean {got[mask].mean():.5f} closed form {expect[mask].mean():.5f}, "
          f"max block |z| {dev.max():.2f} (limit {z:.2f})")
    assert (dev < z).all(), (what, m, e, se)


@pytest.fixture(scope="module")
def open_floor():
    return _floor_closed_form(lambda x: np.ones_like(x))


@pytest.mark.parametrize("integrator", ["pt", "bdpt"])
def test01_cut_out_quad_casts_no_shadow(integrator, open_floor):
    """A quad cut out everywhere (opacity 0 < opacityThreshold 0.5) is no surface: the
    floor gets the unoccluded direct light (0 before the fix, the quad's full shadow)."""
    cut = Material("/cut", diffuse=(0.8,) * 3, opacity=0.0, opacity_threshold=0.5)
    scene = SceneBridge(core).update(_floor_scene(cut))
    img, var, _ = _render(scene, integrator, RES_A, 64, max_depth=1)
    _check_closed_form(img, var, open_floor, f"cut-out {integrator}")
    assert scene.has_pass_through
    # the reference without the quad is the same closed form
    free = SceneBridge(core).update(_floor_scene())
    assert not free.has_pass_through
    img0, var0, _ = _render(free, integrator, RES_A, 64, max_depth=1)
    _check_closed_form(img0, var0, open_floor, f"no occluder {integrator}")


@pytest.mark.parametrize("integrator", ["pt", "bdpt"])
def test02_textured_cut_out_is_evaluated_at_the_hit(integrator, tmp_path):
    """Opacity from a texture's alpha: 0 for u < 1/2, 1 beyond (threshold 0.5). Shadow
    rays are cut out where the camera path would be: the floor is lit for x < 0 (its
    shadow rays cross the quad at x/3 < 0) and dark for x > 0."""
    import OpenImageIO as oiio
    tex = np.zeros((2, 4, 4), np.float32)
    tex[:, 2:, 3] = 1.0
    path = str(tmp_path / "alpha.exr")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(4, 2, 4, oiio.FLOAT))
    out.write_image(tex)
    out.close()
    rec = {"texture": path, "output": "a", "wrapS": "clamp", "wrapT": "clamp",
           "scale": (1, 1, 1, 1), "bias": (0, 0, 0, 0), "sourceColorSpace": "raw"}
    cut = Material("/cut", diffuse=(0.0,) * 3, opacity=1.0, opacity_threshold=0.5,
                   inputs={"opacity": rec})
    scene = SceneBridge(core).update(_floor_scene(cut))
    img, var, _ = _render(scene, integrator, RES_A, 64, max_depth=1)
    expect = _floor_closed_form(lambda x: (x < 0).astype(float))
    cols = np.arange(RES_A[0])
    # pixel columns 7 and 8 straddle x = 0
    mask = np.broadcast_to((cols <= 6) | (cols >= 9), expect.shape)
    _check_closed_form(img, var, expect, f"textured cut-out {integrator}", mask)
    assert img[:, 9:, 0].max() == 0.0 and img[:, :7, 0].min() > 0.0


@pytest.mark.parametrize("integrator", ["pt", "bdpt"])
def test03_ior_1_veil_transmits_one_minus_opacity(integrator, open_floor):
    """An ior-1 surface of opacity 0.3 (diffuse 0.5, so its pass-through lobe is picked
    with probability < 1) lets 0.7 of the light through at every angle."""
    veil = Material("/veil", diffuse=(0.5,) * 3, opacity=0.3, ior=1.0)
    scene = SceneBridge(core).update(_floor_scene(veil))
    img, var, _ = _render(scene, integrator, RES_A, 128, max_depth=1)
    _check_closed_form(img, var, 0.7 * open_floor, f"ior-1 veil {integrator}")


def _cornell_with(extra_quads, lens=None, moving_block=False):
    """test_pssmlt's Cornell box (support/scenes.py) (32 x 32), optionally with more quads (name, centre, u, v,
    Material), a thin lens (f_stop, focus distance) or a block sliding 0.8 m along x
    while the shutter is open."""
    fs = cornell_scene()
    for name, c, u, v, mat in extra_quads:
        fs.materials.append(mat)
        fs.meshes.append(_quad(name, c, u, v, len(fs.materials) - 1))
        fs.instances.append(Instance(name, len(fs.meshes) - 1, np.eye(4)))
    if lens is not None:
        fs.camera.f_stop, fs.camera.focus_distance = lens
    if moving_block:
        s = 0.3
        corners = [(x, y, z) for x in (-s, s) for y in (-s, s) for z in (-s, s)]
        idx = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                        [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]],
                       np.uint32)
        fs.materials.append(Material("/block", diffuse=(0.7, 0.7, 0.2)))
        fs.meshes.append(Mesh("/block", padded_points(corners), idx,
                              material_ids=np.full(12, len(fs.materials) - 1, np.uint32)))
        a = math.radians(25)
        rot = np.eye(4)
        rot[[0, 0, 2, 2], [0, 2, 0, 2]] = [math.cos(a), math.sin(a), -math.sin(a), math.cos(a)]
        steps = []
        for x in (-0.4, 0.4):
            m = rot.copy()
            m[:3, 3] = (x, 0.3, -0.2)
            steps.append(m)
        fs.instances.append(Instance("/block", len(fs.meshes) - 1, steps[0],
                                     motion_transforms=steps))
    return fs


def test04_cut_out_box_equals_the_box_without_it():
    """Area light, two bounces (max_depth 2): a fully cut-out quad under the lamp and
    one in front of the camera leave the Cornell box's image unchanged, for PT and
    BDPT (before the fix both lost light: shadow rays were blocked, and the crossing
    counted as a bounce). SEEDS seeds each against PT on the box without the quads."""
    cut = Material("/cut", diffuse=(0.8,) * 3, opacity=0.0, opacity_threshold=0.5)
    quads = [("/under_lamp", (0, 1.6, 0), (0.7, 0, 0), (0, 0, 0.7), cut),
             ("/in_front", (0, 1, 0.8), (0.95, 0, 0), (0, 0.95, 0), cut)]
    with_cut = SceneBridge(core).update(_cornell_with(quads))
    plain = SceneBridge(core).update(_cornell_with([]))
    res, seeds = (32, 32), range(SEEDS)
    ref = [_render(plain, "pt", res, 64, seed=100 + s, max_depth=2)[0] for s in seeds]
    for integ, spp in (("pt", 64), ("bdpt", 16)):
        runs = [_render(with_cut, integ, res, spp, seed=s, max_depth=2)[0] for s in seeds]
        agree_over_seeds(runs, ref, 8, f"cut-out box {integ} vs plain pt")


def test05_partly_transparent_veil_pt_and_bdpt_agree():
    """An ior-1 veil of opacity 0.4 across the Cornell box (pass-through probability < 1,
    weight 0.6), five bounces: PT and BDPT over SEEDS seeds each. (Before the fix both
    were consistent but crossed the veil only as a Dirac vertex; this checks the new
    crossing densities and BDPT's scattering probabilities of subpath ends.)"""
    veil = Material("/veil", diffuse=(0.5,) * 3, opacity=0.4, ior=1.0)
    scene = SceneBridge(core).update(
        _cornell_with([("/veil", (0, 1, -0.2), (0.95, 0, 0), (0, 0.95, 0), veil)]))
    res, seeds = (32, 32), range(SEEDS)
    pt = [_render(scene, "pt", res, 64, seed=s)[0] for s in seeds]
    bd = [_render(scene, "bdpt", res, 16, seed=50 + s)[0] for s in seeds]
    agree_over_seeds(pt, bd, 8, "veil pt vs bdpt")


# ---- 2. thin lens: light tracing to the lens ---------------------------------------------

def test06_thin_lens_pt_and_bdpt_agree():
    """Cornell box through a lens of radius 17.5 cm (f/1 at 35 cm focal length) focused
    at 3 m: a circle of confusion of about 2 pixels at the front and back of the box.
    BDPT's light tracing now reaches the film through the lens; its MIS weights include
    that strategy. PT and BDPT over SEEDS seeds each."""
    fs = _cornell_with([], lens=(1.0, 3.0))
    fs.camera.lens_unit = 0.01
    scene = SceneBridge(core).update(fs)
    res, seeds = (32, 32), range(SEEDS)
    pt = [_render(scene, "pt", res, 64, seed=s)[0] for s in seeds]
    bd = [_render(scene, "bdpt", res, 16, seed=50 + s)[0] for s in seeds]
    agree_over_seeds(pt, bd, 8, "thin lens pt vs bdpt")


def _caustic_scene(f_stop):
    """A smooth glass ball (radius 0.4) on a Lambertian floor, a point light low on its
    side: the caustic in the ball's shadow is an L S S D E path that only light tracing
    (t = 1) finds. Seen straight down from 3 m, focused on the floor (f/2, 36 mm)."""
    mats = [Material("/floor", diffuse=(0.7,) * 3, use_specular_workflow=True),
            Material("/glass", diffuse=(0.0,) * 3, opacity=0.0, ior=1.5, roughness=0.0)]
    floor = _quad("/floor", (0, 0, 0), (0, 0, 2.5), (2.5, 0, 0), 0)
    p, t, n = _uv_sphere(0.4)
    ball = Mesh("/ball", padded_points(p), t, normals=padded_points(n),
                material_ids=np.ones(len(t), np.uint32))
    ball_xf, light_xf, cam_xf = np.eye(4), np.eye(4), np.eye(4)
    ball_xf[:3, 3] = (0, 0.41, 0)
    light_xf[:3, 3] = (1.6, 1.0, 0)
    cam_xf[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    cam_xf[:3, 3] = (-0.8, 3, 0)
    cam = Camera("/cam", cam_xf, focal_length=36, horizontal_aperture=36, vertical_aperture=36,
                 f_stop=f_stop, focus_distance=3.0 if f_stop else 0.0)
    return FrameScene(
        time=1.0, meshes=[floor, ball],
        instances=[Instance("/floor", 0, np.eye(4)), Instance("/ball", 1, ball_xf)],
        materials=mats,
        lights=[Light("/point", "sphere", light_xf, radiance=(2000.0,) * 3, radius=0.02,
                      treat_as_point=True)],
        camera=cam, resolution=(32, 32), meters_per_unit=1.0)


def test07_point_light_caustic_survives_the_lens():
    """The caustic's energy (pixel box rows 12-18, cols 8-19, inside the ball's shadow)
    through the lens equals the pinhole's: Welch t over SEEDS seeds each, two-sided 1e-3.
    The floor is in focus, so the lens only moves light within a fraction of a pixel.
    Before the fix the lens disabled light tracing and the caustic vanished (the box
    kept only its faint indirect light: about a fifth)."""
    res, seeds, spp = (32, 32), range(SEEDS), 96
    box = (slice(12, 19), slice(8, 20))
    energy = {}
    for f_stop in (0.0, 2.0):
        scene = SceneBridge(core).update(_caustic_scene(f_stop))
        energy[f_stop] = np.array([
            _render(scene, "bdpt", res, spp, seed=s + (0 if f_stop else 100), max_depth=4)[0]
            [box][..., 0].mean() for s in seeds])
    a, b = energy[0.0], energy[2.0]
    se = math.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    t = abs(a.mean() - b.mean()) / se
    crit = t_critical(len(a) - 1, ALPHA)
    print(f"[caustic] box mean pinhole {a.mean():.5f} lens {b.mean():.5f} +- {se:.5f}, "
          f"|t| {t:.2f} (critical {crit:.2f})")
    assert t < crit
    # not vacuous: a loss of a quarter of the box's energy would be detected
    assert crit * se < 0.25 * a.mean(), (crit * se, a.mean())


# ---- 3. motion blur -------------------------------------------------------------------

@pytest.fixture(scope="module")
def moving_box():
    scene = SceneBridge(core).update(_cornell_with([], moving_block=True))
    assert scene.motion_blur
    return scene


@pytest.fixture(scope="module")
def moving_box_pt(moving_box):
    return [_render(moving_box, "pt", (32, 32), 64, seed=s)[0] for s in range(SEEDS)]


def test08_motion_blur_pt_and_bdpt_agree(moving_box, moving_box_pt):
    """A block sliding 0.8 m while the shutter is open: BDPT gives every ray of a sample
    the sample's shutter time, as PT does (before the fix BDPT rendered the block where
    it is at shutter open). SEEDS seeds each."""
    bd = [_render(moving_box, "bdpt", (32, 32), 16, seed=50 + s)[0] for s in range(SEEDS)]
    agree_over_seeds(moving_box_pt, bd, 8, "motion blur pt vs bdpt")


def test09_pssmlt_bdpt_sampler_draws_the_time_from_its_primary_samples(moving_box, moving_box_pt):
    """PSSMLT over BDPT (the default path sampler; its chains render depth >= 2, the
    direct pass depths 0-1 by PT) on the moving block: the shutter time is the camera
    stream's dimension 1 of the chain state, so the chains integrate over the shutter.
    Block means over SEEDS seeds against the PT runs (Welch t, family-wise 1e-3)."""
    runs = []
    for s in range(SEEDS):
        img, _, st = _render(moving_box, "pssmlt", (32, 32), 128, seed=200 + s, chains=256,
                             bootstrap_samples=32768)
        assert st["path_sampler"] == "bdpt"
        runs.append(img)
    agree_over_seeds(moving_box_pt, runs, 8, "motion blur pt vs pssmlt")


def test10_coherent_mlt_packets_match_scalar_with_motion_blur(moving_box):
    """Coherent MLT traces its bundles' rays as packets, at the shutter time BDPT's
    camera subpath draws (PssmltTracer::camera_ray): the packet hits are the scalar ones,
    bit for bit (with another time they would differ)."""
    kw = dict(chains=64, bootstrap_samples=4096, tries=8)
    a, _, _ = _render(moving_box, "cmlt", (32, 32), 32, seed=3, packets=True, **kw)
    b, _, _ = _render(moving_box, "cmlt", (32, 32), 32, seed=3, packets=False, **kw)
    assert np.array_equal(a, b)


def test10b_coherent_mlt_packets_match_scalar_through_pass_through_surfaces():
    """Packets for camera rays, walk bounces and shadow rays in the hardest case for
    them: a veil crossed stochastically (pass-through, ior 1), a cut-out quad under the
    lamp (occluded shadow rays step through it one by one), a thin lens and a moving
    block. Packets on and off give the same image and the same ray count, and packets
    answered shadow rays and closest hits beyond the camera rays."""
    veil = Material("/veil", diffuse=(0.5,) * 3, opacity=0.4, ior=1.0)
    cut = Material("/cut", diffuse=(0.8,) * 3, opacity=0.0, opacity_threshold=0.5)
    fs = _cornell_with([("/veil", (0, 1, -0.2), (0.95, 0, 0), (0, 0.95, 0), veil),
                        ("/under_lamp", (0, 1.6, 0), (0.7, 0, 0), (0, 0, 0.7), cut)],
                       lens=(1.0, 3.0), moving_block=True)
    fs.camera.lens_unit = 0.01
    scene = SceneBridge(core).update(fs)
    assert scene.has_pass_through
    kw = dict(chains=64, bootstrap_samples=4096, threads=2, tries=8, mlt_paths="all")
    on = core.render(scene, _settings("cmlt", (24, 16), 64, 7, packets=True, **kw))
    off = core.render(scene, _settings("cmlt", (24, 16), 64, 7, packets=False, **kw))
    assert np.array_equal(np.asarray(on.image), np.asarray(off.image))
    assert on.stats["rays"] == off.stats["rays"]
    st = on.stats
    assert st["packet_queries"] > 0 and off.stats["packet_queries"] == 0
    assert st["packet_shadow_rays"] > 0
    assert st["packet_rays"] - st["packet_shadow_rays"] > 0
    assert 0 < st["packet_ray_share"] <= 1
    assert np.isfinite(np.asarray(on.image)).all()


def test11_deterministic_over_thread_counts_with_the_new_features():
    """Lens, motion blur and pass-through surfaces together: BDPT and PSSMLT images are
    identical with 1 and 2 threads."""
    veil = Material("/veil", diffuse=(0.5,) * 3, opacity=0.4, ior=1.0)
    fs = _cornell_with([("/veil", (0, 1, -0.2), (0.95, 0, 0), (0, 0.95, 0), veil)],
                       lens=(1.0, 3.0), moving_block=True)
    fs.camera.lens_unit = 0.01
    scene = SceneBridge(core).update(fs)
    for integ, spp in (("bdpt", 4), ("pssmlt", 16)):
        one = core.render(scene, _settings(integ, (24, 16), spp, 9, threads=1, chains=64,
                                           bootstrap_samples=4096))
        two = core.render(scene, _settings(integ, (24, 16), spp, 9, threads=2, chains=64,
                                           bootstrap_samples=4096))
        assert np.array_equal(np.asarray(one.image), np.asarray(two.image)), integ


# ---- 4. lights smaller than a pixel in pt ---------------------------------------------

@pytest.mark.parametrize("pixel_filter", ["box", "gaussian"])
def test12_pt_traces_a_sub_pixel_bulb_from_the_light_side(pixel_filter):
    """pt's camera rays hit the bulb rarely (it covers a small part of its pixel); it is
    traced from the light side too (lens_light_tracing.h), MIS-weighted against those hits. pt
    and bdpt agree per 4x4 block over 10 seeds each (without the light-side samples the
    bulb's block is missing its energy in every render that does not hit it, and a
    render that does is far off), and pt's image is the same with 1 and 2 threads."""
    scene = SceneBridge(core).update(with_bulb(cornell_scene()))
    res, kw = (32, 32), dict(max_depth=4, pixel_filter=pixel_filter)
    pt_runs, bd_runs = [], []
    for seed in range(1, SEEDS + 1):
        img, _, st = _render(scene, "pt", res, 16, seed, **kw)
        assert st["lens_lights"] == 1
        pt_runs.append(img)
        bd_runs.append(_render(scene, "bdpt", res, 4, seed, **kw)[0])
    agree_over_seeds(pt_runs, bd_runs, 4, f"pt vs bdpt, sub-pixel bulb, {pixel_filter}")
    one = core.render(scene, _settings("pt", res, 4, 3, threads=1, **kw))
    assert np.array_equal(np.asarray(one.image), np.asarray(core.render(scene, _settings("pt", res, 4, 3, **kw)).image))


# ---- 5. the diffuse lanes --------------------------------------------------------------

def test13_pt_shades_lambertian_hits_in_lanes_with_and_without_packets():
    """pt places the hits of static instances in structure-of-arrays lanes and shades
    constant-Lambertian ones there (src/core/integrators/path/diffuse_lanes.h), with
    packets or without: the sidecar's ``lane_hits`` counts them, within 1 % either way (packets change only
    Embree's last-ulp hits), fewer than the surface hits (the moving block is placed at
    each ray's time, outside the lanes), and the two images are close. (ior 1 and no
    metal: no specular lobe, so the diffuse-only kernel renders the walls as Lambertian,
    Scene::constant_lambert.)"""
    fs = _cornell_with([], moving_block=True)
    for m in fs.materials:
        m.ior = 1.0
    scene = SceneBridge(core).update(fs)
    on = core.render(scene, _settings("pt", (32, 32), 8, 5, packets=True))
    off = core.render(scene, _settings("pt", (32, 32), 8, 5, packets=False))
    hits = on.stats["rays"] - on.stats["shadow_rays"]
    assert 0 < on.stats["lane_hits"] < hits
    assert on.stats["lane_hits"] == pytest.approx(off.stats["lane_hits"], rel=0.01)
    assert np.abs(np.asarray(on.image) - np.asarray(off.image)).mean() < 0.05 * np.asarray(off.image).mean()
