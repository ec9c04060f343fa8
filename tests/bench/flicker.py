"""Flicker benchmark: independent frames vs stored seeds vs seeds + carried states
vs all three with smoothing, per sequence — TF, GF and mean relMSE against
per-frame converged references (DESIGN.md §4), at an equal sample budget per
frame (``--spp``: path evaluations per pixel; never a time budget, so the
numbers do not depend on the machine's load).

    .venv/bin/python tests/bench/flicker.py [--sequences a,b] [--seeds 4] [--res 48]
        [--frames SPEC] [--spp N] [--ref-spp N] [--chains 256] [--integrator cmlt]
        [--configs independent,...] [--pixel-filter gaussian] [--cvvdp] [--out bench_out/flicker]

Every configuration runs with ``--seeds`` shot seeds (1..N) and the table gives the
mean over seeds and its standard error: one seed's relMSE is mostly that seed's luck
(independent frames and stored seeds have the same per-frame error distribution, so
their difference on one seed is noise). Per sequence the budget defaults to the
table below (door_ajar needs 128 mutations per pixel to converge at all); ``--spp``
and ``--ref-spp`` override it for every sequence. References are cached in
OUT/SEQ/ref (reused when shot, size, frames, integrator and spp match). Each is the mean
of two halves rendered with other seeds, and the table's "reference floor" row is the TF
and GF the reference's own noise puts under every value (``reference``): a stored-seeds
TF near it measures the reference, not the render.

Writes OUT/flicker.md (markdown table), OUT/flicker.json (per-frame values: ratio of
mean brightness to the reference, relMSE, TF terms, per seed; per configuration the rms
brightness error of each frame over the seeds and ``gf_correlated``, the GF those errors
would give if they were one draw for every frame: with those per-frame errors, the
floor of GF for any reuse of random numbers; printed too) and OUT/flicker.png (TF
and GF per configuration and sequence, log scale), and prints the table.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

from cmlt.metrics import flicker, load_image, reference_floor
from cmlt.metrics.flicker import motion_compensated_tf
from cmlt.shot.motion import screen_flow
from cmlt.shot import RenderOptions, render_sequence

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: sequence -> (spp, reference spp, frames) defaults (the budget where each converges
#: well enough for flicker to mean something: door_ajar and camera_pan need more)
SEQUENCES = {
    "static_flicker": (16, 512, "1:8"),
    # 8192: with 512 the reference's own noise was most of the stored seeds' TF
    "moving_light": (16, 8192, "1:8"),
    "door_ajar": (128, 4096, "1:8"),
    "camera_pan": (64, 1024, "1:8"),
    "fading_light": (16, 512, "1:24"),
}
CONFIGS = {
    "independent": dict(seed_per_frame=True, carry_states=False, smooth_normalization=False),
    "stored seeds": dict(seed_per_frame=False, carry_states=False, smooth_normalization=False),
    # stored seeds with the film offset kept at 0: the pixels' keys stay on the screen
    "seeds on the screen": dict(seed_per_frame=False, carry_states=False,
                                smooth_normalization=False, _reproject=False),
    "seeds + carried": dict(seed_per_frame=False, carry_states=True, smooth_normalization=False),
    "seeds + carried + smoothing": dict(seed_per_frame=False, carry_states=True,
                                        smooth_normalization=True),
    # the two above with independent pixel-sample numbers (the default, auto, is
    # Owen-scrambled Sobol points: README "Pixel samples")
    "independent (philox)": dict(seed_per_frame=True, carry_states=False, smooth_normalization=False,
                                sampler="independent"),
    "stored seeds (philox)": dict(seed_per_frame=False, carry_states=False, smooth_normalization=False,
                                 sampler="independent"),
    # stored seeds with every pixel's key following the film offset (one motion for the
    # image: the behaviour before the key maps)
    "keys by the film offset": dict(seed_per_frame=False, carry_states=False,
                                    smooth_normalization=False, _pixel_keys=False),
    # everything on with the keys and the chains' film position following the film
    # offset (one motion for the image: the behaviour before the key maps)
    "everything on (film offset)": dict(seed_per_frame=False, carry_states=True,
                                       smooth_normalization=True, _pixel_keys=False),
    # everything on but the chains' film offset kept at 0 (no camera reprojection)
    "all but reprojection": dict(seed_per_frame=False, carry_states=True,
                                        smooth_normalization=True, _reproject=False),
}
DEFAULT_CONFIGS = ("independent", "stored seeds", "seeds + carried", "seeds + carried + smoothing")


def config_dir(name: str) -> str:
    return name.replace(" + ", "_").replace(" ", "_")


#: the two halves of every reference are rendered with these shot seeds (never one of the
#: renders' seeds 1..N, whose random numbers they would share)
REFERENCE_SEEDS = (1001, 1002)


def reference(shot: str, frames: str, out: str, integrator: str, res, spp: int,
              pixel_filter=None):
    """Per-frame references (F, H, W, 3) with the renders' pixel filter (None: the
    stage's), rendered once and cached in ``out``, and the reference's own noise floor.

    A reference is the mean of two halves of ``spp // 2`` paths per pixel each, rendered
    with different seeds. Its own error enters every measured TF and GF (E = I - R), and
    with stored seeds the renders' frame-to-frame error can be smaller than a reference's:
    on moving_light a 512-path reference alone accounted for most of the stored seeds'
    TF. The halves measure it: TF and GF of one half against the other, halved (the
    difference of two halves has twice the variance of one half, their mean half of it;
    `cmlt flicker --reference-check` reports the same for one reference), is the floor
    the reference puts under the table's values -- a value near it says the reference is
    not converged enough to measure it. Returns (references, floor) with
    floor = {"tf": .., "gf": ..}."""
    key = {"shot": os.path.abspath(shot), "frames": frames, "integrator": integrator,
           "res": list(res), "spp": int(spp), "halves": list(REFERENCE_SEEDS)}
    if pixel_filter:
        key["pixel_filter"] = pixel_filter
    meta = os.path.join(out, "ref.json")
    if os.path.exists(meta):
        with open(meta) as fh:
            old = json.load(fh)
        if old.get("key") == key and all(os.path.exists(p) for h in old["written"] for p in h):
            halves = [np.stack([load_image(p) for p in h]) for h in old["written"]]
            return 0.5 * (halves[0] + halves[1]), old["floor"]
    written = []
    for k, seed in enumerate(REFERENCE_SEEDS):
        r = render_sequence(shot, frames, os.path.join(out, f"half{k}", "r.####.exr"),
                            RenderOptions(integrator=integrator, resolution=tuple(res),
                                          spp=max(1, spp // 2), seed=seed,
                                          pixel_filter=pixel_filter),
                            progress=False, quiet=True)
        written.append(list(r.written))
    halves = [np.stack([load_image(p) for p in h]) for h in written]
    # one half's floor (cmlt.metrics.reference_floor), and the mean of two halves has
    # 1/sqrt(2) of a half's noise
    floor = {k: None if v is None else v / math.sqrt(2.0)
             for k, v in reference_floor(halves[0], halves[1]).items()}
    os.makedirs(out, exist_ok=True)
    with open(meta, "w") as fh:
        json.dump({"key": key, "written": written, "floor": floor}, fh)
    return 0.5 * (halves[0] + halves[1]), floor


def render_config(shot: str, frames: str, out: str, integrator: str, res, spp: int, chains: int,
                  seed: int, bootstrap_samples: int = -1, **kw):
    """Render one configuration; returns (images (F, H, W, 3), temporal records,
    seconds per frame)."""
    from cmlt.temporal import driver
    driver.REPROJECT = bool(kw.pop("_reproject", True))
    driver.PIXEL_KEYS = bool(kw.pop("_pixel_keys", True))
    t0 = time.perf_counter()
    r = render_sequence(shot, frames, os.path.join(out, "f.####.exr"),
                        RenderOptions(integrator=integrator, resolution=tuple(res), spp=spp,
                                      chains=chains, seed=seed,
                                      bootstrap_samples=(16 * chains if bootstrap_samples < 0
                                                         else bootstrap_samples),
                                      # the chains' temporal machinery on every path (the
                                      # default, auto, leaves diffuse shots to the direct pass)
                                      mlt_paths=kw.pop("mlt_paths", "all"),
                                      **kw), progress=False, quiet=True)
    dt = (time.perf_counter() - t0) / len(r.written)
    recs = []
    for p in r.written:
        with open(p + ".json") as fh:
            recs.append(json.load(fh).get("temporal", {}))
    return np.stack([load_image(p) for p in r.written]), recs, dt


def plot(rows, seqs, configs, path, what):
    """TF and GF per sequence and configuration, log scale; a value of 0 (a static
    shot with stored seeds) is marked "0" at the axis floor."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(1, 2, figsize=(12, 4))
    x = np.arange(len(seqs))
    width = 0.8 / max(1, len(configs))
    for i, (t, col) in enumerate((("TF", 4), ("GF", 6))):
        vals = [r[col][0] for r in rows if r[1] in configs]
        positive = [v for v in vals if v > 0]
        floor = 0.3 * min(positive) if positive else 1e-3
        for k, name in enumerate(configs):
            v = [next((r[col][0] for r in rows if r[0] == q and r[1] == name), math.nan)
                 for q in seqs]
            bars = ax[i].bar(x + width * k, [max(y, floor) for y in v], width, label=name,
                             color=f"C{k}")
            for bar, y in zip(bars, v):
                if y == 0:
                    ax[i].text(bar.get_x() + bar.get_width() / 2, floor * 1.15, "0",
                               ha="center", va="bottom", fontsize=8, color=f"C{k}")
        ax[i].set_xticks(x + 0.4 - width / 2, seqs, fontsize=8)
        ax[i].set_yscale("log")
        ax[i].set_ylim(bottom=floor)
        ax[i].set_title(f"{t} ({what}; lower is better)", fontsize=9)
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def correlated_gf(profile, draws: int = 20000) -> float:
    """The expected GF of frames whose brightness errors are perfectly correlated (one
    normal amplitude times ``profile``, the per-frame rms error e_f = mean I_f / mean R_f
    - 1 over seeds) -- the least any reuse of random numbers can reach with those
    per-frame errors: GF is a standard deviation over frames, so an error that comes and
    goes (a transient: door_ajar's slit frames) is flicker however well its frames agree.
    Monte Carlo with a fixed generator (std over frames of a x profile, mean over a)."""
    g = np.asarray(profile, np.float64)
    a = np.random.default_rng(12345).standard_normal((draws, 1))
    return float((a * g).std(axis=1).mean())


