#!/usr/bin/env python3
"""Path-evaluation speed: cmlt's pt and bdpt against Mitsuba 3 on Mitsuba's own Cornell
box, and cmlt's rays per second and trace share on the repository's shots.

    .venv/bin/python -m pip install mitsuba           # the peer (not a cmlt dependency)
    apt-get install libllvm19                          # for Mitsuba's llvm_ad_rgb variant
    .venv/bin/python tests/bench/speed.py --repeats 3 --out renders/bench/speed

The stage ``mitsuba_cornell`` is ``mi.cornell_box()`` written out as USD by
``write_mitsuba_cornell`` below: its rectangles and cubes become meshes (Mitsuba's unit
square and cube under the shapes' ``to_world``), the diffuse BSDFs UsdPreviewSurface
materials with specularColor 0 (exact Lambertians, cmlt's diffuse-only kernel), the
area-lit rectangle a UsdLux RectLight of the same size, place, facing and radiance
(Mitsuba's emitter is one-sided too), the perspective sensor a USD camera with the same
field of view on the smaller axis; colours are linear Rec.709 and the render uses that
rendering space. Both films reconstruct with the one-pixel box (Mitsuba's ``rfilter`` box,
the stage's ``cmlt:pixelFilter`` box): the same estimator per pixel, the same work. ``mi.cornell_box()`` is read when Mitsuba is installed; without it the
same values written below are used (they are Mitsuba 3.x's).

Every render is a separate process (start-up included, as a user runs it), interleaved
round-robin over the renderers, ``--repeats`` times; medians. Columns:

* ``samples/s``: width x height x spp over the render's own time (cmlt: the sidecar's
  ``stats.time_s``; Mitsuba: ``mi.render`` with its kernels compiled, i.e. a second
  render in the same process);
* ``samples/s incl. start-up``: the same over the whole process's wall time (Python
  import, stage load and colour set-up for cmlt; import, scene load and kernel
  compilation, cached on disk by Dr.Jit after the first run, for Mitsuba);
* ``Mrays/s/thread`` and ``trace share`` (``stats.trace_s / stats.busy_s``) for cmlt.

Mitsuba's path tracer has ``max_depth`` 8 (7 scattering events); cmlt runs ``--max-depth
7`` (pbrt's count: 1 = direct light only). Both use Russian roulette with the same rule
(continue with min(0.95, max(throughput) eta^2)); cmlt's starts at the third scattering
event, Mitsuba's by default at the fifth, so Mitsuba gets ``rr_depth`` 3: the same paths'
lengths, the same work per sample (``--mitsuba-rr-depth 5`` for Mitsuba's default, which
traces about a quarter more per sample on its box).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
CMLT = [str(Path(sys.executable).with_name("cmlt"))]  # the console script beside this Python

#: mi.cornell_box() of Mitsuba 3.x (used when Mitsuba is not installed): to_world
#: matrices row by row, reflectances, the emitter's radiance.
_WHITE, _GREEN, _RED = (0.885809, 0.698859, 0.666422), (0.105421, 0.37798, 0.076425), (0.570068, 0.0430135, 0.0443706)


def _rot_x(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rot_y(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _tr(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _sc(x, y, z):
    return np.diag([x, y, z, 1.0])


def cornell_box_dict() -> dict:
    """mi.cornell_box() as plain numbers: ``{name: (type, to_world 4x4 column-vector,
    reflectance, radiance or None)}`` plus the camera."""
    try:
        import mitsuba as mi
        mi.set_variant("scalar_rgb")
        d = mi.cornell_box()
        bsdfs = {k: tuple(v["reflectance"]["value"]) for k, v in d.items()
                 if isinstance(v, dict) and v.get("type") == "diffuse"}
        shapes = {}
        for k, v in d.items():
            if isinstance(v, dict) and v.get("type") in ("rectangle", "cube"):
                m = np.array(v["to_world"].matrix, dtype=float)
                refl = bsdfs[v["bsdf"]["id"]]
                em = tuple(v["emitter"]["radiance"]["value"]) if "emitter" in v else None
                shapes[k] = (v["type"], m, refl, em)
        s = d["sensor"]
        cam = dict(fov=float(s["fov"]), to_world=np.array(s["to_world"].matrix, dtype=float),
                   max_depth=int(d["integrator"]["max_depth"]))
        return dict(shapes=shapes, camera=cam, source=f"mi.cornell_box() of Mitsuba {mi.__version__}")
    except ImportError:
        pass
    shapes = {
        "light": ("rectangle", _tr(0, 0.99, 0.01) @ _rot_x(90) @ _sc(0.23, 0.19, 0.19), _WHITE,
                  (18.387, 13.9873, 6.75357)),
        "floor": ("rectangle", _tr(0, -1, 0) @ _rot_x(-90), _WHITE, None),
        "ceiling": ("rectangle", _tr(0, 1, 0) @ _rot_x(90), _WHITE, None),
        "back": ("rectangle", _tr(0, 0, -1), _WHITE, None),
        "green-wall": ("rectangle", _tr(1, 0, 0) @ _rot_y(-90), _GREEN, None),
        "red-wall": ("rectangle", _tr(-1, 0, 0) @ _rot_y(90), _RED, None),
        "small-box": ("cube", _tr(0.335, -0.7, 0.38) @ _rot_y(-17) @ _sc(0.3, 0.3, 0.3), _WHITE, None),
        "large-box": ("cube", _tr(-0.33, -0.4, -0.28) @ _rot_y(18.25) @ _sc(0.3, 0.61, 0.3), _WHITE, None),
    }
    cam = dict(fov=39.3077, to_world=np.diag([-1.0, 1, -1, 1]) + _tr(0, 0, 3.9) - np.eye(4), max_depth=8)
    return dict(shapes=shapes, camera=cam, source="mi.cornell_box() values of Mitsuba 3.x (Mitsuba not installed)")


def _unit_cube():
    """Mitsuba's cube: [-1, 1]^3, four vertices per face (flat faces), outward normals."""
    pts, idx = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            base = len(pts)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis], p[u], p[v] = sign, a, b
                pts.append(p)
            # counter-clockwise seen from outside
            idx += [base, base + 1, base + 2, base + 3] if sign > 0 else [base, base + 3, base + 2, base + 1]
    return np.array(pts), idx


