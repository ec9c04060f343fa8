"""Flicker benchmark (issue 5): independent frames vs stored seeds vs seeds +
carried states vs all three with smoothing, on static_flicker, moving_light and
door_ajar — TF, GF, mean relMSE against per-frame PT references, time per frame.

    .venv/bin/python tests/bench/flicker.py [--res 48] [--frames 1:8] [--spp 16]
        [--ref-spp 512] [--chains 256] [--out bench_out/flicker]

Writes OUT/flicker.md (markdown table) and OUT/flicker.png (TF and GF per
configuration and sequence), and prints the table.
"""
import argparse
import os
import sys
import time

import numpy as np

from cmlt.metrics import flicker, load_image
from cmlt.shot import RenderOptions, render_sequence

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SEQUENCES = ("static_flicker", "moving_light", "door_ajar")
CONFIGS = {
    "independent": dict(seed_per_frame=True, carry_states=False, smooth_normalization=False),
    "stored seeds": dict(seed_per_frame=False, carry_states=False, smooth_normalization=False),
    "seeds + carried": dict(seed_per_frame=False, carry_states=True, smooth_normalization=False),
    "seeds + carried + smoothing": dict(seed_per_frame=False, carry_states=True,
                                        smooth_normalization=True),
}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, default=48)
    ap.add_argument("--frames", default="1:8")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--chains", type=int, default=256)
    ap.add_argument("--out", default=os.path.join("bench_out", "flicker"))
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--integrator", default="pssmlt", help="pssmlt or cmlt")
    ap.add_argument("--ref-integrator", default="bdpt",
                    help="per-frame references (bdpt: light through the door's slit is what "
                    "the path tracer finds slowly)")
    a = ap.parse_args(argv)
    res = (a.res, a.res)
    rows = []
    seqs = [x for x in a.sequences.split(",") if x]
    for seq in seqs:
        shot = os.path.join(ROOT, "sequences", seq, "shot.usda")
        ref = render_sequence(shot, a.frames, os.path.join(a.out, seq, "ref", "r.####.exr"),
                              RenderOptions(integrator=a.ref_integrator, resolution=res, spp=a.ref_spp),
                              progress=False, quiet=True)
        refs = np.stack([load_image(p) for p in ref.written])
        for name, kw in CONFIGS.items():
            t0 = time.perf_counter()
            r = render_sequence(shot, a.frames,
                                os.path.join(a.out, seq, name.replace(" ", "_").replace("+", ""),
                                             "f.####.exr"),
                                RenderOptions(integrator=a.integrator, resolution=res, spp=a.spp,
                                              chains=a.chains, bootstrap_samples=16 * a.chains,
                                              **kw), progress=False, quiet=True)
            dt = (time.perf_counter() - t0) / len(r.written)
            rep = flicker(np.stack([load_image(p) for p in r.written]), refs)
            rows.append((seq, name, rep.tf, rep.gf, rep.mean_rel_mse, dt))
            print(f"{seq:15s} {name:28s} TF {rep.tf:.4f} GF {rep.gf:.5f} "
                  f"relMSE {rep.mean_rel_mse:.4f} {dt:.2f} s/frame", file=sys.stderr)
    lines = ["| sequence | configuration | TF | GF | mean relMSE | s / frame |",
             "|---|---|---:|---:|---:|---:|"]
    lines += [f"| {s} | {n} | {tf:.4f} | {gf:.5f} | {mse:.4f} | {dt:.2f} |"
              for s, n, tf, gf, mse, dt in rows]
    table = "\n".join(lines)
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "flicker.md"), "w") as fh:
        fh.write(f"`{' '.join(['tests/bench/flicker.py'] + (argv or sys.argv[1:]))}`\n\n"
                 + table + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 2, figsize=(11, 4))
        x = np.arange(len(seqs))
        for k, name in enumerate(CONFIGS):
            vals = [r for r in rows if r[1] == name]
            ax[0].bar(x + 0.2 * k, [v[2] for v in vals], 0.2, label=name)
            ax[1].bar(x + 0.2 * k, [v[3] for v in vals], 0.2, label=name)
        for i, t in enumerate(("TF", "GF")):
            ax[i].set_xticks(x + 0.3, seqs)
            ax[i].set_yscale("log")
            ax[i].set_title(f"{t} ({a.integrator}, {a.spp} mutations/px, lower is better)")
        ax[0].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(a.out, "flicker.png"), dpi=100)
    except ImportError:
        pass
    print(table)


if __name__ == "__main__":
    main()
