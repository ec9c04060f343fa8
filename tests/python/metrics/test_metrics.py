"""cmlt.metrics on synthetic sequences with known answers (DESIGN.md §4),
sequence loading, and the `cmlt flicker` / `cmlt compare` commands."""
import json
import math
import os

import numpy as np
import pytest

from cmlt.cli import main
from cmlt.io.exr import write_exr
from cmlt.metrics import MetricsError, compare, flicker, load_sequence, rel_mse


def _ref(h=16, w=24, seed=0):
    rng = np.random.default_rng(seed)
    return 0.2 + rng.random((h, w, 3))


# --- metrics with known answers ------------------------------------------------------

def test_constant_sequence_equal_to_reference_is_zero():
    R = _ref()
    rep = flicker([R.copy() for _ in range(6)], R)
    assert rep.mode == "reference" and rep.static_reference
    assert rep.tf == 0.0 and rep.gf == 0.0 and rep.mean_rel_mse == 0.0
    assert rep.rel_mse == [0.0] * 6 and rep.delta[0] is None
    # the same with one reference per frame, and without a reference
    rep = flicker(np.stack([R] * 6), np.stack([R] * 6))
    assert not rep.static_reference and rep.tf == rep.gf == rep.mean_rel_mse == 0.0
    rep = flicker([R] * 6)
    assert rep.mode == "frame-difference" and rep.tf == 0.0 and rep.gf == 0.0


@pytest.mark.parametrize("n", [8, 9])
def test_global_oscillation(n):
    """I_f = R (1 + 0.1 (-1)^f): E_f = 0.1 (-1)^f R, so |E_{f+1} - E_f| = 0.2 R and
    TF = 0.2 mean R / mean R = 0.2; I_f/R_f alternates 1.1, 0.9 around 1 so the
    population std is 0.1 for even n and 0.1*sqrt(1 - 1/n^2) for odd n."""
    R = _ref()
    frames = list(range(1, n + 1))
    I = [R * (1 + 0.1 * (-1) ** f) for f in frames]
    rep = flicker(I, R, frames=frames)
    assert rep.tf == pytest.approx(0.2, rel=1e-12)
    gf = 0.1 if n % 2 == 0 else 0.1 * math.sqrt(1 - 1 / n ** 2)
    assert rep.gf == pytest.approx(gf, rel=1e-12)        # population std (ddof=0)
    assert rep.gf != pytest.approx(np.std(rep.ratio, ddof=1), rel=1e-6)
    assert rep.ratio[0] == pytest.approx(0.9) and rep.ratio[1] == pytest.approx(1.1)
    # relMSE by hand: (0.1 R)^2 / (R^2 + 1e-2), averaged
    expect = float(np.mean((0.1 * R) ** 2 / (R ** 2 + 1e-2)))
    assert rep.mean_rel_mse == pytest.approx(expect, rel=1e-12)
    # without a reference: |I_{f+1} - I_f| = 0.2 R; normalised by the sequence's mean I
    nd = flicker(I, frames=frames)
    mean_i = np.mean([im.mean() for im in I])
    assert nd.tf == pytest.approx(0.2 * R.mean() / mean_i, rel=1e-12)
    ratios = np.array([im.mean() for im in I]) / mean_i
    assert nd.gf == pytest.approx(float(np.std(ratios)), rel=1e-12)


def test_tf_by_hand_on_a_ramp_with_per_frame_reference():
    """Per-frame references R_f = (1 + f/10) R, errors E_f = c_f R with c = 0, .1, -.1, .3:
    TF = mean(|.1|, |-.2|, |.4|) * mean R / mean_f mean R_f."""
    R = _ref()
    c = [0.0, 0.1, -0.1, 0.3]
    refs = [(1 + f / 10) * R for f in range(4)]
    I = [refs[f] + c[f] * R for f in range(4)]
    rep = flicker(I, refs)
    norm = np.mean([r.mean() for r in refs])
    assert rep.normaliser == pytest.approx(norm)
    assert rep.tf == pytest.approx(np.mean([0.1, 0.2, 0.4]) * R.mean() / norm, rel=1e-12)
    ratios = [(refs[f].mean() + c[f] * R.mean()) / refs[f].mean() for f in range(4)]
    assert rep.gf == pytest.approx(float(np.std(ratios)), rel=1e-12)


