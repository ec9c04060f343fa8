"""A Metropolis frame without chains (``chainless_integrator``, src/core/integrators/common/
render.cpp): with ``--mlt-paths auto`` a frame whose materials cannot be near-specular has
no caustic paths, so pssmlt and cmlt render it without chains — by the path-traced direct
pass (``pt``), or by BDPT (``bdpt``), which the frame loop picks (``auto``) where the
shot's auto integrator picks it for indirect hot spots (camera_pan); where it picks BDPT
for hard visibility (door_ajar) the frames stay path traced (cmlt.shot.analyse,
CHAINLESS_BDPT_RULES: measured at equal time).

Checked here: a chainless frame with ``bdpt`` is ``--integrator bdpt``'s frame bit for
bit (the same estimator, already tested against pt and the furnaces), and with ``pt``
the direct pass as before; a frame with chains ignores the setting; a part of a frame
(Dask) cannot be rendered by BDPT and says so; the frame loop resolves ``auto`` per shot
(camera_pan: bdpt; door_ajar and the Cornell box: pt), records it in the sidecar and
warns once.
"""
import json

import numpy as np
import pytest

import cmlt._core as core
import support
from cmlt.metrics import load_image
from cmlt.shot import RenderOptions, render_sequence
from cmlt.shot.bridge import SceneBridge
from support.scenes import caustic_scene, cornell_scene, render_settings

RES = 24


def _settings(integrator, **kw):
    kw.setdefault("spp", 8)
    return render_settings(integrator, seed=3, res=RES, chains=64, bootstrap_samples=4096, **kw)


@pytest.fixture(scope="module")
def scenes():
    out = {}
    for name, make in (("cornell", cornell_scene), ("caustic", caustic_scene)):
        bridge = SceneBridge(core)
        out[name] = (bridge, bridge.update(make()))
    return out


def _image(r):
    return np.asarray(r.image, np.float64)


@pytest.mark.parametrize("integrator", ["pssmlt", "cmlt"])
def test_01_a_chainless_frame_by_bdpt_is_bdpts_frame(scenes, integrator):
    _, box = scenes["cornell"]
    bdpt = core.render(box, _settings("bdpt"))
    via = core.render(box, _settings(integrator, chainless_integrator="bdpt"))
    assert dict(via.stats)["integrator"] == "bdpt"
    assert np.array_equal(_image(via), _image(bdpt))
    # pt, and auto (the core alone: pt), keep the direct pass, which is not bdpt's image
    for value in ("pt", "auto"):
        direct = core.render(box, _settings(integrator, chainless_integrator=value))
        st = dict(direct.stats)
        assert st["integrator"] == integrator and st["paths"] == "none"
        assert st["direct_evaluations"] == 8 * RES * RES
        assert not np.array_equal(_image(direct), _image(bdpt))


def test_02_frames_with_chains_ignore_it(scenes):
    _, glass = scenes["caustic"]
    _, box = scenes["cornell"]
    # the ball's caustic on the chains (with the default its light tracing is the direct
    # pass's and no chain starts: mlt_traced_caustics)
    a = core.render(glass, _settings("cmlt", chainless_integrator="bdpt", spp=64, mlt_traced_caustics="chains"))
    b = core.render(glass, _settings("cmlt", chainless_integrator="pt", spp=64, mlt_traced_caustics="chains"))
    assert dict(a.stats)["paths"] == "caustics" and dict(a.stats)["mutations"] > 0
    assert np.array_equal(_image(a), _image(b))
    c = core.render(box, _settings("cmlt", chainless_integrator="bdpt", mlt_paths="all"))
    assert dict(c.stats)["integrator"] == "cmlt" and dict(c.stats)["mutations"] > 0


