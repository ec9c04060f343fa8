"""core.temporal_chain_count is the number of chains a pssmlt/cmlt render starts: the
temporal driver asks that many starts (never the requested --chains itself, which the
budget may not feed), so the two counts must agree whatever the settings."""
import pytest

import cmlt._core as core
from cmlt.shot.bridge import SceneBridge
from support.scenes import cornell_scene


@pytest.fixture(scope="module")
def scene():
    bridge = SceneBridge(core)      # holds the arrays the core shares while it renders
    yield bridge.update(cornell_scene())


def _settings(integrator, **kw):
    st = core.RenderSettings()
    st.integrator, st.width, st.height, st.spp, st.seed, st.threads = integrator, 16, 12, 4, 1, 2
    st.max_depth, st.bootstrap_samples = 4, 64
    st.mlt_paths = "all"  # the chains on every path (auto: none on a diffuse scene)
    for k, v in kw.items():
        setattr(st, k, v)
    return st


@pytest.mark.parametrize("integrator, kw", [
    ("pssmlt", {"chains": 8}),
    ("pssmlt", {"chains": 100_000_000}),
    ("pssmlt", {"chains": 100_000_000, "direct_fraction": 0.0}),
    ("cmlt", {"chains": 8}),
    ("cmlt", {"chains": 100_000_000}),
    ("cmlt", {"chains": 100_000_000, "tries": 4, "inner_length": 8}),
    ("cmlt", {"chains": 3, "tries": 1, "inner_length": 1}),
])
def test01_count_is_the_renders(scene, integrator, kw):
    st = _settings(integrator, **kw)
    n = core.temporal_chain_count(st)
    assert 1 <= n <= kw["chains"]
    assert dict(core.render(scene, st).stats)["chains"] == n


def test02_no_chains_for_pt_and_bdpt():
    for integ in ("pt", "bdpt"):
        assert core.temporal_chain_count(_settings(integ, chains=1000)) == 0