def test_independent_noise_matches_the_gaussian_expectation():
    """E_f iid N(0, s^2) per pixel: E|E_{f+1} - E_f| = 2 s / sqrt(pi)."""
    rng = np.random.default_rng(7)
    R = np.full((64, 64, 3), 2.0)
    s = 0.05
    I = [R + rng.normal(0, s, R.shape) for _ in range(12)]
    rep = flicker(I, R)
    assert rep.tf == pytest.approx(2 * s / math.sqrt(math.pi) / 2.0, rel=0.02)
    # the mean over 12k px of noise s: GF ~ s / sqrt(12288) / 2, tiny but not 0
    assert 0 < rep.gf < 5 * s / math.sqrt(R.size) / 2.0
    assert rep.mean_rel_mse == pytest.approx(s * s / (4 + 1e-2), rel=0.03)
    # frame-difference mode sees the same noise (mean I ~ 2)
    assert flicker(I).tf == pytest.approx(rep.tf, rel=0.01)
    # correlated noise (the same error every frame) has no temporal flicker
    E = rng.normal(0, s, R.shape)
    rep = flicker([R + E] * 5, R)
    assert rep.tf == 0.0 and rep.mean_rel_mse > 0


def test_shape_and_count_errors():
    R = _ref()
    with pytest.raises(MetricsError, match="reference is 12x10"):
        flicker([R, R], np.ones((10, 12, 3)))
    with pytest.raises(MetricsError, match="3 images but 2 reference"):
        flicker([R, R, R], [R, R])
    with pytest.raises(MetricsError, match="image 1 has shape"):
        flicker([R, R[:8]])
    with pytest.raises(MetricsError, match="black"):
        flicker([R, R], np.zeros_like(R))
    assert flicker([R]).tf is None


def test_compare():
    B = _ref()
    A = B * 1.1
    res = compare(A, B)
    assert res["mean_ratio"] == pytest.approx(1.1)
    assert res["rmse"] == pytest.approx(math.sqrt(np.mean((0.1 * B) ** 2)))
    assert res["max_abs_diff"] == pytest.approx(float((0.1 * B).max()))
    assert res["rel_mse"] == pytest.approx(rel_mse(A, B))
    assert res["psnr"] == pytest.approx(10 * math.log10(B.max() ** 2 / np.mean((0.1 * B) ** 2)))
    assert compare(B, B)["psnr"] == math.inf
    with pytest.raises(MetricsError, match="but b is"):
        compare(B, B[:4])


# --- loading ----------------------------------------------------------------------------

def _write_seq(d, name, images, start=1, pattern="{}.{:04d}.exr"):
    os.makedirs(d, exist_ok=True)
    paths = []
    for k, im in enumerate(images):
        p = os.path.join(str(d), pattern.format(name, start + k))
        write_exr(p, im)
        paths.append(p)
    return paths


def test_load_sequence_patterns_globs_and_lists(tmp_path):
    R = _ref(8, 10).astype(np.float32)
    imgs = [R * (k + 1) for k in range(12)]
    paths = _write_seq(tmp_path, "shot", imgs, start=1)
    # a decoy with other padding is not part of shot.####.exr
    write_exr(str(tmp_path / "shot.13.exr"), R)
    for spec in ("shot.####.exr", "shot.$F4.exr", "shot.%04d.exr"):
        frames, images = load_sequence(str(tmp_path / spec))
        assert frames == [float(f) for f in range(1, 13)], spec
        assert images[0].dtype == np.float64 and images[0].shape == (8, 10, 3)
        np.testing.assert_allclose(images[9], imgs[9])
    frames, _ = load_sequence(str(tmp_path / "shot.00*.exr"))
    assert frames[:3] == [1.0, 2.0, 3.0] and len(frames) == 12
    frames, images = load_sequence(list(reversed(paths)))      # sorted by number
    assert frames[0] == 1.0 and np.allclose(images[0], imgs[0])
    frames, _ = load_sequence(str(tmp_path / "shot.####.exr"), frames=[2, 5])
    assert frames == [2.0, 5.0]


def test_load_sequence_rgb_of_multichannel_exr(tmp_path):
    import OpenImageIO as oiio
    h, w = 4, 5
    rgb = np.random.default_rng(1).random((h, w, 3)).astype(np.float32)
    extra = np.full((h, w, 2), 9.0, np.float32)
    spec = oiio.ImageSpec(w, h, 5, oiio.FLOAT)
    spec.channelnames = ("R", "G", "B", "diffuse.R", "depth.Z")
    data = np.concatenate([rgb, extra], axis=2)
    p = str(tmp_path / "multi.0001.exr")
    out = oiio.ImageOutput.create(p)
    assert out.open(p, spec) and out.write_image(data)
    out.close()
    _, images = load_sequence([p])
    np.testing.assert_allclose(images[0], rgb)


