"""Frames split into Dask tasks (cmlt.shot.distributed, ``cmlt render --dask``): the
images are bit-identical to one process's, also when a worker dies mid-frame.

* core: a pssmlt/cmlt frame rendered as parts (chain groups + direct-pass rows) and
  combined by ``combine_mlt_parts`` equals the whole frame bit for bit, for uneven
  splits; pt row bands equal the whole frame's rows;
* a 3-frame cmlt sequence (carried chain starts, smoothed b) on
  ``LocalCluster(n_workers=2, threads_per_worker=1)`` equals the single-process one;
* a pt frame with ``cmlt render --dask local:2`` equals the single-process frame;
* killing one worker process while a frame's tasks run still gives the same image.
"""
import json
import os
import signal

import numpy as np
import pytest

import cmlt._core as core  # the real core: an ImportError is a failure, not a skip
from distributed import Client, LocalCluster

from cmlt.cli import main as cli_main
from cmlt.metrics import load_image
from cmlt.shot import RenderOptions, UsageError, render_sequence
from cmlt.shot.bridge import SceneBridge
from cmlt.shot.distributed import part_ranges
from cmlt.temporal.state import state_path
import support
from support.scenes import cornell_scene, with_bulb

PAN = os.path.join(str(support.SEQUENCES), "camera_pan", "shot.usda")
CORNELL = os.path.join(str(support.SEQUENCES), "cornell", "shot.usda")


def _opts(**kw):
    base = dict(integrator="cmlt", resolution=(40, 32), spp=16, chains=64,
                bootstrap_samples=2048, threads=1, mlt_paths="all")
    base.update(kw)
    return RenderOptions(**base)


def _render(tmp, name, shot, frames, client=None, on_part=None, **kw):
    out = os.path.join(str(tmp), name, "f.####.exr")
    return render_sequence(shot, frames, out, _opts(**kw), progress=False, quiet=True,
                           client=client, on_part=on_part)


def _same_images(a, b):
    assert len(a.written) == len(b.written) > 0
    for pa, pb in zip(a.written, b.written):
        ia, ib = load_image(pa), load_image(pb)
        assert ia.shape == ib.shape
        assert np.array_equal(ia, ib), f"{pb}: differs from {pa} by {np.abs(ia - ib).max()}"


@pytest.fixture(scope="module")
def client():
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0")
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


# ---- the core's parts ---------------------------------------------------------------

def _settings(integrator, **kw):
    st = core.RenderSettings()
    st.integrator = integrator
    st.width = st.height = support.scenes.RES
    st.spp, st.chains, st.bootstrap_samples, st.max_depth = 16, 48, 1024, 6
    st.seed, st.threads = 7, 2
    st.mlt_paths = "all"  # the chains on every path (auto: none on a diffuse scene)
    for k, v in kw.items():
        setattr(st, k, v)
    return st


@pytest.mark.parametrize("integrator,bulb", [("pssmlt", False), ("cmlt", False), ("cmlt", True)])
def test01_mlt_parts_combine_to_the_whole_frame(integrator, bulb):
    scene = SceneBridge(core).update(with_bulb(cornell_scene()) if bulb else cornell_scene())
    whole = core.render(scene, _settings(integrator))
    assert whole.mlt_part is None
    assert whole.stats.get("lens_lights", 0) == (1 if bulb else 0)  # the bulb is traced
    H = support.scenes.RES
    splits = [((0, 5), (0, 3)), ((5, 30), (3, 20)), ((30, 48), (20, H))]  # uneven
    parts, direct = [], np.zeros((H, H, 3), np.float32)
    for chains, rows in splits:
        st = _settings(integrator, partial=True, part_chain_begin=chains[0],
                       part_chain_end=chains[1], part_row_begin=rows[0], part_row_end=rows[1])
        r = core.render(scene, st)
        parts.append(r.mlt_part)
        direct[rows[0]:rows[1]] = np.asarray(r.direct)[rows[0]:rows[1]]
        assert r.mlt_part["steps"] > 0
    image, stats = core.combine_mlt_parts(H, H, parts, direct)
    assert np.array_equal(np.asarray(image), np.asarray(whole.image))
    assert stats["b"] == whole.stats["b"] and stats["b_stderr"] == whole.stats["b_stderr"]
    assert stats["mutations"] == whole.stats["mutations"]
    assert np.array_equal(direct, np.asarray(whole.direct))
    # a part alone is not the frame (the test can fail)
    alone, _ = core.combine_mlt_parts(H, H, parts[:1], direct)
    assert not np.array_equal(np.asarray(alone), np.asarray(whole.image))


