"""Carried chain populations are used whole when the budget runs fewer chains. The
temporal driver plans ``settings.chains`` starts, coupled to the previous frame's
(temporal/carry.h: a start is kept where its target did not change, the others are
refreshed from the residual), listed in chain order; at a small budget coherent MLT runs
at most (chain evaluations) / (1 + m k) chains. In chain order the starts follow their
bootstrap index (systematic resampling is sorted, and the kept and the refreshed starts
each keep that order), so running the *first* n of them would start every chain from
the first n/planned of the bootstrap pool: the core takes an even stride over the whole
population instead (mlt::subsampled_state). Checked on a light switch (frame 2's
carried starts lose their contribution, so both kept and refreshed starts occur): the
starts the core ran cover the planned population's bootstrap indices as the plan does,
and hold kept and refreshed starts in the plan's proportion."""
import numpy as np
import pytest

import cmlt._core as core

STAGE = """#usda 1.0
(
    defaultPrim = "World"
    startTimeCode = 1
    endTimeCode = 2
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "World"
{
    def Mesh "Floor"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-3, 0, 3), (3, 0, 3), (3, 0, -3), (-3, 0, -3)]
    }
    def Mesh "Back"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-3, 0, -2), (3, 0, -2), (3, 3, -2), (-3, 3, -2)]
    }
    def SphereLight "Left"
    {
        float inputs:radius = 0.2
        float inputs:intensity.timeSamples = {1: 30, 2: 0}
        double3 xformOp:translate = (-1.5, 1.5, -1)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def SphereLight "Right"
    {
        float inputs:radius = 0.2
        float inputs:intensity.timeSamples = {1: 0, 2: 30}
        double3 xformOp:translate = (1.5, 1.5, -1)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def Camera "Cam"
    {
        float focalLength = 20
        float horizontalAperture = 36
        float verticalAperture = 27
        double3 xformOp:translate = (0, 1.5, 5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
"""

def _frame(path, t):
    from cmlt.usd import load_frame, open_stage
    return load_frame(open_stage(path), float(t), resolution=(32, 24))


def _ids(states):
    """Bootstrap index of each start (a start's chain_id: temporal_bootstrap_states)."""
    return np.array([states.chain(i)["chain_id"] for i in range(len(states))], np.int64)


class _PlanRequested:
    """The core, except that the driver plans the requested chain count: the driver
    asks the core how many chains the budget feeds (temporal_chain_count) and plans
    that many, so a population larger than the run now comes only from elsewhere (a
    state written under another budget); this makes one to test the core's subsample."""

    def __getattr__(self, name):
        return getattr(core, name)

    @staticmethod
    def temporal_chain_count(st):
        return int(st.chains)


def test01_the_core_runs_an_even_subsample_of_a_carried_population(tmp_path):
    from cmlt.settings import resolve_settings
    from cmlt.shot.bridge import SceneBridge
    from cmlt.temporal import TemporalDriver

    path = str(tmp_path / "switch.usda")
    with open(path, "w") as fh:
        fh.write(STAGE)
    # the chains on every path (auto: none on this diffuse stage)
    resolved, _ = resolve_settings(None, cli_overrides={"integrator": "cmlt", "spp": 16, "seed": 3,
                                                        "mlt_paths": "all"})
    driver = TemporalDriver(_PlanRequested(), resolved, path, 32, 24)
    bridge = SceneBridge(core)
    records = []
    for t in (1, 2):
        scene = bridge.update(_frame(path, t))
        st = core.RenderSettings()
        st.width, st.height = 32, 24
        for name in ("integrator", "spp", "chains", "tries", "inner_length", "seed", "mlt_paths"):
            setattr(st, name, getattr(resolved, name))
        st.threads = 2
        rec = driver.prepare(scene, st, float(t))
        planned = _ids(st.mlt_initial_states)
        r = core.render(scene, st)
        image, rec, data = driver.finish(r, dict(r.stats), np.asarray(r.image), float(t), rec)
        driver.advance(data, f"<frame {t}>")
        records.append((rec, planned, dict(r.stats), _ids(r.mlt_start_states)))
    for frame, (rec, planned, stats, ran) in enumerate(records, 1):
        n = stats["chains"]
        # the budget runs fewer chains than the driver planned ...
        assert n == len(ran) < len(planned), (frame, n, len(planned))
        assert stats["imported_chains"] == n
        # ... and they are the plan at an even stride, not its head
        k = np.arange(n)
        assert (ran == planned[(2 * k + 1) * len(planned) // (2 * n)]).all(), frame
        # so they cover the bootstrap pool as the plan does (the head would hold only the
        # lowest indices: its share above the plan's median would be ~0)
        median = np.median(planned)
        share_plan, share_ran = float((planned > median).mean()), float((ran > median).mean())
        assert abs(share_ran - share_plan) < 0.05, (frame, share_ran, share_plan)
    # frame 2: the switch made carried starts lose their contribution; kept and refreshed
    # starts are in the core's chains in the plan's proportion
    rec, planned, stats, ran = records[1]
    prev_planned = records[0][1]
    assert rec["refreshed_chains"] > 0 and rec["carried_chains"] > 0, rec
    kept_plan = planned == prev_planned
    n = len(ran)
    slots = (2 * np.arange(n) + 1) * len(planned) // (2 * n)
    share_plan, share_ran = float(kept_plan.mean()), float(kept_plan[slots].mean())
    assert abs(share_ran - share_plan) < 0.05, (share_ran, share_plan)
