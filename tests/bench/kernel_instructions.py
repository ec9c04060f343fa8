#!/usr/bin/env python3
"""Instructions a frame executes, by callgrind (benchmark, not a test).

Renders a static, pinhole, untextured Lambertian Cornell box — sequences/cornell at
frame 1 (its boxes move between frames, never within the closed shutter) with every
material made an exact Lambertian: UsdPreviewSurface in the specular workflow with
specularColor 0 (F0 = 0, preview_surface.cpp note 1) — under
``valgrind --tool=callgrind``, collecting only inside the integrator's per-sample entry
(``--toggle-collect``), and prints the instruction count (Ir) of each variant:

* ``preview``: the materials through the general UsdPreviewSurface model (what every
  frame runs today);
* ``lambert``: the same colours as legacy Lambert materials (``set_materials`` without
  params): the BSDF a diffuse-only specialisation would run; the image agrees with
  ``preview`` to float rounding (printed).

    .venv/bin/python tests/bench/kernel_instructions.py --res 64x64 --spp 4 \\
        [--integrator pt] [--variants preview,lambert] [--annotate 25]

Needs valgrind (Debian: ``apt-get install valgrind``); each variant takes a few minutes
(usd-core's import under valgrind dominates). One thread: the counts are exact and
the same on every run.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: where collection starts (callgrind --toggle-collect): pt per sample; bdpt its frame
#: function (BdptTracer methods nest, and a nested match would toggle collection off)
ENTRY = {"pt": "cmlt::PathTracer::pixel_sample*", "bdpt": "cmlt::render_bdpt*"}


def child(variant: str, integrator: str, res, spp: int, out: str) -> None:
    import numpy as np
    import cmlt._core as core
    from cmlt.shot.bridge import SceneBridge
    from cmlt.usd import load_frame, open_stage

    fs = load_frame(open_stage(str(ROOT / "sequences/cornell/shot.usda")), 1.0, resolution=res)
    for m in fs.materials:                  # exact Lambertian: F0 = 0
        m.use_specular_workflow = True
        m.specular = (0.0, 0.0, 0.0)
    scene = SceneBridge(core).update(fs)
    if variant == "lambert":
        scene.set_materials(np.array([m.diffuse for m in fs.materials], np.float32),
                            np.array([m.emission for m in fs.materials], np.float32))
        scene.commit()
    elif variant != "preview":
        raise SystemExit(f"unknown variant {variant!r}")
    st = core.RenderSettings()
    st.width, st.height = res
    st.spp, st.threads, st.integrator, st.seed = spp, 1, integrator, 1
    r = core.render(scene, st)
    np.save(out, np.asarray(r.image))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", default="64x64")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--integrator", default="pt", choices=sorted(ENTRY))
    ap.add_argument("--variants", default="preview,lambert")
    ap.add_argument("--annotate", type=int, default=0, metavar="N",
                    help="print the N most expensive functions (inclusive) of each variant")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    res = tuple(int(v) for v in args.res.lower().split("x"))
    if args.child:
        child(args.child, args.integrator, res, args.spp, args.out)
        return 0
    import numpy as np
    tmp = Path(tempfile.mkdtemp(prefix="cmlt_callgrind_"))
    counts, images = {}, {}
    for v in [s for s in args.variants.split(",") if s]:
        cg, img = tmp / f"{v}.callgrind", tmp / f"{v}.npy"
        cmd = ["valgrind", "--tool=callgrind", "--collect-atstart=no",
               f"--toggle-collect={ENTRY[args.integrator]}", f"--callgrind-out-file={cg}",
               sys.executable, __file__, "--child", v, "--out", str(img), "--res", args.res,
               "--spp", str(args.spp), "--integrator", args.integrator]
        p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT,
                           env=dict(os.environ, PYTHONWARNINGS="ignore"))
        m = re.search(r"Collected : (\d+)", p.stderr)
        if p.returncode != 0 or not m:
            sys.stderr.write(p.stderr[-2000:])
            return 1
        counts[v] = int(m.group(1))
        images[v] = np.load(img)
        print(f"{v:8s} {counts[v]:>14,d} Ir  ({counts[v] / (res[0] * res[1] * args.spp):,.0f} "
              f"per sample)", flush=True)
        if args.annotate:
            a = subprocess.run(["callgrind_annotate", "--inclusive=yes", str(cg)],
                               capture_output=True, text=True).stdout.splitlines()
            rows = [l for l in a if re.match(r"\s*[\d,]+ \(", l) and "cmlt::" in l or
                    "embree" in l and re.match(r"\s*[\d,]+ \(", l)]
            for l in rows[:args.annotate]:
                print("   ", l[:160])
    base = counts.get("preview")
    for v, c in counts.items():
        if base and v != "preview":
            diff = float(np.abs(images[v] - images["preview"]).max())
            print(f"{v} / preview = {c / base:.3f} ({(1 - c / base) * 100:.1f} % fewer "
                  f"instructions); largest pixel difference {diff:.3g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