@pytest.mark.parametrize("bulb", [False, True])
def test02_pt_row_bands_are_the_whole_frames_rows(bulb):
    scene = SceneBridge(core).update(with_bulb(cornell_scene()) if bulb else cornell_scene())
    whole_r = core.render(scene, _settings("pt"))
    assert whole_r.stats.get("lens_lights", 0) == (1 if bulb else 0)  # the bulb is traced
    whole = np.asarray(whole_r.image)
    H = support.scenes.RES
    got = np.zeros_like(whole)
    for y0, y1 in part_ranges(H, 3):
        r = core.render(scene, _settings("pt", partial=True, part_row_begin=y0, part_row_end=y1))
        img = np.asarray(r.image)
        got[y0:y1] = img[y0:y1]
        assert not img[:y0].any() and not img[y1:].any()    # only its rows were rendered
    assert np.array_equal(got, whole)


def test03_bad_parts_are_refused():
    scene = SceneBridge(core).update(cornell_scene())
    with pytest.raises(core.SettingsError, match="part_"):
        core.render(scene, _settings("pt", partial=True, part_row_begin=4, part_row_end=99))
    with pytest.raises(core.SettingsError, match="bdpt"):
        core.render(scene, _settings("bdpt", partial=True, part_row_end=4))
    with pytest.raises(core.SettingsError, match="part 0"):
        core.combine_mlt_parts(8, 8, [{"splat_lo": np.zeros(3, np.uint64),
                                       "splat_hi": np.zeros(3, np.int64),
                                       "norm_counts": np.zeros(2, np.uint64),
                                       "norm_moments": np.zeros(2), "steps": 0}], None)


# ---- sequences on a LocalCluster --------------------------------------------------------

def test04b_chainless_bdpt_frames_run_whole_and_bit_identical(tmp_path, client):
    """cmlt at --mlt-paths auto on camera_pan: its frames have no chains and BDPT renders
    them (chainless_integrator auto: the shot's indirect hot spots), which does not split,
    so each frame is one task — the single process's frames bit for bit."""
    one = _render(tmp_path, "one", PAN, "1:3", mlt_paths="auto")
    dask = _render(tmp_path, "dask", PAN, "1:3", client=client, mlt_paths="auto")
    _same_images(one, dask)
    for p in dask.written:
        s = json.load(open(p + ".json"))
        assert s["settings"]["chainless_integrator"] == "bdpt"
        assert s["stats"]["integrator"] == "bdpt" and s["stats"]["dask"]["parts"] == 1


