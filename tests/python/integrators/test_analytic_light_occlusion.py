"""Analytic lights (rect, disk, sphere, cylinder) stop camera and BSDF rays
(Scene::intersect returns the light as the nearest hit and the path ends there), so they
must also block shadow rays and BDPT connections (Scene::blocked_by_light, used by
Scene::transmittance). This was a bug found by the strategy-by-strategy checks, when
lights were not in any visibility query (they are not in the BVH): the two integrators
then estimated different images: a surface point hidden from the camera behind a light is invisible to
PT but BDPT's light tracing (t = 1) connects it to the camera through the light and
splats it onto the light's pixels; likewise a shadow ray toward one light passes through
another, which a BSDF ray in that direction would hit instead.

Measured (tests/cpp experiments, floor + light in view, max_depth 1): BDPT's next-event
strategy (s, t) = (1, 2) alone is 14% (cylinder) / 8% (sphere) below a quadrature of the
floor radiance over the image, light tracing (2, 1) alone 0.3% / 0.2% above it; with the
light out of view all agree within 0.6%. Over whole images: the Cornell-like box with a
cylinder light, depth-1 strategies differ by 3%, and a coned cylinder by 7-9% (the
"cylinder with a cone" left out of test_cylinder_shaping.cpp's shaped_box).

This test renders a floor under a small sphere light seen from above, max_depth 1, and
asks PT and BDPT to agree per 8x8 block (z-tests with the variance AOV, Bonferroni 1e-3).
Measured before the fix: BDPT +4.4% on the image mean; in the block holding the light PT
4.006, BDPT 4.236 (z = 11.4; the floor radiance behind the light, ~0.7 x the light's
pixel coverage, is what BDPT added).
"""
import math

import numpy as np
import pytest

import cmlt._core as core
from cmlt.scene import Camera, FrameScene, Instance, Light, Material
from cmlt.shot.bridge import SceneBridge

from support.scenes import quad as _quad

pytestmark = pytest.mark.statistical
RES, B = 32, 8


def _scene():
    floor = _quad("/floor", (0, 0, 0), (0, 0, 3), (3, 0, 0), 0)
    light_xf = np.eye(4)
    light_xf[:3, 3] = (0.05, 0.4, -0.03)
    cam_xf = np.eye(4)
    cam_xf[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]   # looking down -y
    cam_xf[:3, 3] = (0, 2, 0)
    return FrameScene(
        time=1.0, meshes=[floor], instances=[Instance("/floor", 0, np.eye(4))],
        materials=[Material("/floor", diffuse=(0.5, 0.5, 0.5))],
        lights=[Light("/light", "sphere", light_xf, radiance=(10.0, 10.0, 10.0), radius=0.15)],
        camera=Camera("/cam", cam_xf, focal_length=50, horizontal_aperture=36, vertical_aperture=36),
        resolution=(RES, RES), meters_per_unit=1.0)


def _render(scene, integrator, spp):
    st = core.RenderSettings()
    st.width = st.height = RES
    st.spp, st.seed, st.threads, st.integrator, st.max_depth = spp, 3, 2, integrator, 1
    r = core.render(scene, st)
    return np.asarray(r.image, np.float64), np.asarray(r.variance, np.float64)


def _blocks(a):
    return a.reshape(RES // B, B, RES // B, B, 3)


def test_pt_bdpt_agree_with_a_light_in_view():
    scene = SceneBridge(core).update(_scene())
    (a, va), (b, vb) = _render(scene, "pt", 256), _render(scene, "bdpt", 128)
    ma, mb = _blocks(a).mean((1, 3)), _blocks(b).mean((1, 3))
    se = np.sqrt(_blocks(va).sum((1, 3)) + _blocks(vb).sum((1, 3))) / (B * B)
    z = np.abs(ma - mb) / np.maximum(se, 1e-300)
    z[(se == 0) & (ma == mb)] = 0
    crit = 4.45   # two-sided 1e-3 / 48
    k = np.unravel_index(z.argmax(), z.shape)
    print(f"\nworst block {k}: PT {ma[k]:.4f} BDPT {mb[k]:.4f} (z {z[k]:.1f}); image means "
          f"PT {a.mean():.5f} BDPT {b.mean():.5f} ({b.mean() / a.mean() - 1:+.2%})")
    assert (z < crit).all()
