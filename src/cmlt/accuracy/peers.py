"""The same USD frame for peer renderers: cmlt's loaded frame converted for Mitsuba 3
and LuxCore, each peer rendering in a worker process of its own, so that their
error-time curves can be drawn beside cmlt's (``cmlt accuracy --peers``,
``tests/bench/peers.py``).

The peers are not cmlt dependencies: ``pip install mitsuba pyluxcore``. A peer that is not
installed, does not import or fails a 16x16 probe render is reported with the reason
(:func:`start_peer`) and left out.

The scene is the same scene
---------------------------
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
  LuxCoreRenderer._scene). Pixel filter: box of one pixel everywhere (Mitsuba ``box``,
  LuxCore ``NONE``).
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

Peer worker processes
---------------------
Each peer renders in a child process of its own, driven from here one render at a time
(so the renders are still interleaved on the same machine state). They cannot share one
process: importing pyluxcore preloads its bundled tbbmalloc_proxy, which replaces malloc
for the whole process, and Mitsuba then aborts with "free(): invalid pointer"; and a
Dr.Jit built against a too-old libLLVM aborts the process from inside LLVM. A worker that
dies is reported (with the tail of its log) and the run goes on without it.
"""


from __future__ import annotations

import glob
import hashlib
import io
import math
import os
import re
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

MAX_DEPTH = 64          # scattering events (cmlt / pbrt convention)
#: each peer's integrator when none is named (``--peers mitsuba`` = ``mitsuba:path``)
DEFAULT_PEER_INTEGRATORS = {"mitsuba": "path", "luxcore": "PATHCPU"}
#: the Python module each peer needs, and what to install
PEER_MODULES = {"mitsuba": "mitsuba", "luxcore": "pyluxcore"}


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


# ============================================================== Mitsuba 3

def find_libllvm() -> Optional[str]:
    """Newest system libLLVM (Dr.Jit's LLVM backend needs a recent one)."""
    best, best_v = None, -1
    for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib",
              "/usr/local/lib"):
        for p in glob.glob(os.path.join(d, "libLLVM*.so*")) + glob.glob(
                os.path.join(d, "llvm-*", "lib", "libLLVM*.so*")):
            m = re.search(r"LLVM-?(\d+)", os.path.basename(p)) or re.search(r"llvm-(\d+)", p)
            if m and int(m.group(1)) > best_v:
                best, best_v = p, int(m.group(1))
    return best


def setup_llvm_env():
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        p = find_libllvm()
        if p:
            os.environ["DRJIT_LIBLLVM_PATH"] = p


