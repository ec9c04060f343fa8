"""The stuck-chain statistics of pssmlt and cmlt frames (stuck_chains, max_chain_share,
max_stay_share): on cornell, a healthy chain population, no chain is stuck and the
largest share stays far below the stuck threshold (100x the fair share 1/chains); with
the luminance target every step splats luminance 1, so every chain's share is its share
of the steps: 1/chains for an even budget. The heavy-tailed population is in the C++
tests (ChainShare.HeavyTailedPopulationHasAHighMaxShare)."""
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))


@pytest.fixture(scope="module")
def cornell():
    import cmlt._core as core
    from cmlt.shot.bridge import SceneBridge
    from cmlt.usd import load_frame, open_stage
    fs = load_frame(open_stage(os.path.join(ROOT, "sequences", "cornell", "shot.usda")), 1.0)
    return core, SceneBridge(core).update(fs)


def _stats(cornell, integ, seed, **extra):
    core, scene = cornell
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.seed, st.threads, st.integrator = 48, 36, 32, seed, 2, integ
    st.mlt_paths = "all"  # the chains on every path (auto: none on a diffuse scene)
    for k, v in extra.items():
        setattr(st, k, v)
    return dict(core.render(scene, st).stats)


@pytest.mark.parametrize("integ", ["pssmlt", "cmlt"])
def test_cornell_has_no_stuck_chain(cornell, integ):
    for seed in (1, 2, 3):
        s = _stats(cornell, integ, seed, chains=200)
        assert s["chains"] == 200
        assert s["stuck_chains"] == 0, s
        k = s["max_chain_share"] * s["chains"]
        assert 1.0 <= k < 50.0, f"{integ} seed {seed}: largest share {k:.1f}x the fair share"
        assert 0.0 < s["max_stay_share"] <= s["max_chain_share"]


@pytest.mark.parametrize("integ", ["pssmlt", "cmlt"])
def test_luminance_target_share_is_the_step_share(cornell, integ):
    s = _stats(cornell, integ, 1, chains=64, importance="luminance")
    assert s["importance"] == "luminance"
    assert s["max_chain_share"] == pytest.approx(1.0 / 64, rel=0.05), s["max_chain_share"]
    assert s["stuck_chains"] == 0