def write_mitsuba_cornell(path: Path, res: int = 256) -> dict:
    """Writes mi.cornell_box() as a USD stage (module docstring); returns its description."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender, UsdShade
    d = cornell_box_dict()
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(root.GetPrim())
    mats = {}

    def material(refl):
        key = tuple(round(c, 7) for c in refl)
        if key in mats:
            return mats[key]
        name = f"/World/Looks/M{len(mats)}"
        m = UsdShade.Material.Define(stage, name)
        sh = UsdShade.Shader.Define(stage, name + "/Surface")
        sh.CreateIdAttr("UsdPreviewSurface")
        sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*refl))
        sh.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
        sh.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
        m.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        mats[key] = m
        return m

    sq_pts = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    cube_pts, cube_idx = _unit_cube()
    for name, (kind, m, refl, em) in d["shapes"].items():
        prim_name = "/World/" + name.replace("-", "_")
        if em is not None:
            # A one-sided emitting rectangle: UsdLux RectLight (emits toward its local -Z;
            # Mitsuba's rectangle toward its +z), same centre, size, facing, radiance.
            ex, ey, ez = m[:3, 0], m[:3, 1], m[:3, 2]
            n = ez / np.linalg.norm(ez)
            lx = ex / np.linalg.norm(ex)
            ly = np.cross(-n, lx)
            xf = np.eye(4)
            xf[:3, 0], xf[:3, 1], xf[:3, 2], xf[:3, 3] = lx, ly, -n, m[:3, 3]
            light = UsdLux.RectLight.Define(stage, prim_name)
            light.CreateWidthAttr(float(2 * np.linalg.norm(ex)))
            light.CreateHeightAttr(float(2 * np.linalg.norm(ey)))
            peak = max(em)
            light.CreateIntensityAttr(float(peak))
            light.CreateColorAttr(Gf.Vec3f(*[c / peak for c in em]))
            light.CreateNormalizeAttr(False)
            UsdGeom.Xformable(light).AddTransformOp().Set(Gf.Matrix4d(*xf.T.flatten().tolist()))
            continue
        mesh = UsdGeom.Mesh.Define(stage, prim_name)
        pts, idx = (sq_pts, [0, 1, 2, 3]) if kind == "rectangle" else (cube_pts, cube_idx)
        world = (np.c_[pts, np.ones(len(pts))] @ m.T)[:, :3]
        mesh.CreatePointsAttr([Gf.Vec3f(*map(float, p)) for p in world])
        mesh.CreateFaceVertexCountsAttr([4] * (len(idx) // 4))
        mesh.CreateFaceVertexIndicesAttr(idx)
        mesh.CreateSubdivisionSchemeAttr("none")
        mesh.CreateDoubleSidedAttr(True)
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material(refl))
    cam_d = d["camera"]
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    focal = 50.0
    aperture = 2 * focal * math.tan(math.radians(cam_d["fov"]) / 2)
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(aperture)
    cam.CreateVerticalApertureAttr(aperture)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.001, 100.0))
    # Mitsuba's sensor looks along its +z with x flipped; a USD camera along its -Z.
    m = cam_d["to_world"] @ np.diag([-1.0, 1, -1, 1])
    UsdGeom.Xformable(cam).AddTransformOp().Set(Gf.Matrix4d(*m.T.flatten().tolist()))
    rs = UsdRender.Settings.Define(stage, "/Render/Settings")
    rs.CreateResolutionAttr(Gf.Vec2i(res, res))
    rs.CreateCameraRel().SetTargets([cam.GetPath()])
    # The reconstruction Mitsuba's film gets below (_MITSUBA_CHILD): the one-pixel box,
    # each sample to its own pixel (cmlt's default is a gaussian splat over 3x3 pixels).
    rs.GetPrim().CreateAttribute("cmlt:pixelFilter", Sdf.ValueTypeNames.Token, False,
                                 Sdf.VariabilityUniform).Set("box")
    stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().Save()
    return dict(source=d["source"], max_depth=cam_d["max_depth"])


# ----------------------------------------------------------------------------- runs

_MITSUBA_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
from cmlt.accuracy.peers.mitsuba import setup_llvm_env
setup_llvm_env()
import mitsuba as mi, drjit as dr
variant, spp, res, threads = {variant!r}, {spp}, {res}, {threads}
mi.set_variant(variant)
dr.set_thread_count(threads)
d = mi.cornell_box()
d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = res
d["sensor"]["film"]["rfilter"] = {{"type": "box"}}
# Russian roulette from the third scattering event, as cmlt's path tracer
# (PathTracer::k_rr_start_depth; the same rule, min(0.95, max(beta) eta^2)): the same
# work per sample. Mitsuba's default starts at the fifth (--mitsuba-rr-depth 5).
d["integrator"]["rr_depth"] = {rr_depth}
d["sensor"]["sampler"]["sample_count"] = spp
scene = mi.load_dict(d)
def render(seed):
    img = mi.render(scene, spp=spp, seed=seed)
    if not variant.startswith("scalar"):
        dr.eval(img); dr.sync_thread()
    return img
t1 = time.perf_counter(); render(0); t2 = time.perf_counter()
import numpy as np
img = np.array(render(1)); t3 = time.perf_counter()
print(json.dumps(dict(first_s=t2 - t1, render_s=t3 - t2, process_to_first_s=t2 - t0,
                      mean=float(img.mean()))))
"""