def test04_cmlt_sequence_on_two_workers_is_bit_identical(tmp_path, client):
    one = _render(tmp_path, "one", PAN, "1:3")
    dask = _render(tmp_path, "dask", PAN, "1:3", client=client)
    _same_images(one, dask)
    side = [json.load(open(p + ".json")) for p in dask.written]
    ref = [json.load(open(p + ".json")) for p in one.written]
    # the automatic parts: one part per frame while two or more frames are left (they
    # run side by side), the last frame one part per worker; and each frame's preparation
    assert [s["stats"]["dask"]["parts"] for s in side] == [1, 1, 2]
    for s, r in zip(side, ref):
        d = s["stats"]["dask"]
        assert d["workers"] == 2 and d["tasks"] == d["parts"] + 1
        assert d["split"] == "chains+rows"
        assert d["bytes_from_workers"] > 0 and d["bytes_to_workers"] > 0
        # the temporal record (carried starts, b used) is the single process's
        assert s["temporal"]["b_used"] == r["temporal"]["b_used"]
        assert s["temporal"]["carried_chains"] == r["temporal"]["carried_chains"]
        assert s["stats"]["mutations"] == r["stats"]["mutations"]
    # the parts are placed on different workers (not where the preparation ran)
    assert all(1 <= s["stats"]["dask"]["part_workers"] <= 2 for s in side)
    assert max(s["stats"]["dask"]["part_workers"] for s in side) == 2
    assert side[2]["temporal"]["carried_chains"] > 0       # frames 2, 3 did carry
    # frames 2 and 3 were submitted while the frame before rendered, their preparations
    # chained on the workers
    assert [s["stats"]["dask"]["submitted_ahead"] for s in side] == [False, True, True]
    assert [s["temporal"]["state_in"] for s in side] == [r["temporal"]["state_in"] for r in ref]


def test05_pt_frame_with_dask_local_2_flag(tmp_path, capsys):
    one = _render(tmp_path, "one", CORNELL, "1", integrator="pt")
    out = os.path.join(str(tmp_path), "cli", "f.####.exr")
    code = cli_main(["render", CORNELL, "--frames", "1", "--out", out, "--integrator", "pt",
                     "--res", "40x32", "--spp", "16", "--threads", "1", "--quiet",
                     "--dask", "local:2"])
    assert code == 0, capsys.readouterr().err
    a, b = load_image(one.written[0]), load_image(out.replace("####", "0001"))
    assert np.array_equal(a, b)
    rec = json.load(open(out.replace("####", "0001") + ".json"))
    assert rec["stats"]["dask"]["split"] == "rows" and rec["stats"]["dask"]["workers"] == 2
    # the relMSE estimate too: the row bands carry each pixel's trimmed mean (its
    # denominator) as they carry the variance
    whole = json.load(open(one.written[0] + ".json"))["stats"]["error_estimate"]
    assert rec["stats"]["error_estimate"]["relmse"] == pytest.approx(whole["relmse"], rel=1e-9)


def test06_worker_killed_mid_frame_same_image(tmp_path, client):
    killed = {}

    def kill_one(done, total, futures):
        # after the first part: kill a worker process that still has parts to run
        if killed:
            return
        processing = client.processing()
        pids = client.run(os.getpid)
        busy = [w for w, keys in processing.items() if keys and w in pids]
        if not busy:
            return
        w = busy[0]
        killed.update(worker=w, pid=pids[w], in_flight=len(processing[w]), done=done)
        os.kill(pids[w], signal.SIGKILL)

    one = _render(tmp_path, "one", PAN, "2", spp=32)
    dask = _render(tmp_path, "dask", PAN, "2", client=client, on_part=kill_one, spp=32,
                   dask_parts=8)
    assert killed, "no worker was busy when the first part arrived"
    assert killed["in_flight"] >= 1 and killed["done"] < 8
    client.wait_for_workers(2, timeout=60)                 # the nanny restarted it
    assert killed["pid"] not in client.run(os.getpid).values()
    _same_images(one, dask)


def test07_time_budget_is_refused(tmp_path, client):
    with pytest.raises(UsageError, match="time budget"):
        _render(tmp_path, "t", PAN, "1", client=client, time_budget=1.0)


def test08_worker_killed_while_frames_are_ahead_same_images(tmp_path, client):
    # a worker dies while the next frames' preparations and parts are queued or held on
    # it: Dask reruns what it lost (the preparations chain from frame to frame) and every
    # image is still the one process's
    calls, killed = [], {}

    def kill_in_second_frame(done, total, futures):
        calls.append(done)
        if killed or len(calls) < total + 1:        # the first part of the second frame
            return
        pids = client.run(os.getpid)
        w = sorted(pids)[0]
        killed.update(worker=w, pid=pids[w])
        os.kill(pids[w], signal.SIGKILL)

    one = _render(tmp_path, "one", PAN, "1:4")
    dask = _render(tmp_path, "dask", PAN, "1:4", client=client, on_part=kill_in_second_frame)
    assert killed, "the second frame's first part never arrived"
    client.wait_for_workers(2, timeout=60)
    assert killed["pid"] not in client.run(os.getpid).values()
    _same_images(one, dask)


