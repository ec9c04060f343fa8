"""UsdSkel: skinned meshes are posed per frame with usd-core's UsdSkel API."""
import numpy as np

import cmlt._core as core

from cmlt.shot.bridge import SceneBridge
from cmlt.usd import load_frame, open_stage, stage_info

#: a two-joint arm along +X: shoulder at the origin, elbow at x = 1; the
#: elbow bends 90 degrees about +Z from frame 1 to frame 2. Vertices at
#: x = 0 follow the shoulder, at x = 2 (the tip) the elbow, at x = 1.5 both
#: half and half (linear blend skinning).
ARM = '''#usda 1.0
(
    defaultPrim = "World"
    startTimeCode = 1
    endTimeCode = 2
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "World"
{
    def SkelRoot "Char" (prepend apiSchemas = ["SkelBindingAPI"])
    {
        rel skel:skeleton = </World/Char/Skel>
        rel skel:animationSource = </World/Char/Anim>
        double3 xformOp:translate = (0, 0, -3)
        uniform token[] xformOpOrder = ["xformOp:translate"]
        def Skeleton "Skel"
        {
            uniform token[] joints = ["shoulder", "shoulder/elbow"]
            uniform matrix4d[] bindTransforms = [((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1)), ((1,0,0,0),(0,1,0,0),(0,0,1,0),(1,0,0,1))]
            uniform matrix4d[] restTransforms = [((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1)), ((1,0,0,0),(0,1,0,0),(0,0,1,0),(1,0,0,1))]
        }
        def SkelAnimation "Anim"
        {
            uniform token[] joints = ["shoulder", "shoulder/elbow"]
            float3[] translations = [(0, 0, 0), (1, 0, 0)]
            quatf[] rotations.timeSamples = {1: [(1, 0, 0, 0), (1, 0, 0, 0)], 2: [(1, 0, 0, 0), (0.70710677, 0, 0, 0.70710677)]}
            half3[] scales = [(1, 1, 1), (1, 1, 1)]
        }
        def Mesh "Arm" (prepend apiSchemas = ["SkelBindingAPI"])
        {
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4, 4]
            int[] faceVertexIndices = [0, 1, 4, 3, 1, 2, 5, 4]
            point3f[] points = [(0, 0, 0), (1.5, 0, 0), (2, 0, 0), (0, 0.1, 0), (1.5, 0.1, 0), (2, 0.1, 0)]
            int[] primvars:skel:jointIndices = [0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1] (
                interpolation = "vertex"
                elementSize = 2
            )
            float[] primvars:skel:jointWeights = [1, 0, 0.5, 0.5, 0, 1, 1, 0, 0.5, 0.5, 0, 1] (
                interpolation = "vertex"
                elementSize = 2
            )
            matrix4d primvars:skel:geomBindTransform = ((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1))
        }
    }
    def Mesh "Ground"
    {
        uniform token subdivisionScheme = "none"
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-5, -1, 5), (5, -1, 5), (5, -1, -5), (-5, -1, -5)]
    }
    def Camera "Cam"
    {
        double3 xformOp:translate = (1, 0.5, 4)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
'''


def _rot_z(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _trans(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _world_points(fs, name):
    inst = [i for i in fs.instances if i.name == name][0]
    p = np.asarray(fs.meshes[inst.mesh].points, dtype=np.float64)
    return (inst.transform @ np.c_[p, np.ones(len(p))].T).T[:, :3], inst, fs.meshes[inst.mesh]


def _stage(tmp_path):
    path = tmp_path / "arm.usda"
    path.write_text(ARM)
    return open_stage(str(path))


def test_01_bend_matches_joint_transforms(tmp_path):
    stage = _stage(tmp_path)
    rest, _, _ = _world_points(load_frame(stage, 1), "/World/Char/Arm")
    authored = np.array([(0, 0, 0), (1.5, 0, 0), (2, 0, 0), (0, .1, 0), (1.5, .1, 0), (2, .1, 0)])
    root = _trans(0, 0, -3)
    np.testing.assert_allclose(rest, authored + (0, 0, -3), atol=1e-6)

    bent, inst, mesh = _world_points(load_frame(stage, 2), "/World/Char/Arm")
    assert mesh.deforming
    # skinning transforms from the joints: shoulder = identity; elbow =
    # (world at frame 2) @ inverse(bind) = T(1,0,0) R_z(90) T(-1,0,0)
    elbow = _trans(1, 0, 0) @ _rot_z(90) @ _trans(-1, 0, 0)
    w = np.array([[1, 0], [.5, .5], [0, 1], [1, 0], [.5, .5], [0, 1]])
    hom = np.c_[authored, np.ones(6)]
    expect = w[:, :1] * hom + w[:, 1:] * (elbow @ hom.T).T      # linear blend
    expect = (root @ expect.T).T[:, :3]
    np.testing.assert_allclose(bent, expect, atol=1e-5)
    # the tip of the 90 degree bend: (2, 0, 0) -> (1, 1, 0)
    np.testing.assert_allclose(bent[2], (1, 1, -3), atol=1e-5)


def test_02_skinned_mesh_is_deforming_in_the_bridge(tmp_path):
    stage = _stage(tmp_path)
    bridge = SceneBridge(core)
    bridge.update(load_frame(stage, 1))
    f2 = load_frame(stage, 2)
    bridge.update(f2)
    rep = bridge.last_update
    assert not rep.rebuilt
    assert (rep.meshes_updated, rep.static_meshes) == (1, 1)
    st = core.RenderSettings()
    st.width, st.height, st.spp, st.seed, st.threads = 24, 16, 2, 3, 2
    img = np.array(core.render(bridge.scene, st).image)
    fresh = np.array(core.render(SceneBridge(core).update(f2), st).image)
    np.testing.assert_allclose(img, fresh, rtol=1e-5, atol=1e-6)


def test_03_stage_info_note(tmp_path):
    info = stage_info(_stage(tmp_path))
    note = [n for n in info.notes if n.startswith("/World/Char")]
    assert note and "skinning is applied" in note[0]
    assert "not applied;" not in note[0]
