#!/usr/bin/env python3
"""What the kernels and each effect cost, in instructions (callgrind) and time (benchmark,
not a test).

Shots (the frame is built outside valgrind and handed to the child as a pickled
FrameScene, so usd-core never runs under valgrind):

* ``cornell``: a static, pinhole, untextured Lambertian Cornell box — sequences/cornell
  at frame 1 (its boxes move between frames, never within the closed shutter) with
  every material an exact Lambertian (UsdPreviewSurface, specular workflow,
  specularColor 0: F0 = 0);
* ``room`` and one variant per effect: tests/python/effects/effect_stages.py's room (floor,
  back wall, rect light, a cube) with its materials made exact Lambertians, then
  ``motion_blur`` (the cube moving with the shutter open, frame 2), ``depth_of_field``
  (fStop 2.8), ``textures`` (a texture on the floor's diffuseColor), ``dome`` (a plain
  DomeLight added), ``dome_textured`` (a textured one), ``caustics`` (a smooth glass ball
  on the floor under the light).

Each shot renders with ``RenderSettings.kernel`` ``general`` (the full UsdPreviewSurface
model for every material) and ``auto`` (the kernels chosen for the frame,
src/core/analysis/kernel_select.h). Callgrind collects inside the integrator's
frame function only (``--toggle-collect``), one thread, so the instruction counts are exact
and the same on every run; ``--time N`` adds wall time per sample outside valgrind, the variants
interleaved N times (median).

    .venv/bin/python tests/bench/kernel_instructions.py --shots cornell --res 64x64 --spp 4
    .venv/bin/python tests/bench/kernel_instructions.py --res 48x36 --spp 4 --time 3

Needs valgrind (Debian: ``apt-get install valgrind``).
"""
from __future__ import annotations

import argparse
import pickle
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "python" / "effects"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from callgrind_child import run_child  # noqa: E402
#: where collection starts (callgrind --toggle-collect): the integrator's frame function
#: (pt traces a tile's samples in lockstep, so there is no per-sample function to enter;
#: BdptTracer methods nest, and a nested match would toggle collection off); Ir per sample
#: is the frame's count over its samples
ENTRY = {"pt": "cmlt::render_pt*", "bdpt": "cmlt::render_bdpt*"}
SHOTS = ("cornell", "room", "motion_blur", "depth_of_field", "textures", "dome",
         "dome_textured", "caustics")
GLASS = {"opacity": 0.0, "roughness": 0.0, "ior": 1.5}


def _lambertian(fs, keep=()):
    for m in fs.materials:
        if m.name.rsplit("/", 1)[-1] in keep:
            continue
        m.use_specular_workflow = True
        m.specular = (0.0, 0.0, 0.0)
    return fs


def build_frame(shot: str, res, tmp: Path):
    """The FrameScene of a shot (module docstring)."""
    from cmlt.usd import load_frame, open_stage
    if shot == "cornell":
        return _lambertian(load_frame(open_stage(str(ROOT / "sequences/cornell/shot.usda")),
                                      1.0, resolution=res))
    from effect_stages import build, write_texture
    opts, frame = dict(move=True), 1.0
    if shot == "motion_blur":
        opts.update(shutter=(-0.25, 0.25))
        frame = 2.0
    elif shot == "depth_of_field":
        opts.update(f_stop=2.8)
    elif shot == "textures":
        opts.update(floor_textures={"diffuseColor": write_texture(tmp / "floor.png", size=64)})
    elif shot == "dome":
        opts.update(dome="plain")
    elif shot == "dome_textured":
        opts.update(dome=write_texture(tmp / "sky.png", (0.4, 0.6, 0.9), size=64))
    elif shot == "caustics":
        opts.update(sphere=GLASS)
    elif shot != "room":
        raise SystemExit(f"unknown shot {shot!r}")
    path = build(tmp / f"{shot}.usda", **opts)
    return _lambertian(load_frame(open_stage(path), frame, resolution=res), keep=("Sphere",))


def render(fs, kernel: str, integrator: str, res, spp: int):
    import cmlt._core as core
    from cmlt.shot.bridge import SceneBridge
    scene = SceneBridge(core).update(fs)
    st = core.RenderSettings()
    st.width, st.height = res
    st.spp, st.threads, st.integrator, st.seed, st.kernel = spp, 1, integrator, 1, kernel
    return core.render(scene, st), sum(core.lambert_kernel_materials(scene))