def test09_dask_continues_a_sequence_from_the_state_dir(tmp_path, client):
    # the first frame a Dask job renders takes its carried state from --state-dir (the
    # client's), the next ones from the preparation before them (the workers')
    one = _render(tmp_path, "one", PAN, "1:4", state_dir=str(tmp_path / "s1"))
    _render(tmp_path, "dask", PAN, "1:2", state_dir=str(tmp_path / "s2"))
    rest = _render(tmp_path, "dask", PAN, "3:4", client=client, state_dir=str(tmp_path / "s2"))
    side = [json.load(open(p + ".json")) for p in rest.written]
    assert side[0]["temporal"]["state_in"] == os.path.abspath(state_path(str(tmp_path / "s2"), 2))
    assert side[0]["temporal"]["carried_chains"] > 0
    for a, b in zip(one.written[2:], rest.written):
        assert np.array_equal(load_image(a), load_image(b)), b
    for a, b in zip(sorted(os.listdir(tmp_path / "s1")), sorted(os.listdir(tmp_path / "s2"))):
        assert a == b
        assert (tmp_path / "s1" / a).read_bytes() == (tmp_path / "s2" / b).read_bytes()


@pytest.mark.parametrize("integrator", ["pt", "bdpt"])
def test10_pt_bdpt_sequences_pipelined_bit_identical(tmp_path, client, integrator):
    one = _render(tmp_path, "one", PAN, "1:3", integrator=integrator)
    dask = _render(tmp_path, "dask", PAN, "1:3", client=client, integrator=integrator)
    _same_images(one, dask)
    side = [json.load(open(p + ".json"))["stats"]["dask"] for p in dask.written]
    assert [d["submitted_ahead"] for d in side] == [False, True, True]
    # a preparation per frame (seed, film offset: the pan moves it), then the parts —
    # pt: one row band per frame while two frames are left, the last frame two
    assert [d["tasks"] for d in side] == ([2, 2, 2] if integrator == "bdpt" else [2, 2, 3])
    assert [d["parts"] for d in side] == ([1, 1, 1] if integrator == "bdpt" else [1, 1, 2])


def test12_auto_parts_follow_the_frames_left():
    from cmlt.shot.distributed import DaskRenderer
    r = DaskRenderer(None, CORNELL)
    frames = [1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 8.0]
    pred = {1.0: 0.0, 2.0: 1.0, 3.0: 2.0, 4.0: 3.0, 5.0: 4.0, 7.0: 6.0, 8.0: 7.0}
    r.plan(frames, pred)        # 5 -> 7 is not a pipelined step (7's state is 6's)
    assert [r.auto_parts(f, 2) for f in frames] == [1, 1, 1, 1, 2, 1, 2]
    assert [r.auto_parts(f, 3) for f in frames] == [1, 1, 1, 3, 3, 3, 3]
    assert r.auto_parts(9.0, 2) == 2               # not in the plan: a single frame
    assert all(r.auto_parts(f, 1) == 1 for f in frames)


def test11_one_part_per_frame_frames_side_by_side(tmp_path, client):
    # --dask-parts 1: each frame one part, frames in flight on both workers at once
    one = _render(tmp_path, "one", PAN, "1:4")
    dask = _render(tmp_path, "dask", PAN, "1:4", client=client, dask_parts=1)
    _same_images(one, dask)
    side = [json.load(open(p + ".json"))["stats"]["dask"] for p in dask.written]
    assert [d["tasks"] for d in side] == [2] * 4
    assert [d["submitted_ahead"] for d in side] == [False, True, True, True]