def test_03_a_part_of_a_chainless_bdpt_frame_is_refused(scenes):
    _, box = scenes["cornell"]
    st = _settings("cmlt", chainless_integrator="bdpt", partial=True, part_row_begin=0,
                   part_row_end=RES // 2, part_chain_begin=0, part_chain_end=0)
    with pytest.raises(core.SettingsError, match="chainless_integrator"):
        core.render(box, st)


def _sequence(tmp_path, name, shot, **kw):
    opts = dict(integrator="cmlt", resolution=(24, 18), spp=8, threads=2, seed=5)
    opts.update(kw)
    out = str(tmp_path / name / "f.####.exr")
    r = render_sequence(str(support.SEQUENCES / shot / "shot.usda"), "1:2", out,
                        RenderOptions(**opts), progress=False, quiet=True)
    side = [json.load(open(p + ".json")) for p in r.written]
    return r, side


def test_04_the_frame_loop_resolves_auto_per_shot(tmp_path):
    # camera_pan: a small light under the ceiling lights the room from a hot spot (the
    # auto integrator's indirect hot spots): bdpt renders its chainless frames, bit for
    # bit as --integrator bdpt
    r, side = _sequence(tmp_path, "pan", "camera_pan")
    for s in side:
        assert s["settings"]["chainless_integrator"] == "bdpt"
        assert s["settings_sources"]["chainless_integrator"].startswith("auto")
        assert "hot spots" in s["settings_sources"]["chainless_integrator"]
        assert s["stats"]["integrator"] == "bdpt"
    rb, _ = _sequence(tmp_path, "pan_bdpt", "camera_pan", integrator="bdpt")
    for pa, pb in zip(r.written, rb.written):
        assert np.array_equal(load_image(pa), load_image(pb))
    # the flag (or the stage) decides over auto
    _, side = _sequence(tmp_path, "pan_pt", "camera_pan", chainless_integrator="pt")
    assert all(s["stats"]["integrator"] == "cmlt" and s["stats"]["paths"] == "none" for s in side)
    # door_ajar: auto picks bdpt for hard visibility, which leaves chainless frames to pt
    _, side = _sequence(tmp_path, "door", "door_ajar")
    for s in side:
        assert s["settings"]["chainless_integrator"] == "pt"
        assert "hard_visibility" in s["settings_sources"]["chainless_integrator"]
        assert s["stats"]["integrator"] == "cmlt" and s["stats"]["paths"] == "none"
    # the Cornell box: light is easy to reach, the direct pass renders it
    _, side = _sequence(tmp_path, "box", "cornell")
    for s in side:
        assert s["settings"]["chainless_integrator"] == "pt"
        assert s["stats"]["integrator"] == "cmlt" and s["stats"]["paths"] == "none"


def test_05_cli_says_bdpt_renders_the_frames(tmp_path, capsys):
    from cmlt.cli import main
    shot = str(support.SEQUENCES / "camera_pan" / "shot.usda")
    assert main(["render", shot, "--frames", "1:2", "--res", "16x12", "--spp", "4", "--threads",
                 "2", "--integrator", "cmlt", "--out", str(tmp_path / "a.####.exr")]) == 0
    err = capsys.readouterr().err
    assert err.count("no caustic paths") == 1 and "rendered by bdpt" in err, err


def test_06_accuracy_measures_what_render_renders():
    """`cmlt accuracy` renders through the core directly: it resolves chainless_integrator
    auto as `cmlt render` does, so a Metropolis integrator is measured as it renders."""
    from cmlt.accuracy.render import IntegratorSpec, ShotFrame
    for shot, want in (("camera_pan", "bdpt"), ("door_ajar", "pt"), ("cornell", "pt")):
        f = ShotFrame(str(support.SEQUENCES / shot / "shot.usda"), resolution=(16, 12), threads=2)
        assert f.settings(IntegratorSpec("cmlt", "cmlt"), spp=4).chainless_integrator == want
        assert f.settings(IntegratorSpec("cmlt", "cmlt", (("chainless_integrator", "pt"),)),
                          spp=4).chainless_integrator == "pt"
