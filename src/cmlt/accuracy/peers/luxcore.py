"""LuxCore as a peer renderer: the neutral scene (scene.py) as a LuxCore scene and render
configuration, rendered to a wall-time budget. Runs inside a peer worker (harness.py)."""

from __future__ import annotations

import time

import numpy as np

from .scene import MAX_DEPTH, PMaterial, PScene


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
        pf = self.ps.camera.pixel_filter
        if pf == "gaussian":
            P("film.filter.type", "GAUSSIAN")
            P("film.filter.width", 1.5)
            P("film.filter.gaussian.alpha", 2.0)
        elif pf == "box":
            P("film.filter.type", "NONE")
        else:
            raise ValueError(f"pixel filter {pf!r}: the peers know box and gaussian")
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
