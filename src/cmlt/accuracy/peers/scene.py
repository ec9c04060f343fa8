"""The neutral scene the peers render: cmlt's loaded frame converted to plain meshes,
materials, emitters and a camera (:func:`convert_frame`), and the brightness measures
that compare the renderers' images.

cmlt's own stage reader loads the frame (``cmlt.usd.open_stage`` / ``load_frame``) and the
loaded :class:`cmlt.scene.FrameScene` is converted programmatically
(:func:`convert_frame`), so all renderers see the same numbers:

* meshes: every instance is baked to world space (metres; the instance transform applied,
  normals by the inverse transpose) and split by material; vertex normals are kept.
  Mitsuba gets ``mi.Mesh`` objects filled from numpy arrays, LuxCore ``Scene.DefineMesh``.
  Intrinsic gprims (the glass ``Sphere``) arrive already tessellated by cmlt (64x32), so
  every renderer traces the same triangles.
* materials: opaque UsdPreviewSurface -> Lambert (Mitsuba ``diffuse``, LuxCore ``matte``)
  with the diffuse colour; ``opacity`` 0 and roughness ~0 -> a smooth dielectric of the
  same IOR (Mitsuba ``dielectric``, LuxCore ``glass`` with white kr/kt); ``emissiveColor``
  -> an area emitter of that radiance. cmlt's UsdPreviewSurface puts a GGX specular layer
  (F0 = ((ior-1)/(ior+1))^2 = 4 %) over the diffuse; the peers' Lambert BSDFs have none, so by
  default the benchmark sets ``ior = 1`` on cmlt's opaque, non-metallic materials, which makes
  its BSDF exactly Lambertian (F0 = F90 = 0, preview_surface.cpp note 1). ``--keep-specular``
  leaves cmlt's materials alone (the brightness ratio then shows the difference).
* lights: RectLight -> two emitting triangles facing the light's -Z (one-sided, like
  cmlt's), black BSDF; SphereLight -> Mitsuba's analytic ``sphere`` with an ``area``
  emitter (exact); LuxCore a 16 x 8 faceted sphere scaled to the same area (same power; see
  LUX_SPHERE_SEGMENTS for why not finer; LuxCore's analytic sphere light cannot be hit by
  rays, so path tracing could not make its caustic); DiskLight -> a 64-triangle fan; an
  untextured DomeLight -> a constant environment. Radiance is cmlt's ``Light.radiance``
  (intensity * 2^exposure * colour, normalised by area when asked), i.e. the same
  W/(m^2 sr) numbers in every renderer: no photometric unit conversion.
* camera: position, view direction (-Z) and up (+Y) of cmlt's camera -> ``look_at``;
  horizontal field of view 2 atan(horizontalAperture / (2 focalLength)), as cmlt's camera
  (its vertical extent follows the image aspect); Mitsuba ``fov_axis = x``; LuxCore gets an
  explicit screen window that also undoes its one-pixel vertical offset (see
  LuxCoreRenderer._scene). Pixel filter (``PCamera.pixel_filter``): ``box``, one pixel
  everywhere (Mitsuba ``box``, LuxCore ``NONE``), or ``gaussian``, sigma 0.5 px in all three:
  cmlt's (pbrt-v4's: radius 1.5, its value at the radius subtracted), Mitsuba's ``gaussian``
  (``stddev`` 0.5, cut at 4 sigma = 2 px, not shifted), LuxCore's ``GAUSSIAN`` (width 1.5,
  alpha 2 = 1 / (2 sigma^2), shifted like pbrt's).
* path length: cmlt max_depth 64 scattering events = Mitsuba max_depth 65 (it counts the
  camera segment) = LuxCore depth 64; Russian roulette is each renderer's own.
* colour: cmlt renders in ACEScg and converts the authored colours into it when it loads
  the frame; the peers get those same ACEScg numbers and run in RGB mode (Mitsuba
  ``*_rgb`` variants, LuxCore is RGB), where transport is per channel, so every output is
  in ACEScg and no colour conversion happens anywhere. No spectral variant is used.

Anything the converter cannot carry over (textures, metals, clearcoat, rough or partly
opaque glass, light shaping, depth of field, two-sided emissive meshes, ...) is listed in
the output under "conversion" and in the JSON; none of it occurs in cornell and
caustic_glass. What still differs there: LuxCore's faceted sphere light; how each renderer
refracts through a tessellated sphere with interpolated normals; Russian roulette and
samplers (LuxCore's default is Sobol, the others independent random numbers).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np


MAX_DEPTH = 64          # scattering events (cmlt / pbrt convention)


def clipped_ratio(img: np.ndarray, ref: np.ndarray, clip_ref: np.ndarray) -> float:
    """Mean brightness of ``img`` over ``ref``'s, both clipped at 20 x the median of
    ``clip_ref``: the visible light sources and their highlights (a few pixels thousands
    of times brighter than the rest, which decide the plain mean) and fireflies count as
    bright pixels, not by how bright they are, so the ratio reads the illumination."""
    c = 20.0 * max(float(np.median(clip_ref)), 1e-6)
    return float(np.minimum(img, c).mean() / max(np.minimum(ref, c).mean(), 1e-12))


def luminance(img: np.ndarray) -> float:
    # ACEScg (AP1) luminance weights
    return float(np.mean(img[..., 0] * 0.2722287 + img[..., 1] * 0.6740818 + img[..., 2] * 0.0536895))


# ============================================================== neutral scene

@dataclass
class PMaterial:
    name: str
    kind: str                                  # 'diffuse' | 'dielectric'
    diffuse: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    emission: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    ior: float = 1.5

    @property
    def emissive(self) -> bool:
        return max(self.emission) > 0.0


@dataclass
class PMesh:
    name: str
    P: np.ndarray                              # float64 (N, 3), world, metres
    T: np.ndarray                              # int64 (M, 3)
    N: Optional[np.ndarray]                    # float64 (N, 3) or None
    material: int


@dataclass
class PSphere:                                 # an emitting sphere (SphereLight)
    name: str
    center: Tuple[float, float, float]
    radius: float
    radiance: Tuple[float, float, float]
    # the same sphere as a mesh (world space) for LuxCore: see LUX_SPHERE_SEGMENTS
    P: Optional[np.ndarray] = None
    T: Optional[np.ndarray] = None
    N: Optional[np.ndarray] = None


@dataclass
class PCamera:
    origin: np.ndarray
    target: np.ndarray
    up: np.ndarray
    hfov_deg: float
    width: int
    height: int
    near: float
    far: float
    pixel_filter: str = "box"                  # 'box' | 'gaussian' (module doc)


@dataclass
class PScene:
    shot: str
    time: float
    materials: List[PMaterial] = field(default_factory=list)
    meshes: List[PMesh] = field(default_factory=list)
    spheres: List[PSphere] = field(default_factory=list)
    domes: List[Tuple[float, float, float]] = field(default_factory=list)
    camera: Optional[PCamera] = None
    notes: List[str] = field(default_factory=list)     # what does not carry over

    def triangle_count(self) -> int:
        return int(sum(len(m.T) for m in self.meshes))

    def digest(self) -> str:
        h = hashlib.sha1()
        for m in self.meshes:
            h.update(np.ascontiguousarray(m.P, dtype=np.float32).tobytes())
            h.update(np.ascontiguousarray(m.T, dtype=np.int64).tobytes())
            h.update(repr(self.materials[m.material]).encode())
        for s in self.spheres:
            h.update(repr(s).encode())
        h.update(repr(self.domes).encode())
        c = self.camera
        h.update(repr((c.origin.tolist(), c.target.tolist(), c.up.tolist(), c.hfov_deg,
                       c.width, c.height)).encode())
        if c.pixel_filter != "box":
            h.update(c.pixel_filter.encode())
        return h.hexdigest()[:12]


# LuxCore's emitting sphere: a UV sphere of 16 x 8 segments (224 triangles). Measured here
# (caustic_glass, 64x64, 4 s PATHCPU, relMSE against cmlt's bdpt reference): 120 and 224
# triangles 0.25-0.27, but 528, 960 and cmlt's own 64 x 32 tessellation (3968) 10-11: with
# more than a few hundred emitting triangles LuxCore's direct light sampling stops helping
# (at any scene scale), and the floor under the light is rendered by BSDF hits alone.
LUX_SPHERE_SEGMENTS = (16, 8)


def uv_sphere_same_area(radius: float, n_around: int, n_rings: int):
    """Flat-faceted UV sphere (outward winding) scaled so that its area is 4 pi r^2: the
    same emitted power as the analytic sphere light of the same radiance."""
    th = np.pi * np.arange(n_rings + 1) / n_rings
    ph = 2 * np.pi * np.arange(n_around) / n_around
    P = np.stack([np.outer(np.sin(th), np.cos(ph)), np.outer(np.cos(th), np.ones(n_around)),
                  np.outer(np.sin(th), np.sin(ph))], -1).reshape(-1, 3)
    T = []
    for j in range(n_rings):
        for i in range(n_around):
            a, b = j * n_around + i, j * n_around + (i + 1) % n_around
            c, d = (j + 1) * n_around + (i + 1) % n_around, (j + 1) * n_around + i
            T += [(a, c, b), (a, d, c)]
    T = np.array(T, dtype=np.int64)
    n = np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])
    keep = np.linalg.norm(n, axis=1) > 1e-9
    T, n = T[keep], n[keep]
    inward = np.sum(n * P[T].mean(1), axis=1) < 0
    T[inward] = T[inward][:, [0, 2, 1]]
    area = 0.5 * np.linalg.norm(n, axis=1).sum()
    return P * radius * math.sqrt(4 * math.pi / area), T


def _material_is_lambert(m) -> bool:
    return m.opacity >= 1.0 and m.metallic <= 0.0


def make_cmlt_lambert(fs) -> List[str]:
    """Set ior = 1 on opaque, non-metallic materials: cmlt's UsdPreviewSurface is then an
    exact Lambertian (no 4 % GGX layer), like the peers' diffuse BSDFs."""
    changed = []
    for m in fs.materials:
        if _material_is_lambert(m) and not m.use_specular_workflow and m.ior != 1.0:
            m.ior = 1.0
            changed.append(m.name)
        elif _material_is_lambert(m) and m.use_specular_workflow and max(m.specular) > 0:
            m.specular = (0.0, 0.0, 0.0)
            changed.append(m.name)
    return changed