def test_load_sequence_errors_name_the_files(tmp_path):
    R = _ref(8, 10).astype(np.float32)
    _write_seq(tmp_path, "shot", [R] * 5)
    os.remove(tmp_path / "shot.0003.exr")
    with pytest.raises(MetricsError, match=r"missing frame\(s\) 3.*shot\.0003\.exr"):
        load_sequence(str(tmp_path / "shot.####.exr"))
    with pytest.raises(MetricsError, match="no files match"):
        load_sequence(str(tmp_path / "nothing.####.exr"))
    with pytest.raises(MetricsError, match=r"shot\.0003\.exr"):
        load_sequence(str(tmp_path / "shot.####.exr"), frames=[1, 2, 3])
    write_exr(str(tmp_path / "shot.0003.exr"), np.ones((4, 4, 3)))
    with pytest.raises(MetricsError, match=r"shot\.0003\.exr is 4x4 but .*shot\.0001\.exr is 10x8"):
        load_sequence(str(tmp_path / "shot.####.exr"))


# --- the CLI ------------------------------------------------------------------------------

@pytest.fixture
def three(tmp_path):
    R = _ref(8, 10).astype(np.float32)
    seq = _write_seq(tmp_path / "renders", "shot", [R * 1.0, R * 1.1, R * 0.9])
    refs = _write_seq(tmp_path / "ref", "shot", [R] * 3)
    return tmp_path, R, seq, refs


