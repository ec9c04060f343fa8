"""The start probe (``mlt_min_starts``, src/core/integrators/mlt/mlt_frame.h, probe_starts):
with ``--mlt-paths auto`` and an auto bootstrap size, a pssmlt/cmlt frame whose chains
would start from fewer than ``mlt_min_starts`` of the bootstrap's samples with light (as
a probe of 16384 samples on keys of their own predicts) is rendered without chains.

Checked here: such a frame is the ``mlt_paths none`` frame bit for bit (the direct pass,
or BDPT with ``chainless_integrator bdpt``); a frame the probe keeps is the frame without
the probe bit for bit; the probe's prediction is the frame's own bootstrap sizing (its
probe count times its bootstrap size); the probe does not run where a setting fixes the
frame (a given bootstrap size or mlt_paths, 0); the frame loop decides a sequence's frames
the same way, records the probe in the sidecar and warns once. That each of the two
estimators is unbiased is tested elsewhere (test_mlt_paths, test_chainless_integrator);
the choice between them reads only the probe's keys, never the bootstrap's.
"""
import json

import numpy as np
import pytest

import cmlt._core as core
import support
from cmlt.shot import RenderOptions, render_sequence
from cmlt.shot.bridge import SceneBridge
from support.scenes import caustic_scene, render_settings

RES = 24


def _settings(integrator, **kw):
    kw.setdefault("spp", 2560)   # a budget whose bootstrap the frame sizes by its own probe
    kw.setdefault("bootstrap_samples", 0)   # auto: the probe decides
    # the chains keep the ball's caustic (by default the direct pass's light tracing
    # renders it, and the chains' class here is too rare for any probe to see)
    kw.setdefault("mlt_traced_caustics", "chains")
    return render_settings(integrator, seed=5, res=RES, chains=64, **kw)


@pytest.fixture(scope="module")
def caustic():
    bridge = SceneBridge(core)
    return bridge.update(caustic_scene())


def _image(r):
    return np.asarray(r.image, np.float64)


@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
def test_01_too_few_starts_is_the_chainless_frame(caustic, integrator):
    r = core.render(caustic, _settings(integrator, mlt_min_starts=10**9))
    st = dict(r.stats)
    assert st["mlt_too_few_starts"] is True and st["paths"] == "none" and st["direct_alone"]
    none = core.render(caustic, _settings(integrator, mlt_paths="none"))
    assert "mlt_expected_starts" not in dict(none.stats)     # mlt_paths given: no probe
    assert np.array_equal(_image(r), _image(none))
    # with bdpt for frames without chains, bdpt's frame
    via = core.render(caustic, _settings(integrator, mlt_min_starts=10**9, chainless_integrator="bdpt"))
    assert dict(via.stats)["integrator"] == "bdpt" and dict(via.stats)["mlt_too_few_starts"] is True
    assert np.array_equal(_image(via), _image(core.render(caustic, _settings("bdpt"))))


@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
def test_02_a_frame_the_probe_keeps_is_unchanged(caustic, integrator):
    kept = core.render(caustic, _settings(integrator, mlt_min_starts=1))
    st = dict(kept.stats)
    assert st["mlt_too_few_starts"] is False and st["paths"] == "caustics" and st["chains"] > 0
    off = core.render(caustic, _settings(integrator, mlt_min_starts=0))
    assert "mlt_expected_starts" not in dict(off.stats)
    assert np.array_equal(_image(kept), _image(off))
    # the prediction is the frame's own sizing: its probe's count times its bootstrap
    assert st["bootstrap_probe"] == 16384
    assert st["mlt_expected_starts"] == pytest.approx(
        st["bootstrap_probe_nonzero"] * st["bootstrap_samples"] / 16384, rel=1e-12)
    assert st["mlt_expected_starts"] >= 1
    # a threshold just above the prediction moves the frame; at it, it stays
    e = st["mlt_expected_starts"]
    above = dict(core.render(caustic, _settings(integrator, mlt_min_starts=int(np.floor(e)) + 1)).stats)
    assert above["mlt_too_few_starts"] is True and above["paths"] == "none"


def test_03_given_bootstrap_size_runs_no_probe(caustic):
    r = core.render(caustic, _settings("cmlt", bootstrap_samples=4096, mlt_min_starts=10**9))
    st = dict(r.stats)
    assert "mlt_expected_starts" not in st and st["paths"] == "caustics"


def test_04_the_frame_loop_decides_and_warns(tmp_path):
    shot = str(support.SEQUENCES / "caustic_glass" / "shot.usda")
    out = str(tmp_path / "f.####.exr")
    opts = dict(integrator="cmlt", resolution=(24, 16), spp=32, threads=2)
    r = render_sequence(shot, "1:2", out, RenderOptions(**opts), progress=False, quiet=True)
    side = [json.loads((tmp_path / f"f.{f:04d}.exr.json").read_text()) for f in (1, 2)]
    for s in side:
        probe = s["temporal"]["start_probe"]
        assert probe["probe"] == 16384 and probe["too_few"] is (probe["expected_starts"] < 64)
        assert s["stats"]["paths"] == ("none" if probe["too_few"] else "caustics")
    assert side[0]["temporal"]["start_probe"]["too_few"]        # the glass ball's caustic: rare
    warned = [w for w in r.warnings if "--mlt-min-starts" in w]
    assert len(warned) == 1
    # with the probe off the chains run
    out2 = str(tmp_path / "g.####.exr")
    render_sequence(shot, "1:1", out2, RenderOptions(**opts, mlt_min_starts=0), progress=False, quiet=True)
    s = json.loads((tmp_path / "g.0001.exr.json").read_text())
    assert "start_probe" not in s["temporal"] and s["stats"]["paths"] == "caustics"
