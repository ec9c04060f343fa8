"""The material kernels (src/core/analysis/kernel_select.h): which materials the
diffuse-only kernel takes, and that it renders what the general UsdPreviewSurface kernel
renders — on a Lambertian Cornell box, where it takes every material, with every
integrator, and on every sequence in sequences/ (where it takes the materials that
happen to be exact Lambertians, often none)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cmlt._core as core
from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage, stage_info

SEQUENCES = Path(__file__).resolve().parents[3] / "sequences"
CORNELL = SEQUENCES / "cornell" / "shot.usda"
#: every stage in sequences/: the shots and the hard cases
STAGES = sorted(p.parent for p in SEQUENCES.glob("*/shot.usda")) + \
    sorted(p.parent for p in SEQUENCES.glob("hard/*/shot.usda"))


def _lambertian(fs):
    """The frame with every material an exact Lambertian: specular workflow, F0 = 0."""
    for m in fs.materials:
        m.use_specular_workflow = True
        m.specular = (0.0, 0.0, 0.0)
    return fs


def _render(scene, kernel, integrator="pt", res=(24, 18), spp=4, seed=3):
    st = core.RenderSettings()
    st.width, st.height = res
    st.spp, st.threads, st.seed, st.integrator, st.kernel = spp, 2, seed, integrator, kernel
    if integrator in ("pssmlt", "cmlt"):
        st.chains, st.bootstrap_samples = 64, 2048
    r = core.render(scene, st)
    assert r.stats["nan_samples"] == 0
    return np.asarray(r.image, dtype=np.float64)


def _same_to_rounding(a, b, what):
    """Per pixel within float rounding of the brighter image (the kernels compute the same
    products in a different order)."""
    scale = max(1.0, float(np.abs(b).max()))
    worst = float(np.abs(a - b).max())
    assert worst <= 1e-5 * scale, f"{what}: largest pixel difference {worst:g} (scale {scale:g})"


def test01_the_rule_on_constants():
    fs = load_frame(open_stage(str(CORNELL)), 1.0, resolution=(8, 6))
    bridge = SceneBridge(core)
    # the Cornell box as authored: UsdPreviewSurface in the metallic workflow, ior 1.5:
    # F0 = 0.04, a specular lobe, so the general model
    assert not any(core.lambert_kernel_materials(bridge.update(fs)))
    fs = _lambertian(fs)
    assert all(core.lambert_kernel_materials(SceneBridge(core).update(fs)))
    m = fs.materials[0]
    cases = [  # (change, exact Lambertian?)
        (dict(specular=(0.04, 0.04, 0.04)), False),          # F0 > 0
        (dict(clearcoat=0.1), False),
        (dict(opacity=0.5), False),                           # transmission
        (dict(opacity=0.5, opacity_threshold=0.3), True),     # a cut-out it passes: opaque
        (dict(opacity=0.2, opacity_threshold=0.3), False),    # a hole
        (dict(roughness=0.05), True),                         # no specular lobe to sharpen
        (dict(use_specular_workflow=False, metallic=0.0, ior=1.0), True),   # F0 = 0
        (dict(use_specular_workflow=False, metallic=0.0, ior=1.5), False),  # F0 = 0.04
    ]
    keep = {k: getattr(m, k) for k in ("specular", "clearcoat", "opacity", "opacity_threshold",
                                       "roughness", "use_specular_workflow", "metallic", "ior")}
    for change, want in cases:
        for k, v in keep.items():
            setattr(m, k, v)
        for k, v in change.items():
            setattr(m, k, v)
        got = core.lambert_kernel_materials(SceneBridge(core).update(fs))[0]
        assert got is want, change


@pytest.mark.parametrize("integrator", ["pt", "bdpt", "pssmlt", "cmlt"])
def test02_lambertian_cornell_same_image_with_every_integrator(integrator):
    fs = _lambertian(load_frame(open_stage(str(CORNELL)), 1.0, resolution=(24, 18)))
    scene = SceneBridge(core).update(fs)
    assert all(core.lambert_kernel_materials(scene))
    general = _render(scene, "general", integrator)
    special = _render(scene, "auto", integrator)
    assert general.max() > 0
    _same_to_rounding(special, general, f"cornell (Lambertian), {integrator}")
    # the scene keeps the auto selection after a general render
    assert np.array_equal(_render(scene, "auto", integrator), special)


@pytest.mark.parametrize("stage", STAGES, ids=lambda p: str(p.relative_to(SEQUENCES)))
def test03_every_sequence_same_image(stage):
    st = open_stage(str(stage / "shot.usda"))
    fs = load_frame(st, stage_info(st).start, resolution=(20, 15))
    scene = SceneBridge(core).update(fs)
    general = _render(scene, "general", res=(20, 15), spp=2)
    special = _render(scene, "auto", res=(20, 15), spp=2)
    _same_to_rounding(special, general, str(stage.relative_to(SEQUENCES)))


def test04_the_setting():
    st = core.RenderSettings()
    assert st.kernel == "auto"
    st.kernel = "fast"
    with pytest.raises(core.SettingsError, match=r"RenderSettings\.kernel: unknown value 'fast'"):
        st.validate()