class MitsubaRenderer:
    name = "mitsuba"

    def __init__(self, ps: PScene, variant: str, threads: int):
        setup_llvm_env()
        import mitsuba as mi
        import drjit as dr
        self.mi, self.dr = mi, dr
        mi.set_variant(variant)
        mi.set_log_level(mi.LogLevel.Warn)
        dr.set_thread_count(threads)
        self.variant = variant
        self.version = mi.__version__
        self.ps = ps
        t0 = time.perf_counter()
        self.scene = mi.load_dict(self._scene_dict(ps))
        self.setup_s = time.perf_counter() - t0
        self.res = (ps.camera.width, ps.camera.height)
        self._calibrated: Dict[str, int] = {}

    def _bsdf(self, m: PMaterial):
        if m.kind == "dielectric":
            return {"type": "dielectric", "int_ior": float(m.ior), "ext_ior": 1.0}
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(m.diffuse)}}

    def _look_at(self, origin, target, up):
        T = self.mi.ScalarTransform4f
        try:
            return T().look_at(origin=list(origin), target=list(target), up=list(up))
        except TypeError:
            return T.look_at(origin=list(origin), target=list(target), up=list(up))

    def _scene_dict(self, ps: PScene) -> dict:
        mi = self.mi
        c = ps.camera
        d = {"type": "scene",
             "sensor": {"type": "perspective", "fov": c.hfov_deg, "fov_axis": "x",
                        "near_clip": c.near, "far_clip": c.far,
                        "to_world": self._look_at(c.origin, c.target, c.up),
                        "film": {"type": "hdrfilm", "width": c.width, "height": c.height,
                                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                        "sampler": {"type": "independent", "sample_count": 1}}}
        for i, m in enumerate(ps.meshes):
            mat = ps.materials[m.material]
            props = mi.Properties()
            props["bsdf"] = mi.load_dict(self._bsdf(mat))
            if mat.emissive:
                props["emitter"] = mi.load_dict({"type": "area", "radiance": {
                    "type": "rgb", "value": list(mat.emission)}})
            mesh = mi.Mesh(f"mesh{i}", vertex_count=len(m.P), face_count=len(m.T),
                           has_vertex_normals=m.N is not None, has_vertex_texcoords=False,
                           props=props)
            params = mi.traverse(mesh)

            def put(key, arr, dtype):
                # the buffer's own type: a JIT array in llvm_* variants, a dynamic
                # host array in scalar_* ones
                params[key] = type(params[key])(np.ascontiguousarray(arr, dtype=dtype).ravel())
            put("vertex_positions", m.P, np.float32)
            put("faces", m.T, np.uint32)
            if m.N is not None:
                put("vertex_normals", m.N, np.float32)
            params.update()
            d[f"mesh{i}"] = mesh
        for i, s in enumerate(ps.spheres):
            d[f"sphere_light{i}"] = {
                "type": "sphere", "center": list(s.center), "radius": s.radius,
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": list(s.radiance)}}}
        for i, L in enumerate(ps.domes):
            d[f"dome{i}"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(L)}}
        return d

    def _integrator(self, name: str):
        if name in ("path", "prb"):
            return self.mi.load_dict({"type": name, "max_depth": MAX_DEPTH + 1,
                                      "hide_emitters": False})
        if name == "ptracer":
            return self.mi.load_dict({"type": "ptracer", "max_depth": MAX_DEPTH + 1,
                                      "hide_emitters": False})
        raise ValueError(f"unknown Mitsuba integrator {name!r}")

    def _pass(self, integ, spp: int, seed: int) -> np.ndarray:
        img = self.mi.render(self.scene, integrator=integ, spp=int(spp), seed=int(seed))
        return np.array(img, dtype=np.float64)[..., :3]

    def render(self, integrator: str, budget: float, seed: int) -> dict:
        integ = self._integrator(integrator)
        npx = self.res[0] * self.res[1]
        s0 = time.perf_counter()
        key = f"{integrator}:{budget:g}"
        pass_spp = self._calibrated.get(key)
        if pass_spp is None:
            self._pass(integ, 1, 10_000_000 + seed)             # compile
            t1 = time.perf_counter()
            self._pass(integ, 1, 10_000_001 + seed)             # time one spp
            per_spp = max(time.perf_counter() - t1, 1e-4)
            cap = max(1, (1 << 20) // npx)                      # wavefront <= 1M lanes
            pass_spp = int(min(cap, max(1, round(0.1 * budget / per_spp))))
            self._calibrated[key] = pass_spp
        self._pass(integ, pass_spp, 20_000_000 + seed)          # compile at this pass size
        setup = time.perf_counter() - s0
        acc, n = None, 0
        c0, t0 = time.process_time(), time.perf_counter()
        while True:
            img = self._pass(integ, pass_spp, seed * 100_003 + n)
            acc = img if acc is None else acc + img
            n += 1
            el = time.perf_counter() - t0
            if el + 0.5 * el / n >= budget:
                break
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        spp = n * pass_spp
        return {"image": acc / n, "time_s": dt, "cpu_s": cpu, "setup_s": setup, "spp": float(spp),
                "samples_per_s": spp * npx / max(dt, 1e-9),
                "extra": {"pass_spp": pass_spp, "passes": n, "variant": self.variant}}


# ============================================================== LuxCore

_LUX = {"mod": None}


def import_luxcore():
    """Import and initialise pyluxcore (in a worker: its output goes to the worker's log)."""
    if _LUX["mod"] is None:
        import pyluxcore

        def handler(msg):
            print(f"[luxcore] {msg}", flush=True)
        pyluxcore.Init(handler)
        _LUX["mod"] = pyluxcore
    return _LUX["mod"]


class LuxCoreRenderer:
    name = "luxcore"

    def __init__(self, ps: PScene, threads: int):
        self.lux = import_luxcore()
        self.version = self.lux.Version()
        self.ps = ps
        self.threads = threads
        self.res = (ps.camera.width, ps.camera.height)
        self.setup_s = 0.0
        self._sphere_tess = {}

    def _scene(self):
        lux, ps = self.lux, self.ps
        scene = lux.Scene()
        props = lux.Properties()

        def P(name, value):
            props.Set(lux.Property(name, value))

        c = ps.camera
        P("scene.camera.type", "perspective")
        P("scene.camera.lookat.orig", [float(v) for v in c.origin])
        P("scene.camera.lookat.target", [float(v) for v in c.target])
        P("scene.camera.up", [float(v) for v in c.up])
        # LuxCore's perspective camera: the field of view spans screen [-1, 1] (by default
        # the longer image side), and film row fy (rows bottom-up) looks through raster
        # row H - fy - 1, which puts the image one pixel lower than cmlt's and Mitsuba's
        # (measured: the ceiling light's edges). An explicit screen window gives x [-1, 1]
        # (fov on the width, as cmlt's camera), y [-a, a] (a = H / W, square pixels),
        # shifted down by one pixel to undo the offset.
        a = c.height / c.width
        dy = 2.0 * a / c.height
        P("scene.camera.fieldofview", float(c.hfov_deg))
        P("scene.camera.screenwindow", [-1.0, 1.0, -a - dy, a - dy])
        P("scene.camera.cliphither", float(c.near))
        P("scene.camera.clipyon", float(c.far))

        def material(key, m: PMaterial):
            pre = f"scene.materials.{key}."
            if m.kind == "dielectric":
                P(pre + "type", "glass")
                P(pre + "kr", [1.0, 1.0, 1.0])
                P(pre + "kt", [1.0, 1.0, 1.0])
                P(pre + "interiorior", float(m.ior))
                P(pre + "exteriorior", 1.0)
            else:
                P(pre + "type", "matte")
                P(pre + "kd", [float(v) for v in m.diffuse])
            if m.emissive:
                P(pre + "emission", [float(v) for v in m.emission])
                P(pre + "emission.gain", [1.0, 1.0, 1.0])
                P(pre + "emission.power", 0.0)
                P(pre + "emission.efficency", 0.0)

        for i, m in enumerate(ps.materials):
            material(f"mat{i}", m)

        def mesh(key, Pw, T, N, matkey):
            pts = [tuple(map(float, p)) for p in Pw]
            tris = [tuple(map(int, t)) for t in T]
            nrm = None if N is None else [tuple(map(float, n)) for n in N]
            scene.DefineMesh(key, pts, tris, nrm, None, None, None)
            P(f"scene.objects.{key}.shape", key)
            P(f"scene.objects.{key}.material", matkey)

        for i, m in enumerate(ps.meshes):
            mesh(f"mesh{i}", m.P, m.T, m.N, f"mat{m.material}")
        for i, s in enumerate(ps.spheres):
            material(f"sphmat{i}", PMaterial(s.name, "diffuse", emission=s.radiance))
            mesh(f"sphere{i}", s.P, s.T, s.N, f"sphmat{i}")
        for i, L in enumerate(ps.domes):
            P(f"scene.lights.dome{i}.type", "constantinfinite")
            P(f"scene.lights.dome{i}.color", [float(v) for v in L])
            P(f"scene.lights.dome{i}.gain", [1.0, 1.0, 1.0])
        scene.Parse(props)
        return scene

    def _config(self, integrator: str, seed: int):
        lux = self.lux
        engine, _, sampler = integrator.partition("+")
        cfg = lux.Properties()

        def P(name, value):
            cfg.Set(lux.Property(name, value))

        P("renderengine.type", engine)
        P("sampler.type", sampler or "SOBOL")
        P("renderengine.seed", int(seed) % 2_000_000_000 + 1)
        P("native.threads.count", int(self.threads))
        P("film.width", int(self.res[0]))
        P("film.height", int(self.res[1]))
        P("film.filter.type", "NONE")
        P("film.imagepipelines.0.0.type", "TONEMAP_LINEAR")
        P("film.imagepipelines.0.0.scale", 1.0)
        P("film.outputs.0.type", "RGB")
        P("film.outputs.0.filename", "peers_rgb.exr")
        for k in ("total", "diffuse", "glossy", "specular"):
            P(f"path.pathdepth.{k}", MAX_DEPTH)
        P("path.maxdepth", MAX_DEPTH)
        P("light.maxdepth", MAX_DEPTH)
        P("batch.haltspp", 0)
        P("batch.halttime", 0)
        return cfg

    def render(self, integrator: str, budget: float, seed: int) -> dict:
        lux = self.lux
        s0 = time.perf_counter()
        scene = self._scene()
        config = lux.RenderConfig(self._config(integrator, seed), scene)
        session = lux.RenderSession(config)
        session.Start()
        c0, t0 = time.process_time(), time.perf_counter()
        setup = t0 - s0
        while time.perf_counter() - t0 < budget:
            time.sleep(min(0.01, max(0.0, budget - (time.perf_counter() - t0))))
        session.UpdateStats()
        stats = session.GetStats()
        session.Stop()
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        w, h = self.res
        buf = np.zeros((h, w, 3), dtype=np.float32)
        session.GetFilm().GetOutputFloat(lux.FilmOutputType.RGB, buf)
        img = buf[::-1].astype(np.float64)            # LuxCore's film rows are bottom-up

        def stat(name, default=0.0):
            try:
                return float(stats.Get(name).GetFloat())
            except Exception:
                return default
        passes = stat("stats.renderengine.pass")
        count = stat("stats.renderengine.total.samplecount", 0.0)
        npx = w * h
        spp = count / npx if count > 0 else passes
        return {"image": img, "time_s": dt, "cpu_s": cpu, "setup_s": setup, "spp": spp,
                "samples_per_s": spp * npx / max(dt, 1e-9),
                "extra": {"passes": passes, "luxcore_time_s": stat("stats.renderengine.time"),
                          "luxcore_samplesec": stat("stats.renderengine.total.samplesec")}}


# ============================================================== peer worker processes
#
# Each peer renders in a child process of its own, driven from here one render at a time
# (so the renders are still interleaved on the same machine state). They cannot share one
# process: importing pyluxcore preloads its bundled tbbmalloc_proxy, which replaces malloc
# for the whole process, and Mitsuba then aborts with "free(): invalid pointer"; and a
# Dr.Jit built against a too-old libLLVM aborts the process from inside LLVM. A worker that
# dies is reported (with the tail of its log) and the benchmark goes on without it.

class WorkerDied(RuntimeError):
    pass


def worker_main(conn, renderer: str, variant: str, threads: int, log_path: str):
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    sys.stdout = io.TextIOWrapper(os.fdopen(1, "wb", buffering=0), write_through=True)
    sys.stderr = sys.stdout
    R = None
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            os._exit(0)
        cmd = msg[0]
        try:
            if cmd == "quit":
                conn.send({"ok": True})
                os._exit(0)
            elif cmd == "scene":
                ps = msg[1]
                t0 = time.perf_counter()
                R = (MitsubaRenderer(ps, variant, threads) if renderer == "mitsuba"
                     else LuxCoreRenderer(ps, threads))
                conn.send({"ok": True, "version": R.version, "setup_s": time.perf_counter() - t0})
            elif cmd == "render":
                _, integ, budget, seed = msg
                print(f"render {integ} {budget} s seed {seed}", flush=True)
                out = R.render(integ, budget, seed)
                conn.send({"ok": True, "out": out})
            else:
                conn.send({"error": f"unknown command {cmd!r}"})
        except Exception as e:
            traceback.print_exc()
            conn.send({"error": f"{type(e).__name__}: {e}"})


class Worker:
    """One peer renderer in a child process (spawned: no state inherited from here)."""

    def __init__(self, renderer: str, variant: str, threads: int, log_dir: Path):
        import multiprocessing as mp
        ctx = mp.get_context("spawn")
        self.renderer, self.variant = renderer, variant
        self.log_path = log_dir / f"{renderer}{'_' + variant if variant else ''}.log"
        env_before = dict(os.environ)
        if renderer == "mitsuba" and variant.startswith("llvm"):
            setup_llvm_env()                  # inherited by the spawned child
        self.libllvm = os.environ.get("DRJIT_LIBLLVM_PATH")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=worker_main, daemon=True,
                                args=(child, renderer, variant, threads, str(self.log_path)))
        self.proc.start()
        child.close()
        os.environ.clear()
        os.environ.update(env_before)

    def log_tail(self, n: int = 6) -> str:
        try:
            lines = [l for l in self.log_path.read_text(errors="replace").splitlines() if l.strip()]
        except OSError:
            return ""
        return " | ".join(l.strip()[:200] for l in lines[-n:])

    def call(self, msg, timeout: float) -> dict:
        if not self.proc.is_alive():
            raise WorkerDied(f"worker is not running (exit code {self.proc.exitcode})")
        try:
            self.conn.send(msg)
        except OSError as e:
            self.proc.join(2)
            raise WorkerDied(f"worker gone ({e}; exit code {self.proc.exitcode}); "
                             f"log: {self.log_tail()}")
        deadline = time.perf_counter() + timeout
        while True:
            try:
                if self.conn.poll(0.2):
                    break
            except OSError:
                break
            if not self.proc.is_alive():
                raise WorkerDied(f"worker died (exit code {self.proc.exitcode}); log: {self.log_tail()}")
            if time.perf_counter() > deadline:
                self.proc.kill()
                raise WorkerDied(f"no answer in {timeout:.0f} s; worker killed; log: {self.log_tail()}")
        try:
            reply = self.conn.recv()
        except (EOFError, OSError):
            self.proc.join(2)
            raise WorkerDied(f"worker died (exit code {self.proc.exitcode}); log: {self.log_tail()}")
        if "error" in reply:
            raise RuntimeError(reply["error"])
        return reply

    def close(self):
        try:
            if self.proc.is_alive():
                self.call(("quit",), 10.0)
        except Exception:
            pass
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()


class RemoteRenderer:
    """Driver-side handle with the same render() as cmlt.accuracy.render.CmltRenderer."""

    def __init__(self, worker: Worker, ps: "PScene", timeout: float):
        self.worker = worker
        self.name = worker.renderer
        r = worker.call(("scene", ps), timeout)
        self.version = r["version"]
        self.setup_s = r["setup_s"]

    def render(self, integrator: str, budget: float, seed: int) -> dict:
        # generous: Mitsuba compiles kernels and calibrates before its timed passes
        return self.worker.call(("render", integrator, budget, seed), 300.0 + 3.0 * budget)["out"]


def small_copy(ps: "PScene", res=(16, 16)) -> "PScene":
    import copy
    q = copy.copy(ps)
    q.camera = copy.copy(ps.camera)
    q.camera.width, q.camera.height = res
    return q


def start_peer(renderer: str, variant_pref: str, ps: "PScene", threads: int, log_dir: Path,
               say: Callable[[str], None] = print):
    """Start a worker and check it renders a 16x16 version of ``ps``. Returns
    (worker or None, status dict); ``say`` gets the progress messages."""
    if renderer == "mitsuba":
        variants = ["llvm_ad_rgb", "scalar_rgb"] if variant_pref == "auto" else [variant_pref]
        module = "mitsuba"
    else:
        variants, module = [""], "pyluxcore"
    import importlib.util
    if importlib.util.find_spec(module) is None:
        return None, {"ok": False, "note": f"{module} is not installed in this Python "
                                           f"({sys.executable} -m pip install {module})"}
    tried = []
    for v in variants:
        say(f"starting {renderer} {v} ...")
        w = Worker(renderer, v, threads, log_dir)
        try:
            RemoteRenderer(w, small_copy(ps), 600.0)
            probe_integ = "path" if renderer == "mitsuba" else "PATHCPU"
            out = w.call(("render", probe_integ, 0.3, 1), 600.0)["out"]
            if not np.isfinite(out["image"]).all():
                raise RuntimeError("probe image is not finite")
        except Exception as e:
            tried.append(f"{v or renderer}: {e}")
            w.close()
            continue
        tried.append(f"{v or renderer}: ok")
        st = {"ok": True, "note": "; ".join(tried), "variant": v or None}
        if w.libllvm and v.startswith("llvm"):
            st["libllvm"] = w.libllvm
        return w, st
    return None, {"ok": False, "note": "; ".join(tried)}


# ============================================================== peers beside cmlt

def parse_peers(text: str) -> List[Tuple[str, str]]:
    """``mitsuba,luxcore:BIDIRCPU`` -> [("mitsuba", "path"), ("luxcore", "BIDIRCPU")];
    a renderer without an integrator gets its default (DEFAULT_PEER_INTEGRATORS). Raises
    ValueError naming an unknown renderer."""
    out = []
    for item in [t.strip() for t in text.split(",") if t.strip()]:
        ren, _, integ = item.partition(":")
        ren = ren.lower()
        if ren not in DEFAULT_PEER_INTEGRATORS:
            raise ValueError(f"--peers {text!r}: unknown peer {ren!r}; choose from "
                             f"{', '.join(DEFAULT_PEER_INTEGRATORS)} (renderer[:integrator])")
        out.append((ren, integ or DEFAULT_PEER_INTEGRATORS[ren]))
    if not out:
        raise ValueError(f"--peers {text!r}: name at least one peer")
    return out


class PeerSession:
    """The peers of an accuracy run: one worker process per renderer, started and probed
    once; :meth:`load` sends each frame's converted scene; :meth:`render` renders it to a
    wall-time budget. ``status[renderer]`` says whether it runs and why not."""

    def __init__(self, renderers: Sequence[str], probe_scene: "PScene", threads: int,
                 log_dir: str, variant: str = "auto", say: Callable[[str], None] = print):
        self.status: Dict[str, dict] = {}
        self.workers: Dict[str, Worker] = {}
        self.handles: Dict[str, RemoteRenderer] = {}
        self.say = say
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        for ren in dict.fromkeys(renderers):
            w, st = start_peer(ren, variant, probe_scene, threads, Path(log_dir), say=say)
            self.status[ren] = st
            if w is not None:
                self.workers[ren] = w

    def available(self, renderer: str) -> bool:
        return renderer in self.workers and self.status[renderer].get("ok", False)

    def load(self, ps: "PScene") -> None:
        """Build ``ps`` in every running peer; a peer that fails is marked as not running."""
        self.handles = {}
        for ren, w in list(self.workers.items()):
            if not self.status[ren].get("ok"):
                continue
            try:
                self.handles[ren] = RemoteRenderer(w, ps, 900.0)
                self.status[ren]["version"] = self.handles[ren].version
            except Exception as e:          # noqa: BLE001 - a peer's failure is reported
                self.status[ren]["ok"] = False
                self.status[ren]["note"] = f"scene build failed: {type(e).__name__}: {e}"
                self.say(f"{ren}: {self.status[ren]['note']}")

    def render(self, renderer: str, integrator: str, seconds: float, seed: int) -> dict:
        out = self.handles[renderer].render(integrator, seconds, seed)
        img = np.asarray(out["image"], dtype=np.float64)
        out["finite"] = bool(np.isfinite(img).all())
        out["image"] = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
        return out

    def close(self) -> None:
        for w in self.workers.values():
            w.close()
        self.workers = {}
