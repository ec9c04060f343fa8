"""An analytic check of the whole Python -> core path: a diffuse plane
(albedo a) under a uniform dome (radiance L), direct light only
(max_depth 1). Every point of the plane sees the full upper hemisphere, so
the irradiance is pi*L and the outgoing radiance is (a/pi)*pi*L = a*L in
every pixel and channel."""
import numpy as np
import pytest

import cmlt._core as core

from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge

ALBEDO = np.array([0.2, 0.5, 0.8])
RADIANCE = np.array([1.5, 1.0, 0.5])


def _scene():
    s = 1000.0                       # "infinite": the camera sees nothing else
    pts = padded_points([(-s, 0, -s), (s, 0, -s), (s, 0, s), (-s, 0, s)])
    plane = Mesh("/plane", pts, np.array([[0, 2, 1], [0, 3, 2]], np.uint32))
    # camera 1 m above the plane, looking straight down (local -Z -> world -Y)
    cam_xf = np.array([[1, 0, 0, 0], [0, 0, 1, 1], [0, -1, 0, 0], [0, 0, 0, 1]], float)
    return FrameScene(
        time=1.0, meshes=[plane], instances=[Instance("/plane", 0, np.eye(4))],
        # specular workflow with specularColor 0: UsdPreviewSurface's exact Lambertian
        materials=[Material("/m", diffuse=tuple(ALBEDO), use_specular_workflow=True)],
        lights=[Light("/dome", "dome", np.eye(4), radiance=tuple(RADIANCE))],
        camera=Camera("/cam", cam_xf, focal_length=35, horizontal_aperture=36,
                      vertical_aperture=36),
        resolution=(48, 48), meters_per_unit=1.0)


@pytest.mark.statistical
@pytest.mark.parametrize("sampler", ["independent", "sobol"])
def test_diffuse_plane_under_uniform_dome(sampler):
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.max_depth, st.seed, st.threads = 48, 48, 16, 1, 5, 2
    st.integrator, st.sampler = "pt", sampler
    r = core.render(SceneBridge(core).update(_scene()), st)
    img = np.asarray(r.image, dtype=np.float64)
    var = np.asarray(r.variance, dtype=np.float64)
    assert img.shape == var.shape == (48, 48, 3)
    assert np.isfinite(img).all() and (var >= 0).all()
    n = img.shape[0] * img.shape[1]
    expected = ALBEDO * RADIANCE
    mean = img.reshape(-1, 3).mean(0)
    # r.variance is the variance of each pixel's estimate (with Sobol points an
    # upper bound); pixels are independent, so the variance of the image mean is
    # sum(var)/n^2
    se = np.sqrt(var.reshape(-1, 3).sum(0)) / n
    # The CI must not be vacuous: a wrong albedo factor (a*L/pi, a*L*0.9)
    # would lie outside it.
    assert (se < 0.02 * expected).all(), (se, expected)
    # 4.5 sigma per channel: false-alarm rate ~2e-5 for the 3 channels
    # (a cosine-sampled dome can be exact: allow float rounding on top)
    assert (np.abs(mean - expected) < 4.5 * se + 1e-5 * expected).all(), (mean, expected, se)
    # the reported variance agrees with the spread between pixels (every
    # pixel has the same expectation here) for independent samples; with Sobol
    # points (stratified over a pixel's samples) it is the per-sample variance
    # over the passes, and the pixels spread far less: the points' gain on a
    # two-dimensional integrand (measured: 0.38x)
    spread = img.reshape(-1, 3).var(0, ddof=1)
    reported = var.reshape(-1, 3).mean(0)
    if sampler == "independent":
        assert np.all(np.abs(spread - reported) <= 0.25 * reported + 1e-10), (spread, reported)
    else:
        assert np.all(spread < 0.6 * reported), (spread, reported)
