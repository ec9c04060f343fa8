"""Frame-to-frame changes come from USD time samples, not array comparison:
static prims are never touched after the first frame, animated transforms
and deforming points are sent, and the incremental scene renders like a
fresh one."""
import numpy as np
import pytest

import cmlt._core as core

from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage


def _settings(w=32, h=24, spp=4, seed=11):
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.seed, st.threads, st.max_depth = w, h, spp, seed, 2, 8
    st.integrator = "pt"
    return st


def _render(scene, st):
    r = core.render(scene, st)
    return np.array(r.image, copy=True)


def _by_name(fs):
    return {i.name: i for i in fs.instances}


def test_01_flags_from_time_samples(tiny_shot):
    stage = open_stage(tiny_shot)
    f1 = load_frame(stage, 1)
    inst = _by_name(f1)
    assert inst["/World/Box"].animated
    assert not inst["/World/Floor"].animated and not inst["/World/Back"].animated
    assert not any(m.deforming for m in f1.meshes)
    f2 = load_frame(stage, 2)
    assert f1.static_signature == f2.static_signature
    # a static mesh hands over the very same arrays: identity, no comparison
    for a, b in zip(f1.meshes, f2.meshes):
        assert a.points is b.points and a.indices is b.indices
        assert a.material_ids is b.material_ids


def test_02_static_prims_are_not_touched(tiny_shot):
    stage = open_stage(tiny_shot)
    bridge = SceneBridge(core)
    bridge.update(load_frame(stage, 1))
    bridge.update(load_frame(stage, 2))
    rep = bridge.last_update
    assert not rep.rebuilt
    assert (rep.static_instances, rep.animated_instances, rep.transforms_updated) == (2, 1, 1)
    assert (rep.static_meshes, rep.deforming_meshes, rep.meshes_updated) == (3, 0, 0)
    d = rep.as_dict()
    assert d["static_meshes"] == 3 and d["static_instances"] == 2


def test_03_static_flag_is_trusted():
    """A static mesh is not compared: even different points are not sent
    (the reader, not an array comparison, decides)."""
    from support.scenes import tent_frame as _frame
    bridge = SceneBridge(core)
    a = _frame(1, 0.3, 0.0)
    a.meshes[1].deforming = False
    a.instances[1].animated = False
    bridge.update(a)
    b = _frame(2, 1.2, 0.4)
    b.meshes[1].deforming = False
    b.instances[1].animated = False
    bridge.update(b)
    rep = bridge.last_update
    assert (rep.meshes_updated, rep.transforms_updated) == (0, 0)
    assert (rep.static_meshes, rep.static_instances, rep.animated_instances) == (2, 1, 1)


DEFORM = {
    '''        point3f[] points = [(-2, 0, -2), (2, 0, -2), (2, 4, -2), (-2, 4, -2)]''':
    '''        point3f[] points.timeSamples = {
            1: [(-2, 0, -2), (2, 0, -2), (2, 4, -2), (-2, 4, -2)],
            3: [(-2, 0, -2), (2, 0, -2), (3, 4, -1), (-1, 4, -1)]}''',
}


def test_04_deforming_points_update_incremental_equals_fresh(make_shot):
    path = make_shot("deform.usda", DEFORM)
    stage = open_stage(path)
    f1, f2 = load_frame(stage, 1), load_frame(stage, 2)
    back = [m for m in f1.meshes if m.name == "/World/Back"][0]
    assert back.deforming
    assert sum(m.deforming for m in f1.meshes) == 1
    st = _settings(*f1.resolution)
    bridge = SceneBridge(core)
    img1 = _render(bridge.update(f1), st)
    img2 = _render(bridge.update(f2), st)
    rep = bridge.last_update
    assert not rep.rebuilt
    assert (rep.meshes_updated, rep.deforming_meshes, rep.static_meshes) == (1, 1, 2)
    assert rep.transforms_updated == 1
    fresh = _render(SceneBridge(core).update(f2), st)
    assert not np.array_equal(img1, fresh)
    np.testing.assert_allclose(img2, fresh, rtol=1e-5, atol=1e-6)


def test_05_animated_ancestor_and_reset_xform_stack(make_shot):
    path = make_shot("parent.usda", {
        '''def Xform "World"
{''': '''def Xform "World"
{
    double3 xformOp:translate.timeSamples = {1: (0, 0, 0), 3: (0, 1, 0)}
    uniform token[] xformOpOrder = ["xformOp:translate"]''',
        '''        point3f[] points = [(-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)]''':
        '''        point3f[] points = [(-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)]
        uniform token[] xformOpOrder = ["!resetXformStack!"]''',
    })
    inst = _by_name(load_frame(open_stage(path), 1))
    assert inst["/World/Back"].animated              # moves with its parent
    assert not inst["/World/Floor"].animated         # resetXformStack: parent ignored


POINT_INSTANCER = '''#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 2
    metersPerUnit = 1
)
def Xform "W"
{
    def PointInstancer "Moving"
    {
        point3f[] positions.timeSamples = {1: [(0, 0, 0), (2, 0, 0)], 2: [(0, 1, 0), (2, 1, 0)]}
        int[] protoIndices = [0, 0]
        rel prototypes = </W/Moving/Protos/P>
        def Scope "Protos"
        {
            def Mesh "P"
            {
                int[] faceVertexCounts = [3]
                int[] faceVertexIndices = [0, 1, 2]
                point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
            }
        }
    }
    def PointInstancer "Still"
    {
        point3f[] positions = [(0, 0, 5), (2, 0, 5)]
        int[] protoIndices = [0, 0]
        rel prototypes = </W/Still/Protos/P>
        def Scope "Protos"
        {
            def Mesh "P"
            {
                int[] faceVertexCounts = [3]
                int[] faceVertexIndices = [0, 1, 2]
                point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
            }
        }
    }
    def Camera "Cam"
    {
        double3 xformOp:translate = (0, 0, 20)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''


def test_06_point_instancer_arrays(tmp_path):
    p = tmp_path / "pi.usda"
    p.write_text(POINT_INSTANCER)
    stage = open_stage(str(p))
    fs = load_frame(stage, 1)
    flags = {i.name: i.animated for i in fs.instances}
    assert len(flags) == 4
    assert all(v for k, v in flags.items() if k.startswith("/W/Moving"))
    assert not any(v for k, v in flags.items() if k.startswith("/W/Still"))
    bridge = SceneBridge(core)
    bridge.update(fs)
    bridge.update(load_frame(stage, 2))
    rep = bridge.last_update
    assert not rep.rebuilt
    assert (rep.transforms_updated, rep.static_instances) == (2, 2)
