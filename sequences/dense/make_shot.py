#!/usr/bin/env python3
"""Write sequences/dense/shot.usdc: a dense shot of about a million triangles.

A UV sphere of ``--rings`` x ``--segments`` quads (2 triangles each, with vertex normals
and uvs, the seam and poles sharing nothing: every quad row is a strip of a regular
grid) on a floor quad, lit by a rect light, seen by one camera; frame 1 only.
Generated, not committed (``shot.usdc`` is ignored by git): run

    .venv/bin/python sequences/dense/make_shot.py            # 1,000,000 sphere triangles
    .venv/bin/python sequences/dense/make_shot.py --rings 50 --segments 100 --out /tmp/s.usdc

It is the shot the memory figure (``cmlt inspect``: bytes per triangle) and the speed
benchmarks use for a dense mesh.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def sphere_grid(rings: int, segments: int, radius: float):
    """Points, normals, uvs of a (rings + 1) x (segments + 1) vertex grid on a sphere,
    and its faceVertexCounts / faceVertexIndices (quads, counter-clockwise outside)."""
    theta = np.linspace(0.0, np.pi, rings + 1)            # from +Y down to -Y
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    n = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], axis=-1)
    n = n.reshape(-1, 3)
    uv = np.stack([p / (2.0 * np.pi), 1.0 - t / np.pi], axis=-1).reshape(-1, 2)
    r, s = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    v00 = (r * (segments + 1) + s).reshape(-1)
    v10 = v00 + segments + 1
    quads = np.stack([v00, v10, v10 + 1, v00 + 1], axis=-1)
    return n * radius, n, uv, np.full(len(quads), 4, dtype=np.int32), quads.reshape(-1)


def write(out: Path, rings: int, segments: int) -> int:
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt

    stage = Usd.Stage.CreateNew(str(out))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(1)
    root = UsdGeom.Xform.Define(stage, "/Dense")
    stage.SetDefaultPrim(root.GetPrim())

    look = UsdShade.Material.Define(stage, "/Dense/Looks/Clay")
    shader = UsdShade.Shader.Define(stage, "/Dense/Looks/Clay/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.7, 0.6, 0.5))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.5)
    look.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")

    pts, nrm, uv, counts, idx = sphere_grid(rings, segments, 1.0)
    ball = UsdGeom.Mesh.Define(stage, "/Dense/Ball")
    ball.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    ball.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(counts))
    ball.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(idx.astype(np.int32)))
    ball.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    ball.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(nrm.astype(np.float32)))
    ball.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    pv = UsdGeom.PrimvarsAPI(ball).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                 UsdGeom.Tokens.vertex)
    pv.Set(Vt.Vec2fArray.FromNumpy(uv.astype(np.float32)))
    ball.CreateExtentAttr([(-1, -1, -1), (1, 1, 1)])
    ball.AddTranslateOp().Set(Gf.Vec3d(0, 1, 0))
    UsdShade.MaterialBindingAPI.Apply(ball.GetPrim()).Bind(look)

    floor = UsdGeom.Mesh.Define(stage, "/Dense/Floor")
    floor.CreatePointsAttr([(-5, 0, 5), (5, 0, 5), (5, 0, -5), (-5, 0, -5)])
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    floor.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    UsdShade.MaterialBindingAPI.Apply(floor.GetPrim()).Bind(look)

    light = UsdLux.RectLight.Define(stage, "/Dense/Key")
    light.CreateWidthAttr(2.0)
    light.CreateHeightAttr(2.0)
    light.CreateIntensityAttr(20.0)
    lx = UsdGeom.Xformable(light)
    lx.AddTranslateOp().Set(Gf.Vec3d(0, 4, 0))
    lx.AddRotateXOp().Set(-90.0)                           # emit down (-Z becomes -Y)

    cam = UsdGeom.Camera.Define(stage, "/Dense/Camera")
    cam.CreateFocalLengthAttr(35.0)
    cx = UsdGeom.Xformable(cam)
    cx.AddTranslateOp().Set(Gf.Vec3d(0, 1.5, 5))
    cx.AddRotateXOp().Set(-8.0)
    stage.GetRootLayer().Save()
    return 2 * rings * segments


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rings", type=int, default=500)
    ap.add_argument("--segments", type=int, default=1000)
    ap.add_argument("--out", default=str(Path(__file__).with_name("shot.usdc")))
    args = ap.parse_args(argv)
    n = write(Path(args.out), args.rings, args.segments)
    print(f"{args.out}: {n:,} sphere triangles + a floor")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
