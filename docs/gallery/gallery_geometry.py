"""Geometry and USD helpers for the gallery's stages (``build_gallery.py``): image
writing, a lat-long sky, cameras, surfaces of revolution, boxes, a torus with
per-vertex colours, UsdPreviewSurface materials and their binding."""
from __future__ import annotations

import math

import numpy as np
import OpenImageIO as oiio
from pxr import Gf, Sdf, UsdGeom, UsdShade


def write_image(path, pixels, fmt=oiio.FLOAT):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(path)
    if not out.open(path, oiio.ImageSpec(w, h, c, fmt)):
        raise OSError(f"{path}: {oiio.geterror()}")
    out.write_image(np.ascontiguousarray(pixels))
    out.close()


def sky_texture(path, sun_az=40.0, sun_el=35.0):
    """A lat-long sky (OpenEXR convention, +Y pole in light space): blue
    brightening to the horizon, a warm sun glow, a dark warm ground."""
    h, w = 64, 128
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    theta, phi = np.pi * v, np.pi * (1 - 2 * u)
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], -1)
    el = np.radians(sun_el)
    az = np.radians(sun_az)
    sun = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    up = np.clip(d[..., 1], 0, 1)[..., None]
    sky = (1 - up) * np.array([0.75, 0.85, 1.0]) + up * np.array([0.25, 0.45, 0.95])
    glow = np.clip(d @ sun, 0, 1)[..., None] ** 64 * np.array([6.0, 5.0, 3.5])
    ground = np.array([0.12, 0.10, 0.08])
    img = np.where(d[..., 1:2] > 0, sky + glow, ground)
    write_image(path, img.astype(np.float32))
    return path


def look_at(eye, target, up):
    """A Gf.Matrix4d (row vectors) for a camera at ``eye`` looking at ``target``."""
    eye, target, up = (np.asarray(a, float) for a in (eye, target, up))
    z = eye - target
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return Gf.Matrix4d(*x, 0, *y, 0, *z, 0, *eye, 1)


def camera(stage, path, eye, target, up, focal=35.0, clip=(1, 10000)):
    cam = UsdGeom.Camera.Define(stage, path)
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(27.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(*clip))
    cam.AddTransformOp().Set(look_at(eye, target, up))
    return cam


def lathe(stage, path, profile, segments=24, z_up=True):
    """A surface of revolution about the up axis from a profile [(r, h), ...]
    (bottom to top), closed by fans at both ends: quads for Catmull-Clark."""
    n = segments
    pts, counts, idx = [(0.0, 0.0, 0.0)], [], []
    for r, hgt in profile:
        for k in range(n):
            a = 2 * math.pi * k / n
            x, y = r * math.cos(a), r * math.sin(a)
            pts.append((x, y, hgt) if z_up else (x, hgt, -y))
    top = profile[-1][1] + 0.15 * profile[-1][0]
    pts.append((0.0, 0.0, top) if z_up else (0.0, top, 0.0))
    ring = lambda i, k: 1 + i * n + k % n                               # noqa: E731
    for k in range(n):                                    # bottom fan, facing down
        counts.append(3)
        idx += [0, ring(0, k + 1), ring(0, k)]
    for i in range(len(profile) - 1):
        for k in range(n):
            counts.append(4)
            idx += [ring(i, k), ring(i, k + 1), ring(i + 1, k + 1), ring(i + 1, k)]
    last, apex = len(profile) - 1, len(pts) - 1
    for k in range(n):
        counts.append(3)
        idx += [ring(last, k), ring(last, k + 1), apex]
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    m.CreateFaceVertexCountsAttr(counts)
    m.CreateFaceVertexIndicesAttr(idx)
    m.CreateSubdivisionSchemeAttr("catmullClark")
    return m


def box(stage, path, lo, hi, subdiv="none"):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                        (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)])
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4,
                                   1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7])
    m.CreateSubdivisionSchemeAttr(subdiv)
    return m


def preview_surface(stage, path, **inputs):
    mat = UsdShade.Material.Define(stage, path)
    s = UsdShade.Shader.Define(stage, path + "/Surface")
    s.CreateIdAttr("UsdPreviewSurface")
    types = {"diffuseColor": Sdf.ValueTypeNames.Color3f, "emissiveColor":
             Sdf.ValueTypeNames.Color3f, "metallic": Sdf.ValueTypeNames.Float,
             "roughness": Sdf.ValueTypeNames.Float, "clearcoat": Sdf.ValueTypeNames.Float,
             "clearcoatRoughness": Sdf.ValueTypeNames.Float}
    for k, v in inputs.items():
        s.CreateInput(k, types[k]).Set(v)
    mat.CreateSurfaceOutput().ConnectToSource(s.ConnectableAPI(), "surface")
    return mat, s


def bind(prim, mat):
    UsdShade.MaterialBindingAPI.Apply(prim)
    UsdShade.MaterialBindingAPI(prim).Bind(mat if isinstance(mat, UsdShade.Material)
                                           else UsdShade.Material(mat))


def torus(stage, path, R=0.45, r=0.16, nu=48, nv=16):
    pts, counts, idx, col = [], [], [], []
    for i in range(nu):
        a = 2 * math.pi * i / nu
        for j in range(nv):
            b = 2 * math.pi * j / nv
            pts.append(((R + r * math.cos(b)) * math.cos(a), r * math.sin(b),
                        (R + r * math.cos(b)) * math.sin(a)))
            h = i / nu                                   # a hue around the ring
            col.append(tuple(0.5 + 0.45 * math.cos(2 * math.pi * (h + o)) for o in
                             (0.0, 1 / 3, 2 / 3)))
    for i in range(nu):
        for j in range(nv):
            a, b = i * nv + j, ((i + 1) % nu) * nv + j
            c, e = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
            counts.append(4)
            idx += [a, e, c, b]
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(pts)
    m.CreateFaceVertexCountsAttr(counts)
    m.CreateFaceVertexIndicesAttr(idx)
    m.CreateSubdivisionSchemeAttr("catmullClark")
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex).Set(col)
    return m