def test_cli_flicker_table_json_plot(three, capsys):
    tmp, R, seq, refs = three
    js, png = tmp / "out" / "f.json", tmp / "out" / "f.png"
    code = main(["flicker", str(tmp / "renders" / "shot.####.exr"),
                 "--reference", str(tmp / "ref" / "shot.####.exr"),
                 "--json", str(js), "--plot", str(png)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "TF" in out and "GF" in out and "relMSE" in out
    for frame in ("1", "2", "3"):
        assert any(line.strip().split("│")[1:2] and line.split("│")[1].strip() == frame
                   for line in out.splitlines() if "│" in line), out
    data = json.loads(js.read_text())
    for key in ("mode", "frames", "mean", "ratio", "delta", "tf", "gf", "rel_mse",
                "mean_rel_mse", "reference_mean", "normaliser", "sequence", "reference"):
        assert key in data, key
    assert data["frames"] == [1.0, 2.0, 3.0] and data["mode"] == "reference"
    assert data["tf"] == pytest.approx((0.1 + 0.2) / 2, rel=1e-5)
    assert data["gf"] == pytest.approx(np.std([1.0, 1.1, 0.9]), rel=1e-5)
    assert png.exists() and png.stat().st_size > 1000
    # static reference (one file) gives the same numbers
    code = main(["flicker", str(tmp / "renders" / "shot.####.exr"), "--reference", refs[0],
                 "--json", "-"])
    out, _ = capsys.readouterr()
    assert code == 0 and json.loads(out)["static_reference"] is True
    assert json.loads(out)["tf"] == pytest.approx(data["tf"])
    # no reference: frame-difference mode
    code = main(["flicker", str(tmp / "renders" / "shot.####.exr"), "--plot", str(png)])
    out, _ = capsys.readouterr()
    assert code == 0 and "frame differences" in out


def test_cli_plot_without_matplotlib_is_a_clear_error(three, capsys, monkeypatch):
    """matplotlib is the optional extra `plot`: without it --plot fails before any
    work, naming the extra, and writes nothing."""
    import sys
    tmp, *_ = three
    png = tmp / "out" / "none.png"
    monkeypatch.setitem(sys.modules, "matplotlib", None)     # import matplotlib -> ImportError
    code = main(["flicker", str(tmp / "renders" / "shot.####.exr"), "--plot", str(png)])
    err = capsys.readouterr().err
    assert code == 2 and "--plot needs matplotlib" in err and "cmlt[plot]" in err, err
    assert not png.exists()


def test_cli_compare(three, capsys):
    tmp, R, seq, refs = three
    assert main(["compare", seq[1], refs[1]]) == 0
    out = capsys.readouterr().out
    assert "relMSE" in out and "PSNR" in out
    assert main(["compare", seq[1], refs[1], "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["mean_ratio"] == pytest.approx(1.1, rel=1e-5)
    assert main(["compare", refs[0], refs[1], "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["psnr"] is None     # inf is not JSON


def test_cli_errors(three, capsys):
    tmp, R, seq, refs = three
    code = main(["flicker", str(tmp / "missing" / "shot.####.exr")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("cmlt: error: ") and err.count("\n") == 1
    assert "missing/shot.####.exr" in err
    code = main(["compare", seq[0], str(tmp / "nope.exr")])
    err = capsys.readouterr().err
    assert code == 2 and "nope.exr: no such file" in err and err.count("\n") == 1
    small = tmp / "small.exr"
    write_exr(str(small), np.ones((4, 4, 3)))
    code = main(["compare", seq[0], str(small)])
    err = capsys.readouterr().err
    assert code == 2 and "small.exr" in err and "shot.0001.exr" in err
    code = main(["flicker", str(tmp / "renders" / "shot.####.exr"), "--reference", str(small)])
    err = capsys.readouterr().err
    assert code == 2 and "small.exr is 4x4" in err
    # reference frames that do not match the sequence's frames
    os.remove(refs[2])
    code = main(["flicker", str(tmp / "renders" / "shot.####.exr"),
                 "--reference", str(tmp / "ref" / "shot.####.exr")])
    err = capsys.readouterr().err
    assert code == 2 and "no reference for frame(s) 3" in err and err.count("\n") == 1
    assert main(["flicker"]) == 2
    capsys.readouterr()


def test_motion_compensated_terms_follow_the_flow():
    """An error pattern that moves one pixel right per frame, on a flow that says so:
    the motion-compensated terms are 0 where the plain TF is not; without references
    the images themselves are compared along the flow."""
    from cmlt.metrics.flicker import motion_compensated_terms, motion_compensated_tf
    rng = np.random.default_rng(0)
    H, W, F = 8, 12, 4
    noise = rng.normal(0.0, 0.1, (H, W + F, 3))
    ref = np.ones((F, H, W, 3))
    imgs = np.stack([ref[f] + noise[:, F - f:F - f + W] for f in range(F)])
    yy, xx = np.mgrid[0:H, 0:W]
    fl = np.stack([xx + 1.5, yy + 0.5], -1).astype(np.float64)   # every point moves right by 1
    flow = [fl] * (F - 1)
    terms = motion_compensated_terms(imgs, ref, flow)
    assert len(terms) == F - 1 and max(terms) < 1e-12
    assert flicker(imgs, list(ref)).tf > 0.05
    # without references: the images along the flow (the same moving pattern)
    assert max(motion_compensated_terms(imgs, None, flow)) < 1e-12
    # a flow that points nowhere (nothing hit) gives no term
    nan = [np.full((H, W, 2), np.nan)] * (F - 1)
    assert all(math.isnan(t) for t in motion_compensated_terms(imgs, ref, nan))
    assert math.isnan(motion_compensated_tf(imgs, ref, nan))


def test_cli_flicker_shot_adds_the_motion_compensated_tf(tmp_path, capsys):
    """`cmlt flicker SEQ --reference REF --shot SHOT`: the motion-compensated TF along the
    shot's screen motion, the same number the library computes, below the plain TF on a
    pan whose noise follows the surfaces; a missing shot is a one-line error."""
    import support
    from cmlt.metrics.flicker import motion_compensated_tf
    from cmlt.shot import RenderOptions, render_sequence
    from cmlt.shot.motion import screen_flow
    pan = os.path.join(str(support.SEQUENCES), "camera_pan", "shot.usda")
    res = (32, 24)

    def run(name, spp, seed):
        r = render_sequence(pan, "1:3", str(tmp_path / name / "f.####.exr"),
                            RenderOptions(integrator="pt", resolution=res, spp=spp, seed=seed, threads=0),
                            progress=False, quiet=True)
        return [load_sequence([p])[1][0] for p in r.written]

    imgs, refs = run("r", 8, 1), run("ref", 256, 9)
    out = tmp_path / "f.json"
    code = main(["flicker", str(tmp_path / "r" / "f.####.exr"), "--reference",
                 str(tmp_path / "ref" / "f.####.exr"), "--shot", pan, "--json", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "TF, motion-compensated along" in text
    data = json.loads(out.read_text())
    want = motion_compensated_tf(imgs, refs, screen_flow(pan, "1:3", res))
    assert data["tf_motion_compensated"] == pytest.approx(want, rel=1e-12)
    assert data["delta_motion_compensated"][0] is None and len(data["delta_motion_compensated"]) == 3
    assert 0 < data["tf_motion_compensated"] < 0.8 * data["tf"]
    code = main(["flicker", str(tmp_path / "r" / "f.####.exr"), "--shot", str(tmp_path / "nope.usda")])
    err = capsys.readouterr().err
    assert code == 2 and "nope.usda: no such file" in err and err.count("\n") == 1
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\nthis is not usd {\n")
    code = main(["flicker", str(tmp_path / "r" / "f.####.exr"), "--shot", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and f"--shot {bad}" in err and err.count("\n") == 1, err


# --- the reference's own flicker -----------------------------------------------------------

def _floor_case(tmp, render_noise, seed=3, n=6, h=48, w=64, sigma_ref=0.02):
    """A moving truth T_f; two references T_f + independent noise of sigma_ref (per frame,
    per reference); renders T_f + e_f with e_f = the same error every frame (stored
    seeds: no frame-to-frame error of their own) plus `render_noise` of fresh noise."""
    rng = np.random.default_rng(seed)
    base = 0.3 + rng.random((h, w, 3))
    truth = [base * (1.0 + 0.05 * k) for k in range(n)]
    fixed = 0.05 * rng.standard_normal((h, w, 3))
    renders = [t + fixed + render_noise * rng.standard_normal((h, w, 3)) for t in truth]
    ref_a = [t + sigma_ref * rng.standard_normal((h, w, 3)) for t in truth]
    ref_b = [t + sigma_ref * rng.standard_normal((h, w, 3)) for t in truth]
    f32 = lambda xs: [x.astype(np.float32) for x in xs]
    _write_seq(tmp / "renders", "shot", f32(renders))
    _write_seq(tmp / "refa", "shot", f32(ref_a))
    _write_seq(tmp / "refb", "shot", f32(ref_b))
    return [str(tmp / d / "shot.####.exr") for d in ("renders", "refa", "refb")]


def test_cli_reference_floor_measures_the_references_noise(tmp_path, capsys):
    """Renders whose error never changes (TF 0 against the truth) measured against a noisy
    reference: all of the TF is the reference's, the floor from a second reference says so
    (within 3 %: 48x64x3 values per frame pair) and the command warns. With renders whose
    own error changes 10x more than the reference's, the floor is the same and no warning."""
    seq, ref_a, ref_b = _floor_case(tmp_path / "still", render_noise=0.0)
    js = tmp_path / "still.json"
    code = main(["flicker", seq, "--reference", ref_a, "--reference-check", ref_b, "--json", str(js)])
    out, err = capsys.readouterr()
    assert code == 0, err
    data = json.loads(js.read_text())
    floor = data["reference_floor"]
    # E(|N(0, 2 s^2)|) / mean R: the TF a reference of per-value noise s adds on its own
    norm = float(np.mean([load_sequence(ref_a)[1][k].mean() for k in range(6)]))
    expected = 0.02 * math.sqrt(2.0) * math.sqrt(2.0 / math.pi) / norm
    assert floor["tf"] == pytest.approx(expected, rel=0.03)
    assert data["tf"] == pytest.approx(floor["tf"], rel=0.03)
    assert floor["check"] == ref_b
    assert "reference floor" in out and "less than 3x the reference's own floor" in err

    seq, ref_a, ref_b = _floor_case(tmp_path / "noisy", render_noise=0.2)
    code = main(["flicker", seq, "--reference", ref_a, "--reference-check", ref_b, "--json", "-"])
    out, err = capsys.readouterr()
    assert code == 0, err
    data = json.loads(out)
    assert data["reference_floor"]["tf"] == pytest.approx(expected, rel=0.03)
    assert data["tf"] > 5 * data["reference_floor"]["tf"]
    assert not any("floor" in w for w in data["warnings"])


def test_cli_reference_check_errors_name_the_flag_and_files(tmp_path, capsys):
    seq, ref_a, ref_b = _floor_case(tmp_path, render_noise=0.0, n=3)
    assert main(["flicker", seq, "--reference-check", ref_b]) == 2
    assert "--reference-check needs --reference" in capsys.readouterr().err
    os.remove(str(tmp_path / "refb" / "shot.0002.exr"))
    assert main(["flicker", seq, "--reference", ref_a, "--reference-check", ref_b]) == 2
    err = capsys.readouterr().err
    assert "refb" in err and "no reference for frame(s) 2" in err