def _textured_inputs(m) -> List[str]:
    out = []
    for k, v in (m.inputs or {}).items():
        if not isinstance(v, (int, float, bool, str, tuple, list)) and v is not None:
            out.append(k)
    return out


def convert_frame(fs, shot: str) -> PScene:
    """cmlt FrameScene -> the neutral scene the peer builders read."""
    ps = PScene(shot=shot, time=float(fs.time))
    notes = ps.notes
    # ---- materials
    for m in fs.materials:
        tex = _textured_inputs(m)
        if tex:
            notes.append(f"{m.name}: textured inputs {tex} not converted (constant values used)")
        if m.opacity < 1.0:
            alpha = m.roughness ** 2
            if m.opacity > 0.0:
                notes.append(f"{m.name}: opacity {m.opacity:g} (partly transparent) converted "
                             f"as a full dielectric")
            if alpha >= 1e-3:
                notes.append(f"{m.name}: rough glass (roughness {m.roughness:g}) converted as "
                             f"smooth glass")
            ps.materials.append(PMaterial(m.name, "dielectric", emission=tuple(m.emission),
                                          ior=float(m.ior)))
            continue
        if m.metallic > 0.0:
            notes.append(f"{m.name}: metallic {m.metallic:g} converted as Lambert "
                         f"(1 - metallic) * diffuse")
        if m.clearcoat > 0.0:
            notes.append(f"{m.name}: clearcoat {m.clearcoat:g} ignored")
        if m.use_specular_workflow and max(m.specular) > 0:
            notes.append(f"{m.name}: specular workflow F0 {tuple(m.specular)} ignored (Lambert)")
        d = tuple(float(c) * (1.0 - m.metallic) for c in m.diffuse)
        ps.materials.append(PMaterial(m.name, "diffuse", diffuse=d,
                                      emission=tuple(float(c) for c in m.emission)))
    if not ps.materials:
        ps.materials.append(PMaterial("<fallback>", "diffuse", diffuse=(0.18, 0.18, 0.18)))
    # ---- meshes, baked to world space and split by material
    for inst in fs.instances:
        mesh = fs.meshes[inst.mesh]
        M = np.asarray(inst.transform, dtype=np.float64)
        P = np.asarray(mesh.points, dtype=np.float64).reshape(-1, 3)
        P = P @ M[:3, :3].T + M[:3, 3]
        T = np.asarray(mesh.indices, dtype=np.int64).reshape(-1, 3)
        if np.linalg.det(M[:3, :3]) < 0:
            T = T[:, [0, 2, 1]]
        N = None
        if mesh.normals is not None:
            Nm = np.linalg.inv(M[:3, :3]).T
            N = np.asarray(mesh.normals, dtype=np.float64).reshape(-1, 3) @ Nm.T
            N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-30)
        if inst.motion_transforms or mesh.motion_points:
            notes.append(f"{inst.name}: motion blur not converted (shutter instant only)")
        mids = (np.zeros(len(T), dtype=np.int64) if mesh.material_ids is None
                else np.asarray(mesh.material_ids, dtype=np.int64).reshape(-1))
        for mid in np.unique(mids):
            if mid < len(ps.materials) and ps.materials[int(mid)].emissive:
                notes.append(f"{inst.name}: emissive mesh: cmlt emits from both faces, the "
                             f"peers from the front (counter-clockwise) face only")
            sel = T[mids == mid]
            used, inv = np.unique(sel.reshape(-1), return_inverse=True)
            ps.meshes.append(PMesh(name=f"{inst.name}#{int(mid)}", P=P[used],
                                   T=inv.reshape(-1, 3), N=None if N is None else N[used],
                                   material=int(min(mid, len(ps.materials) - 1))))
    # ---- lights
    for li in fs.lights:
        L = tuple(float(c) for c in li.radiance)
        X = np.asarray(li.transform, dtype=np.float64)
        if li.kind in ("rect", "disk", "sphere", "cylinder") and (
                li.cone_angle < 180.0 or li.focus > 0.0):
            notes.append(f"{li.name}: ShapingAPI (cone {li.cone_angle:g}, focus {li.focus:g}) "
                         f"not converted")
        if li.kind == "rect":
            if li.texture:
                notes.append(f"{li.name}: rect light texture not converted")
            w, h = li.width / 2.0, li.height / 2.0
            loc = np.array([(-w, -h, 0), (-w, h, 0), (w, h, 0), (w, -h, 0)], dtype=np.float64)
            P = loc @ X[:3, :3].T + X[:3, 3]
            # winding: normal = local -Z (the emitting side of a UsdLux RectLight)
            T = np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int64)
            ps.materials.append(PMaterial(li.name, "diffuse", emission=L))
            ps.meshes.append(PMesh(li.name, P, T, None, len(ps.materials) - 1))
        elif li.kind == "disk":
            n = 64
            th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
            loc = np.concatenate([[(0.0, 0.0, 0.0)],
                                  np.stack([li.radius * np.cos(th), li.radius * np.sin(th),
                                            np.zeros(n)], -1)])
            P = loc @ X[:3, :3].T + X[:3, 3]
            # (c, i+1, i): normal -Z
            T = np.array([(0, 1 + (i + 1) % n, 1 + i) for i in range(n)], dtype=np.int64)
            ps.materials.append(PMaterial(li.name, "diffuse", emission=L))
            ps.meshes.append(PMesh(li.name, P, T, None, len(ps.materials) - 1))
            notes.append(f"{li.name}: disk light as a 64-triangle fan in the peers")
        elif li.kind == "sphere":
            if li.treat_as_point:
                notes.append(f"{li.name}: treatAsPoint sphere light converted as a small sphere")
            Ps, Ts = uv_sphere_same_area(float(li.radius), *LUX_SPHERE_SEGMENTS)
            ps.spheres.append(PSphere(li.name, tuple(X[:3, 3].tolist()), float(li.radius), L,
                                      P=Ps + X[:3, 3], T=Ts, N=None))
        elif li.kind == "dome" and not li.texture:
            ps.domes.append(L)
        else:
            notes.append(f"{li.name}: {li.kind} light not converted (skipped in the peers)")
    # ---- camera
    c = fs.camera
    X = np.asarray(c.transform, dtype=np.float64)
    origin = X[:3, 3].copy()
    fwd = -X[:3, 2] / np.linalg.norm(X[:3, 2])
    up = X[:3, 1] / np.linalg.norm(X[:3, 1])
    if c.projection != "perspective":
        notes.append(f"{c.name}: {c.projection} projection converted as perspective")
    if c.f_stop > 0 and c.focus_distance > 0:
        notes.append(f"{c.name}: depth of field (fStop {c.f_stop:g}) not converted")
    if c.horizontal_aperture_offset or c.vertical_aperture_offset:
        notes.append(f"{c.name}: aperture offsets not converted")
    hfov = math.degrees(2.0 * math.atan(0.5 * c.horizontal_aperture / c.focal_length))
    w, h = fs.resolution
    ps.camera = PCamera(origin, origin + fwd, up, hfov, int(w), int(h), float(c.near), float(c.far))
    return ps
