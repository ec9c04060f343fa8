"""Two example sequences load: caustic_glass (glass material, moving sphere light) and
textured_dome (dome texture, textured materials, moving camera), and a small render of
each is finite and not black."""
from pathlib import Path

import numpy as np
import pytest

import cmlt._core as core
import support

ROOT = support.ROOT


def _frame(shot, t, res=(32, 32)):
    from cmlt.usd import load_frame, open_stage
    return load_frame(open_stage(str(ROOT / shot)), t, resolution=res)


def _render(fs, integrator="pt", spp=4):
    from cmlt.shot.bridge import SceneBridge
    st = core.RenderSettings()
    st.width, st.height = fs.resolution
    st.spp, st.seed, st.threads, st.integrator = spp, 1, 2, integrator
    return np.asarray(core.render(SceneBridge(core).update(fs), st).image, np.float64)


def test01_caustic_glass_loads_and_the_light_moves():
    a, b = _frame("sequences/caustic_glass/shot.usda", 1), _frame("sequences/caustic_glass/shot.usda", 24)
    glass = [m for m in a.materials if m.name.endswith("/Glass")]
    assert glass and glass[0].opacity == 0.0 and glass[0].ior == pytest.approx(1.5)
    assert glass[0].roughness == 0.0
    (la,), (lb,) = a.lights, b.lights
    assert la.kind == "sphere" and not np.allclose(la.transform[:3, 3], lb.transform[:3, 3])
    img = _render(a, "bdpt")
    assert np.isfinite(img).all() and img.mean() > 0


def test02_textured_dome_loads_and_the_camera_moves():
    a, b = _frame("sequences/textured_dome/shot.usda", 1), _frame("sequences/textured_dome/shot.usda", 24)
    (dome,) = a.lights
    assert dome.kind == "dome" and dome.texture and str(dome.texture).endswith("sky.exr")
    assert not np.allclose(a.camera.transform, b.camera.transform)
    assert any("texture" in (rec or {}) for m in a.materials for rec in (m.inputs or {}).values()
               if isinstance(rec, dict))
    img = _render(a)
    assert np.isfinite(img).all() and img.mean() > 0.05
