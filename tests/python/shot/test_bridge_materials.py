"""UsdPreviewSurface through the whole Python -> core path.

* set_materials keeps its old two-argument form (Lambert) and checks `params`;
* glass, mirror, metal, rough glass, clearcoat, cutout: finite images;
* furnaces: a closed world of constant radiance L (a uniform dome) must give L
  in every pixel whatever non-absorbing object stands in it: a smooth glass
  sphere (ior 1.5: Dirac refraction + reflection, total internal reflection,
  radiance scaling 1/eta^2 in and eta^2 out), an ior-1 pass-through sphere,
  and an albedo-1 Lambertian sphere (exact UsdPreviewSurface Lambertian:
  specular workflow with specularColor 0).
"""
import numpy as np
import pytest

import cmlt._core as core

from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points
from cmlt.shot.bridge import SceneBridge
from cmlt.shot.material_table import MATERIAL_PARAM_COLUMNS, material_params

L_DOME = np.array([0.7, 1.0, 1.3])


def uv_sphere(radius=1.0, n_theta=48, n_phi=96):
    """Closed, outward-facing (CCW from outside) sphere with normals and uvs."""
    th = np.linspace(0, np.pi, n_theta + 1)
    ph = np.linspace(0, 2 * np.pi, n_phi + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.cos(T), -np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    uv = np.stack([P / (2 * np.pi), 1 - T / np.pi], -1).reshape(-1, 2)
    tris = []
    w = n_phi + 1
    for i in range(n_theta):
        for j in range(n_phi):
            a, b, c, d = i * w + j, i * w + j + 1, (i + 1) * w + j, (i + 1) * w + j + 1
            tris += [(a, c, b), (b, c, d)]
    tris = np.array(tris, np.uint32)
    # drop the degenerate triangles at the poles
    p = n * radius
    area = np.linalg.norm(np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]), axis=1)
    tris = tris[area > 1e-12]
    return p.astype(np.float32), tris, n.astype(np.float32), uv.astype(np.float32)


def _camera(dist=4.0):
    xf = np.eye(4)
    xf[2, 3] = dist                   # at +Z looking down -Z at the origin
    return Camera("/cam", xf, focal_length=50, horizontal_aperture=36, vertical_aperture=36)


def _scene(materials, res=24, extra_meshes=()):
    p, t, n, uv = uv_sphere()
    meshes = [Mesh("/sphere", padded_points(p), t, normals=padded_points(n), uvs=uv)]
    inst = [Instance("/sphere", 0, np.eye(4))]
    for k, (mesh, xf) in enumerate(extra_meshes):
        meshes.append(mesh)
        inst.append(Instance(mesh.name, k + 1, xf))
    return FrameScene(time=1.0, meshes=meshes, instances=inst, materials=materials,
                      lights=[Light("/dome", "dome", np.eye(4), radiance=tuple(L_DOME))],
                      camera=_camera(), resolution=(res, res), meters_per_unit=1.0)


def _render(fs, spp=16, max_depth=64, seed=3):
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.max_depth, st.seed, st.threads = spp, max_depth, seed, 2
    st.integrator = "pt"
    r = core.render(SceneBridge(core).update(fs), st)
    return np.asarray(r.image, np.float64), np.asarray(r.variance, np.float64)


def test01_set_materials_backward_compatible_and_checked():
    s = core.Scene()
    d = np.full((2, 3), 0.5, np.float32)
    e = np.zeros((2, 3), np.float32)
    s.set_materials(d, e)                                   # Lambert, as before
    s.set_materials(d, e, None)
    s.set_materials(d, e, np.zeros((2, 11), np.float32))    # PreviewSurface, no textures
    full = np.stack([material_params(Material("/a")), material_params(Material("/b"))])
    assert full.shape == (2, len(MATERIAL_PARAM_COLUMNS)) == (2, 25)
    s.set_materials(d, e, full)
    with pytest.raises(ValueError, match="params"):
        s.set_materials(d, e, np.zeros((2, 7), np.float32))
    with pytest.raises(ValueError, match="params"):
        s.set_materials(d, e, np.zeros((3, 11), np.float32))
    with pytest.raises(TypeError, match="params"):
        s.set_materials(d, e, np.zeros((2, 11), np.float64))
    bad = full.copy()
    bad[0, 5] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        s.set_materials(d, e, bad)
    bad = full.copy()
    bad[0, 11] = 7                                         # texture 7 does not exist
    s.set_materials(d, e, bad)
    with pytest.raises(Exception, match="texture 7"):
        s.commit()


@pytest.mark.parametrize("mat", [
    Material("/glass", opacity=0.0, roughness=0.0, ior=1.5),
    Material("/rough_glass", opacity=0.0, roughness=0.3, ior=1.33),
    Material("/mirror", diffuse=(1, 1, 1), metallic=1.0, roughness=0.0),
    Material("/metal", diffuse=(0.9, 0.6, 0.3), metallic=1.0, roughness=0.4),
    Material("/coated", diffuse=(0.2, 0.3, 0.8), clearcoat=1.0, clearcoat_roughness=0.0),
    Material("/specular_wf", use_specular_workflow=True, specular=(1, 1, 1), roughness=1.0),
    Material("/cutout", opacity=0.2, opacity_threshold=0.5),
    Material("/ior1_rough", opacity=0.0, roughness=1.0, ior=1.0),
], ids=lambda m: m.name.strip("/"))
def test02_every_model_renders_finite(mat):
    floor = Mesh("/floor", padded_points([(-5, 0, -5), (5, 0, -5), (5, 0, 5), (-5, 0, 5)]),
                 np.array([[0, 2, 1], [0, 3, 2]], np.uint32))
    xf = np.eye(4)
    xf[1, 3] = -1.0
    fs = _scene([mat, Material("/floor", diffuse=(0.5, 0.5, 0.5))], res=16,
                extra_meshes=[(floor, xf)])
    fs.meshes[1].material_ids = np.array([1, 1], np.uint32)
    img, var = _render(fs, spp=8, max_depth=12)
    assert np.isfinite(img).all() and np.isfinite(var).all()
    assert (img >= 0).all() and img.max() > 0


def _furnace(mat, spp):
    img, var = _render(_scene([mat]), spp=spp)
    assert np.isfinite(img).all()
    n = img.shape[0] * img.shape[1]
    mean = img.reshape(-1, 3).mean(0)
    se = np.sqrt(var.reshape(-1, 3).sum(0)) / n
    return mean, se


@pytest.mark.statistical
@pytest.mark.parametrize("mat", [
    Material("/glass", opacity=0.0, roughness=0.0, ior=1.5),
    Material("/white_lambert", diffuse=(1, 1, 1), use_specular_workflow=True),
], ids=lambda m: m.name.strip("/"))
def test03_white_furnace(mat):
    mean, se = _furnace(mat, spp=64)
    # The CI is not vacuous: a 2 % energy error would fall outside it.
    assert (se < 0.005 * L_DOME).all(), se
    # 4.5 sigma per channel (false alarms ~2e-5 per channel); float rounding on top
    assert (np.abs(mean - L_DOME) < 4.5 * se + 1e-5 * L_DOME).all(), (mean, L_DOME, se)


def test04_pass_through_is_exact():
    # ior 1: the interface neither reflects nor bends: the sphere is invisible.
    img, _ = _render(_scene([Material("/air", opacity=0.0, roughness=0.0, ior=1.0)]), spp=2)
    np.testing.assert_allclose(img, np.broadcast_to(L_DOME, img.shape), rtol=1e-5)
