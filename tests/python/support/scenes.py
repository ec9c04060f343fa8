"""Scenes built through the Python scene API (cmlt.scene) that several tests render."""
import math

import numpy as np

from cmlt.scene import Camera, FrameScene, Instance, Light, Material, Mesh, padded_points

#: image size of the box and caustic scenes, and the depth their MLT tests render with
RES = 32
MAX_DEPTH = 6


def quad(name, c, u, v, mat):
    c, u, v = (np.asarray(a, float) for a in (c, u, v))
    pts = padded_points([c - u - v, c + u - v, c + u + v, c - u + v])
    return Mesh(name, pts, np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                material_ids=np.array([mat, mat], np.uint32))


def cornell_scene():
    """A 2 m box open towards the camera (+z): white floor, ceiling and back wall, red
    left and green right walls, an emissive square under the ceiling; camera at z = 3.4."""
    mats = [Material("/white", diffuse=(0.7, 0.7, 0.7)), Material("/red", diffuse=(0.6, 0.06, 0.05)),
            Material("/green", diffuse=(0.1, 0.5, 0.1)),
            Material("/light", diffuse=(0.0, 0.0, 0.0), emission=(12.0, 10.0, 8.0))]
    quads = [  # normals point into the box (u x v)
        quad("/floor", (0, 0, 0), (0, 0, 1), (1, 0, 0), 0),
        quad("/ceiling", (0, 2, 0), (1, 0, 0), (0, 0, 1), 0),
        quad("/back", (0, 1, -1), (1, 0, 0), (0, 1, 0), 0),
        quad("/left", (-1, 1, 0), (0, 1, 0), (0, 0, 1), 1),
        quad("/right", (1, 1, 0), (0, 0, 1), (0, 1, 0), 2),
        quad("/lamp", (0, 1.98, 0), (0.3, 0, 0), (0, 0, 0.3), 3),
    ]
    cam_xf = np.eye(4)
    cam_xf[:3, 3] = (0, 1, 3.4)
    return FrameScene(
        time=1.0, meshes=quads, instances=[Instance(q.name, i, np.eye(4)) for i, q in enumerate(quads)],
        materials=mats, lights=[],
        camera=Camera("/cam", cam_xf, focal_length=35, horizontal_aperture=24, vertical_aperture=24),
        resolution=(RES, RES), meters_per_unit=1.0)


def with_bulb(fs):
    """The frame with a 1 mm sphere light of radiance 2e5 in view (in the Cornell box:
    smaller than a pixel, so the path-traced passes trace it from the light side too,
    and its splats cross the row bands of a frame's parts)."""
    xf = np.eye(4)
    xf[:3, 3] = (0.2, 1.2, -0.5)
    fs.lights.append(Light("/bulb", "sphere", xf, radiance=(2e5, 2e5, 2e5), radius=1e-3))
    return fs


def uv_sphere(radius, n_theta=24, n_phi=48):
    pts, tris = [], []
    for i in range(n_theta + 1):
        th = math.pi * i / n_theta
        for j in range(n_phi):
            ph = 2 * math.pi * j / n_phi
            pts.append((radius * math.sin(th) * math.cos(ph), radius * math.cos(th),
                        -radius * math.sin(th) * math.sin(ph)))
    for i in range(n_theta):
        for j in range(n_phi):
            a, b = i * n_phi + j, i * n_phi + (j + 1) % n_phi
            c, d = a + n_phi, b + n_phi
            tris += [(a, c, b), (b, c, d)]   # counter-clockwise seen from outside
    p = np.array(pts, float)
    return p, np.array(tris, np.uint32), p / radius