def run_mitsuba(variant: str, spp: int, res: int, threads: int, rr_depth: int = 3) -> dict:
    code = _MITSUBA_CHILD.format(root=str(ROOT / "src"), variant=variant, spp=spp, res=res, threads=threads,
                                 rr_depth=rr_depth)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"mitsuba {variant}: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else p.returncode}")
    out = json.loads(p.stdout.strip().splitlines()[-1])
    n = res * res * spp
    # the whole process up to the end of the first render (import, load, JIT, render)
    return dict(samples_s=n / out["render_s"], samples_s_startup=n / out["process_to_first_s"],
                mean=out["mean"], render_s=out["render_s"], wall_s=time.perf_counter() - t0)


def run_cmlt(stage: Path, integrator: str, spp: int, res: int, threads: int, max_depth: int,
             tmp: Path, extra: List[str]) -> dict:
    out = tmp / f"{integrator}.####.exr"
    cmd = CMLT + ["render", str(stage), "--integrator", integrator, "--spp", str(spp),
                  "--res", f"{res}x{res}", "--threads", str(threads), "--out", str(out), "--quiet",
                  "--seed", "1"] + (["--max-depth", str(max_depth)] if max_depth else []) + extra
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=str(ROOT))
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"cmlt {integrator}: {p.stderr.strip()}")
    side = sorted(tmp.glob(f"{integrator}.*.exr.json"))[-1]
    st = json.loads(side.read_text())["stats"]
    n = res * res * spp
    busy = st.get("busy_s") or 0.0
    thr = st.get("threads") or threads
    rays = st.get("rays") or 0
    return dict(samples_s=n / st["time_s"], samples_s_startup=n / wall, render_s=st["time_s"],
                wall_s=wall, trace_share=(st.get("trace_s", 0.0) / busy) if busy else float("nan"),
                mrays_thread=rays / busy / 1e6 if busy else float("nan"),
                rays_per_sample=rays / n)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64, help="pt samples per pixel (bdpt: a quarter)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--shots", default="mitsuba_cornell,caustic_glass,textured_dome,dense",
                    help="mitsuba_cornell and names under sequences/ (dense is generated by its make_shot.py)")
    ap.add_argument("--integrators", default="pt,bdpt")
    ap.add_argument("--mitsuba", default="scalar_rgb,llvm_ad_rgb", help="Mitsuba variants ('' for none)")
    ap.add_argument("--cmlt-args", default="", help="extra cmlt render flags, e.g. '--kernel general'")
    ap.add_argument("--mitsuba-rr-depth", type=int, default=3,
                    help="Mitsuba's rr_depth: 3 starts its Russian roulette where cmlt's does (the same "
                         "work per sample); 5 is Mitsuba's default")
    ap.add_argument("--out", default="renders/bench/speed")
    args = ap.parse_args(argv)

    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    stages: Dict[str, Path] = {}
    desc = {}
    for shot in [s for s in args.shots.split(",") if s]:
        if shot == "mitsuba_cornell":
            stages[shot] = out / "mitsuba_cornell.usda"
            desc = write_mitsuba_cornell(stages[shot], args.res)
        elif shot == "dense":
            p = ROOT / "sequences/dense/shot.usdc"
            if not p.exists():
                subprocess.run([sys.executable, str(ROOT / "sequences/dense/make_shot.py")], check=True)
            stages[shot] = p
        else:
            stages[shot] = ROOT / "sequences" / shot / "shot.usda"
    integrators = [s for s in args.integrators.split(",") if s]
    variants = [s for s in args.mitsuba.split(",") if s]
    extra = args.cmlt_args.split() if args.cmlt_args else []
    max_depth = desc.get("max_depth", 8) - 1

    results: Dict[tuple, List[dict]] = {}
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        for rep in range(args.repeats):
            for shot, stage in stages.items():
                jobs = [("cmlt", i) for i in integrators]
                if shot == "mitsuba_cornell":
                    jobs += [("mitsuba", v) for v in variants]
                for who, what in jobs:
                    key = (shot, who, what)
                    try:
                        if who == "cmlt":
                            spp = args.spp if what == "pt" else max(1, args.spp // 4)
                            extra_shot = extra + (["--rendering-space", "lin_rec709"] if shot == "mitsuba_cornell" else [])
                            r = run_cmlt(stage, what, spp, args.res, args.threads,
                                         max_depth if shot == "mitsuba_cornell" else 0, tmp / shot, extra_shot)
                        else:
                            r = run_mitsuba(what, args.spp, args.res, args.threads, args.mitsuba_rr_depth)
                    except Exception as e:  # a peer that does not run is reported, not fatal
                        print(f"  {shot} {who} {what}: failed: {e}", file=sys.stderr)
                        continue
                    results.setdefault(key, []).append(r)
                    print(f"  [{rep + 1}/{args.repeats}] {shot} {who} {what}: {r['samples_s']:.3g} samples/s"
                          f" ({r['samples_s_startup']:.3g} with start-up)", file=sys.stderr, flush=True)

    med = {k: {f: statistics.median([r[f] for r in v]) for f in v[0]} for k, v in results.items()}
    lines = [f"Speed, {args.res}x{args.res}, {args.threads} threads, pt {args.spp} spp, bdpt {max(1, args.spp // 4)} spp,"
             f" median of {args.repeats} (interleaved); {desc.get('source', '')}, Mitsuba's rr_depth"
             f" {args.mitsuba_rr_depth}", "",
             "| shot | renderer | samples/s | samples/s incl. start-up | × Mitsuba scalar | × Mitsuba llvm |"
             " Mrays/s/thread | trace share | rays/sample |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for (shot, who, what), m in med.items():
        ref_s = med.get((shot, "mitsuba", "scalar_rgb"), {}).get("samples_s")
        ref_l = med.get((shot, "mitsuba", "llvm_ad_rgb"), {}).get("samples_s")
        f = lambda v, spec: "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)
        lines.append(f"| {shot} | {who} {what} | {f(m['samples_s'], '.3g')} | {f(m['samples_s_startup'], '.3g')} |"
                     f" {f(m['samples_s'] / ref_s if ref_s else None, '.2f')} |"
                     f" {f(m['samples_s'] / ref_l if ref_l else None, '.2f')} |"
                     f" {f(m.get('mrays_thread'), '.2f')} | {f(m.get('trace_share'), '.0%')} |"
                     f" {f(m.get('rays_per_sample'), '.2f')} |")
    table = "\n".join(lines)
    print(table)
    (out / "speed.md").write_text(table + "\n")
    (out / "speed.json").write_text(json.dumps({" ".join(k): v for k, v in results.items()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
