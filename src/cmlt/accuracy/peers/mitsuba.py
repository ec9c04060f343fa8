"""Mitsuba 3 as a peer renderer: the neutral scene (scene.py) as a Mitsuba scene dict,
rendered in passes to a wall-time budget. Runs inside a peer worker (harness.py)."""

from __future__ import annotations

import glob
import os
import re
import time
from typing import Dict, Optional

import numpy as np

from .scene import MAX_DEPTH, PMaterial, PScene


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

    @staticmethod
    def _rfilter(name: str) -> dict:
        if name == "box":
            return {"type": "box"}
        if name == "gaussian":
            return {"type": "gaussian", "stddev": 0.5}
        raise ValueError(f"pixel filter {name!r}: the peers know box and gaussian")

    def _scene_dict(self, ps: PScene) -> dict:
        mi = self.mi
        c = ps.camera
        d = {"type": "scene",
             "sensor": {"type": "perspective", "fov": c.hfov_deg, "fov_axis": "x",
                        "near_clip": c.near, "far_clip": c.far,
                        "to_world": self._look_at(c.origin, c.target, c.up),
                        "film": {"type": "hdrfilm", "width": c.width, "height": c.height,
                                 "rfilter": self._rfilter(c.pixel_filter),
                                 "pixel_format": "rgb"},
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