def caustic_scene():
    """Smooth glass ball (opacity 0, ior 1.5, roughness 0) of radius 0.4 on a 2 m diffuse
    floor, a sphere light of radius 0.1 above and to the side: the caustic under the ball
    is an (L) S S D E path, found by light tracing (t = 1)."""
    mats = [Material("/floor", diffuse=(0.7, 0.7, 0.7)),
            Material("/glass", diffuse=(0.0, 0.0, 0.0), opacity=0.0, ior=1.5, roughness=0.0)]
    floor = quad("/floor", (0, 0, 0), (0, 0, 1), (1, 0, 0), 0)
    p, t, n = uv_sphere(0.4)
    ball = Mesh("/ball", padded_points(p), t, normals=padded_points(n),
                material_ids=np.ones(len(t), np.uint32))
    ball_xf = np.eye(4)
    ball_xf[:3, 3] = (0, 0.41, 0)
    light_xf = np.eye(4)
    light_xf[:3, 3] = (0.3, 1.4, -0.1)
    cam_xf = np.eye(4)
    a = math.radians(-38)
    cam_xf[:3, :3] = [[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]]
    cam_xf[:3, 3] = (0, 1.3, 1.6)
    return FrameScene(
        time=1.0, meshes=[floor, ball],
        instances=[Instance("/floor", 0, np.eye(4)), Instance("/ball", 1, ball_xf)],
        materials=mats,
        lights=[Light("/light", "sphere", light_xf, radiance=(60.0, 55.0, 45.0), radius=0.1)],
        camera=Camera("/cam", cam_xf, focal_length=22, horizontal_aperture=36, vertical_aperture=36),
        resolution=(RES, RES), meters_per_unit=1.0)


def plane(size=4.0):
    s = size / 2
    pts = padded_points([(-s, 0, -s), (s, 0, -s), (s, 0, s), (-s, 0, s)])
    return Mesh("/plane", pts, np.array([[0, 2, 1], [0, 3, 2]], np.uint32))


def tent(height):
    """A deforming 'tent': 5 points, the centre one moves up."""
    pts = padded_points([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1), (0, height, 0)])
    idx = np.array([[0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]], np.uint32)
    return Mesh("/tent", pts, idx, deforming=True)


def look_down_camera():
    # camera at (0, 3, 3) looking at the origin: rotate -45 degrees about X
    c, s = np.cos(np.radians(-45)), np.sin(np.radians(-45))
    t = np.array([[1, 0, 0, 0], [0, c, -s, 3], [0, s, c, 3], [0, 0, 0, 1]], float)
    return Camera("/cam", t, focal_length=35, horizontal_aperture=36, vertical_aperture=27)


def rot_x(degrees):
    """Rotation about X; a distant light shines along its local -Z."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]], float)


def tent_frame(time, tent_height, tent_x):
    """A plane and a deforming tent moved to x = tent_x, a sun and a sky, seen from above."""
    xf = np.eye(4)
    xf[0, 3] = tent_x
    return FrameScene(
        time=time, meshes=[plane(), tent(tent_height)],
        instances=[Instance("/plane", 0, np.eye(4)), Instance("/tent", 1, xf)],
        materials=[Material("/white", diffuse=(0.7, 0.7, 0.7))],
        lights=[Light("/sun", "distant", rot_x(-60), radiance=(3.0, 3.0, 3.0), angle=5.0),
                Light("/sky", "dome", np.eye(4), radiance=(0.2, 0.25, 0.3))],
        camera=look_down_camera(), resolution=(32, 24), meters_per_unit=1.0)


def render_settings(integrator, spp, seed, res=RES, chains=256, bootstrap_samples=16384, **kw):
    """core.RenderSettings of a small test render: res x res, 2 threads, MAX_DEPTH, the
    Metropolis integrators' chains and bootstrap as given, then any other field."""
    import cmlt._core as core
    st = core.RenderSettings()
    st.width = st.height = res
    st.spp, st.seed, st.threads, st.max_depth = spp, seed, 2, MAX_DEPTH
    st.integrator = integrator
    st.chains, st.bootstrap_samples = chains, bootstrap_samples
    for k, v in kw.items():
        setattr(st, k, v)
    return st