def child(frame_file: str, kernel: str, integrator: str, res, spp: int, out: str) -> None:
    import numpy as np
    with open(frame_file, "rb") as f:
        fs = pickle.load(f)
    r, _ = render(fs, kernel, integrator, res, spp)
    np.save(out, np.asarray(r.image))
    with open(out + ".rays", "w") as f:
        f.write(str(int(r.stats["rays"])))


def callgrind(frame_file: Path, kernel: str, args, res, tmp: Path):
    import numpy as np
    tag = f"{frame_file.stem}.{kernel}"
    cg, img = tmp / f"{tag}.callgrind", tmp / f"{tag}.npy"
    counts = run_child(__file__, ENTRY[args.integrator], cg,
                       [frame_file, "--kernel", kernel, "--out", img, "--res", args.res,
                        "--spp", args.spp, "--integrator", args.integrator])
    rays = int(Path(str(img) + ".rays").read_text())
    return counts["Ir"], np.load(img), rays


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", default="48x36")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--integrator", default="pt", choices=sorted(ENTRY))
    ap.add_argument("--shots", default=",".join(SHOTS))
    ap.add_argument("--time", type=int, default=0, metavar="N",
                    help="also time each render N times outside valgrind, interleaved")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--kernel", default="auto", help=argparse.SUPPRESS)
    ap.add_argument("--out", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    res = tuple(int(v) for v in args.res.lower().split("x"))
    if args.child:
        child(args.child, args.kernel, args.integrator, res, args.spp, args.out)
        return 0
    import numpy as np
    tmp = Path(tempfile.mkdtemp(prefix="cmlt_callgrind_"))
    samples = res[0] * res[1] * args.spp
    shots = [s for s in args.shots.split(",") if s]
    frames = {}
    for s in shots:
        frames[s] = tmp / f"{s}.pickle"
        with open(frames[s], "wb") as f:
            pickle.dump(build_frame(s, res, tmp), f)
    rows = {}
    for s in shots:
        row = {}
        for kernel in ("general", "auto"):
            ir, img, rays = callgrind(frames[s], kernel, args, res, tmp)
            row[kernel] = (ir, img, rays)
        with open(frames[s], "rb") as f:
            _, n_lambert = render(pickle.load(f), "auto", args.integrator, (4, 4), 1)
        diff = float(np.abs(row["auto"][1] - row["general"][1]).max())
        g, a = row["general"][0], row["auto"][0]
        rows[s] = row
        print(f"{s:15s} general {g / samples:9,.0f} Ir/sample  auto {a / samples:9,.0f} "
              f"Ir/sample  auto/general {a / g:.3f} ({(1 - a / g) * 100:+.1f} % fewer)  "
              f"rays/sample {row['auto'][2] / samples:.2f}  diffuse-only materials "
              f"{n_lambert}  largest pixel difference {diff:.2g}", flush=True)
    base = rows.get("room")
    if base:
        b = base["auto"][0]
        print("\ncost of each effect against the room (kernel auto, Ir per sample):")
        for s in shots:
            if s in ("room", "cornell"):
                continue
            a = rows[s]["auto"][0]
            print(f"  {s:15s} {a / samples:9,.0f}  x{a / b:.2f}  "
                  f"(rays/sample {rows[s]['auto'][2] / samples:.2f} vs "
                  f"{base['auto'][2] / samples:.2f})")
    if args.time:
        times = {(s, k): [] for s in shots for k in ("general", "auto")}
        loaded = {}
        for s in shots:
            with open(frames[s], "rb") as f:
                loaded[s] = pickle.load(f)
        for _ in range(args.time):
            for s in shots:
                for k in ("general", "auto"):
                    t0 = time.perf_counter()
                    render(loaded[s], k, args.integrator, res, args.spp)
                    times[(s, k)].append(time.perf_counter() - t0)
        print(f"\nwall time per sample, 1 thread, median of {args.time} interleaved runs "
              f"(includes the frame's scene build):")
        for s in shots:
            g = statistics.median(times[(s, "general")]) / samples * 1e6
            a = statistics.median(times[(s, "auto")]) / samples * 1e6
            print(f"  {s:15s} general {g:7.2f} us  auto {a:7.2f} us  auto/general {a / g:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