def _mean_se(values):
    v = np.asarray([x for x in values if x is not None], dtype=np.float64)
    if v.size == 0:
        return math.nan, math.nan
    se = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else math.nan
    return float(v.mean()), se


def _fmt(m, se, digits):
    if not math.isfinite(m):
        return "-"
    s = f"{m:.{digits}f}"
    return s if not math.isfinite(se) else f"{s} ± {se:.{digits}f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", type=int, default=48)
    ap.add_argument("--frames", default=None, help="every sequence (default: its own)")
    ap.add_argument("--spp", type=int, default=None, help="every sequence (default: its own)")
    ap.add_argument("--ref-spp", type=int, default=None, help="every sequence (default: its own)")
    ap.add_argument("--chains", type=int, default=256)
    ap.add_argument("--bootstrap-samples", type=int, default=-1,
                    help="the chains' bootstrap per frame (default 16 per chain; 0: the "
                    "renderer's own choice per frame, which grows it where few samples "
                    "carry light)")
    ap.add_argument("--seeds", type=int, default=4, help="shot seeds 1..N per configuration")
    ap.add_argument("--out", default=os.path.join("bench_out", "flicker"))
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--configs", default=",".join(DEFAULT_CONFIGS),
                    help=f"any of: {', '.join(CONFIGS)}")
    ap.add_argument("--integrator", default="cmlt", help="pssmlt or cmlt")
    ap.add_argument("--mlt-paths", default="all", dest="mlt_paths",
                    help="what the chains render (default all: the chains' temporal machinery "
                         "on every path; auto: the renderer's default)")
    ap.add_argument("--ref-integrator", default="bdpt",
                    help="per-frame references (bdpt: light through the door's slit is what "
                    "the path tracer finds slowly)")
    ap.add_argument("--pixel-filter", default=None, dest="pixel_filter",
                    help="every render's and reference's pixel filter (default: the stage's)")
    ap.add_argument("--cvvdp", action="store_true",
                    help="also ColorVideoVDP JOD against the references (cmlt.metrics.cvvdp; "
                    "needs the optional cvvdp package)")
    ap.add_argument("--cvvdp-seeds", type=int, default=1,
                    help="seeds whose JOD is computed (it takes about a minute per video)")
    a = ap.parse_args(argv)
    res = (a.res, a.res)
    seqs = [x for x in a.sequences.split(",") if x]
    configs = [x for x in a.configs.split(",") if x]
    for c in configs:
        if c not in CONFIGS:
            ap.error(f"--configs: unknown configuration {c!r} (one of {', '.join(CONFIGS)})")
    jod = None
    if a.cvvdp:
        from cmlt.metrics.cvvdp import CvvdpUnavailable, video_jod
        jod = video_jod
    rows, dump = [], {"argv": argv if argv is not None else sys.argv[1:], "sequences": {}}
    for seq in seqs:
        spp, ref_spp, frames = SEQUENCES.get(seq, (16, 512, "1:8"))
        spp = a.spp or spp
        ref_spp = a.ref_spp or ref_spp
        frames = a.frames or frames
        shot = os.path.join(ROOT, "sequences", seq, "shot.usda")
        refs, floor = reference(shot, frames, os.path.join(a.out, seq, "ref"), a.ref_integrator,
                                res, ref_spp, a.pixel_filter)
        print(f"{seq:15s} reference ({a.ref_integrator}, {ref_spp} per pixel) floor: "
              f"TF {floor['tf']:.4f} GF {floor['gf']:.5f}", file=sys.stderr)
        flow = screen_flow(shot, frames, res)
        dseq = dump["sequences"].setdefault(seq, {"spp": spp, "ref_spp": ref_spp, "frames": frames,
                                                  "reference_mean": refs.mean(axis=(1, 2, 3)).tolist(),
                                                  "reference_floor": floor,
                                                  "configs": {}})
        rows.append((seq, f"reference floor ({ref_spp}/px)", ref_spp, frames,
                     (floor["tf"], math.nan), (math.nan, math.nan), (floor["gf"], math.nan),
                     (math.nan, math.nan), (math.nan, math.nan), (math.nan, math.nan)))
        for name in configs:
            per_seed = []
            for seed in range(1, a.seeds + 1):
                out = os.path.join(a.out, seq, config_dir(name), f"seed{seed}")
                kw = dict(CONFIGS[name])
                if a.pixel_filter:
                    kw["pixel_filter"] = a.pixel_filter
                kw["mlt_paths"] = a.mlt_paths
                imgs, recs, dt = render_config(shot, frames, out, a.integrator, res, spp,
                                               a.chains, seed, a.bootstrap_samples, **kw)
                rep = flicker(imgs, refs)
                tf_mc = motion_compensated_tf(imgs, refs, flow)
                j = None
                if jod is not None and seed <= a.cvvdp_seeds:
                    try:
                        j = jod(imgs, refs, fps=24.0)
                    except CvvdpUnavailable as exc:
                        print(f"cvvdp: {exc}", file=sys.stderr)
                        jod = None
                per_seed.append({"seed": seed, "tf": rep.tf, "tf_mc": tf_mc, "gf": rep.gf,
                                 "rel_mse": rep.mean_rel_mse, "s_per_frame": dt,
                                 "ratio": rep.ratio, "delta": rep.delta,
                                 "frame_rel_mse": rep.rel_mse, "jod": j,
                                 "b_used": [r.get("b_used") for r in recs],
                                 "change": [r.get("change_detected") for r in recs]})
                print(f"{seq:15s} {name:28s} seed {seed} TF {rep.tf:.4f} TFmc {tf_mc:.4f} GF {rep.gf:.5f} "
                      f"relMSE {rep.mean_rel_mse:.4f}" + (f" JOD {j:.3f}" if j is not None else "")
                      + f" {dt:.2f} s/frame", file=sys.stderr)
            dseq["configs"][name] = per_seed
            # per-frame rms brightness error over seeds, and the GF the same errors would
            # give if every frame's were the same draw (correlated_gf)
            err = np.array([np.asarray(p["ratio"], np.float64) - 1.0 for p in per_seed])
            profile = np.sqrt((err ** 2).mean(axis=0))
            dseq.setdefault("brightness_rms", {})[name] = profile.tolist()
            dseq.setdefault("gf_correlated", {})[name] = correlated_gf(profile)
            print(f"{seq:15s} {name:28s} rms brightness error per frame "
                  + " ".join(f"{v:.3f}" for v in profile)
                  + f"; GF if perfectly correlated across frames {dseq['gf_correlated'][name]:.4f}",
                  file=sys.stderr)
            rows.append((seq, name, spp, frames) + tuple(
                _mean_se([p[k] for p in per_seed]) for k in ("tf", "tf_mc", "gf", "rel_mse", "jod",
                                                               "s_per_frame")))
    head = "| sequence | configuration | spp | frames | TF | TF, motion-compensated | GF | mean relMSE |"
    rule = "|---|---|---:|---|---:|---:|---:|---:|"
    if a.cvvdp:
        head += " JOD |"
        rule += "---:|"
    lines = [head + " s / frame |", rule + "---:|"]
    for s, n, spp, fr, tf, tfmc, gf, mse, j, dt in rows:
        line = (f"| {s} | {n} | {spp} | {fr} | {_fmt(*tf, 4)} | {_fmt(*tfmc, 4)} | {_fmt(*gf, 4)} "
                f"| {_fmt(*mse, 4)} |")
        if a.cvvdp:
            line += f" {_fmt(*j, 3)} |"
        lines.append(line + (f" {dt[0]:.2f} |" if math.isfinite(dt[0]) else " - |"))
    table = "\n".join(lines)
    os.makedirs(a.out, exist_ok=True)
    cmd = " ".join(["tests/bench/flicker.py"] + list(dump["argv"]))
    with open(os.path.join(a.out, "flicker.md"), "w") as fh:
        fh.write(f"`{cmd}` ({a.integrator}, {a.res}x{a.res}, {a.chains} "
                 f"chains, pixel filter {a.pixel_filter or 'of the stage'}, "
                 f"seeds 1..{a.seeds}: mean ± standard error over seeds)\n\n"
                 + table + "\n")
    with open(os.path.join(a.out, "flicker.json"), "w") as fh:
        json.dump(dump, fh, indent=1)
    plot(rows, seqs, configs, os.path.join(a.out, "flicker.png"),
         f"{a.integrator}, mean of {a.seeds} seeds")
    print(table)


if __name__ == "__main__":
    main()
