"""Writes shot.usda (the animated Cornell box) next to this file.

Run it after editing: ``python sequences/cornell/make_shot.py``. The .usda is
committed, so rendering never needs this script; it exists so that the
per-frame time samples (a sine bounce) are reproducible rather than typed.
"""
import math
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
W, H = 550.0, 550.0          # box width/depth and height (cm)
HALF = W / 2
FRAMES = range(1, 25)


def quad(name, pts, normal, material):
    """A one-quad wall; checks that its winding faces along `normal`."""
    p = np.array(pts, float)
    n = np.cross(p[1] - p[0], p[2] - p[0])
    assert np.dot(n, normal) > 0, name
    plist = ", ".join(f"({x:g}, {y:g}, {z:g})" for x, y, z in p)
    return f'''
        def Mesh "{name}" (prepend apiSchemas = ["MaterialBindingAPI"])
        {{
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [{plist}]
            normal3f[] normals = [{", ".join([f"({normal[0]:g}, {normal[1]:g}, {normal[2]:g})"] * 4)}] (
                interpolation = "vertex"
            )
            rel material:binding = </Cornell/Looks/{material}>
        }}'''


def cube_faces():
    """Unit cube x,z in [-0.5, 0.5], y in [0, 1]; faces wound outwards."""
    pts = np.array([(x, y, z) for x in (-0.5, 0.5) for y in (0.0, 1.0) for z in (-0.5, 0.5)])
    faces = []
    centre = np.array([0, 0.5, 0])
    for axis in range(3):
        for side in (0, 1):
            idx = [i for i, p in enumerate(pts) if (p[axis] > centre[axis]) == bool(side)]
            # order the 4 corners around the face centre, counter-clockwise seen from outside
            c = pts[idx].mean(0)
            normal = np.zeros(3)
            normal[axis] = 1 if side else -1
            u = np.roll(normal, 1)
            v = np.cross(normal, u)
            ang = [math.atan2(np.dot(pts[i] - c, v), np.dot(pts[i] - c, u)) for i in idx]
            order = [i for _, i in sorted(zip(ang, idx))]
            q = pts[order]
            assert np.dot(np.cross(q[1] - q[0], q[2] - q[0]), normal) > 0
            faces.append(order)
    return pts, faces


def box(name, size, translate_samples, rotate_samples, material):
    pts, faces = cube_faces()
    plist = ", ".join(f"({x:g}, {y:g}, {z:g})" for x, y, z in pts)
    flist = ", ".join(str(i) for f in faces for i in f)

    def samples(d, fmt):
        return "{" + ", ".join(f"{k}: {fmt(v)}" for k, v in d.items()) + "}"

    t = samples(translate_samples, lambda v: f"({v[0]:g}, {v[1]:.4f}, {v[2]:g})")
    r = samples(rotate_samples, lambda v: f"{v:.4f}")
    return f'''
        def Mesh "{name}" (prepend apiSchemas = ["MaterialBindingAPI"])
        {{
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [{", ".join(["4"] * 6)}]
            int[] faceVertexIndices = [{flist}]
            point3f[] points = [{plist}]
            double3 xformOp:translate.timeSamples = {t}
            float xformOp:rotateY.timeSamples = {r}
            float3 xformOp:scale = ({size[0]:g}, {size[1]:g}, {size[2]:g})
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY", "xformOp:scale"]
            rel material:binding = </Cornell/Looks/{material}>
        }}'''


def material(name, rgb):
    return f'''
            def Material "{name}"
            {{
                token outputs:surface.connect = </Cornell/Looks/{name}/Surface.outputs:surface>
                def Shader "Surface"
                {{
                    uniform token info:id = "UsdPreviewSurface"
                    color3f inputs:diffuseColor = ({rgb[0]:g}, {rgb[1]:g}, {rgb[2]:g})
                    float inputs:roughness = 1
                    float inputs:metallic = 0
                    token outputs:surface
                }}
            }}'''


def main():
    walls = [
        quad("Floor", [(-HALF, 0, HALF), (HALF, 0, HALF), (HALF, 0, -HALF), (-HALF, 0, -HALF)],
             (0, 1, 0), "White"),
        quad("Ceiling", [(-HALF, H, -HALF), (HALF, H, -HALF), (HALF, H, HALF), (-HALF, H, HALF)],
             (0, -1, 0), "White"),
        quad("BackWall", [(-HALF, 0, -HALF), (HALF, 0, -HALF), (HALF, H, -HALF), (-HALF, H, -HALF)],
             (0, 0, 1), "White"),
        quad("LeftWall", [(-HALF, 0, HALF), (-HALF, 0, -HALF), (-HALF, H, -HALF), (-HALF, H, HALF)],
             (1, 0, 0), "Red"),
        quad("RightWall", [(HALF, 0, -HALF), (HALF, 0, HALF), (HALF, H, HALF), (HALF, H, -HALF)],
             (-1, 0, 0), "Green"),
    ]
    first, last = FRAMES[0], FRAMES[-1]
    # short box: turns a quarter turn about its vertical axis over the shot
    short = box("ShortBox", (165, 165, 165),
                {first: (95, 0, 80), last: (95, 0, 80)},
                {first: -17.0, last: 73.0}, "White")
    # tall box: one smooth bounce, 0 -> 80 cm -> 0 (a sample per frame)
    bounce = {f: (-95, 80 * 0.5 * (1 - math.cos(2 * math.pi * (f - first) / (last - first))), -85)
              for f in FRAMES}
    tall = box("TallBox", (165, 330, 165), bounce, {first: 17.0, last: 17.0}, "White")

    text = f'''#usda 1.0
(
    doc = """Animated Cornell box for cmlt: 24 frames at 24 fps, centimetres, Y up.
    Generated by make_shot.py; see notes.md."""
    defaultPrim = "Cornell"
    startTimeCode = {first}
    endTimeCode = {last}
    timeCodesPerSecond = 24
    framesPerSecond = 24
    metersPerUnit = 0.01
    upAxis = "Y"
    renderSettingsPrimPath = "/Render/Settings"
)

def Xform "Cornell" (
    kind = "assembly"
)
{{
    def Scope "Geometry"
    {{{"".join(walls)}{short}{tall}
    }}

    def Scope "Lights"
    {{
        # 130 x 105 cm panel just under the ceiling, facing down (-Z -> -Y)
        def RectLight "CeilingLight"
        {{
            float inputs:width = 130
            float inputs:height = 105
            float inputs:intensity = 17
            color3f inputs:color = (1, 0.85, 0.65)
            bool inputs:normalize = 0
            double3 xformOp:translate = (0, {H - 0.5:g}, 0)
            float3 xformOp:rotateXYZ = (-90, 0, 0)
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
        }}
    }}

    def Camera "Camera"
    {{
        # 35 mm lens on a 25 x 25 mm back (the classic Cornell camera); USD
        # lens units are tenths of a scene unit, i.e. mm in a cm stage
        token projection = "perspective"
        float focalLength = 35
        float horizontalAperture = 25
        float verticalAperture = 25
        float2 clippingRange = (10, 10000)
        float fStop = 0
        double3 xformOp:translate = (0, {H / 2:g}, {HALF + 800:g})
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}

    def Scope "Looks"
    {{{material("White", (0.73, 0.73, 0.73))}{material("Red", (0.63, 0.065, 0.05))}{material("Green", (0.14, 0.45, 0.091))}
    }}
}}

def Scope "Render"
{{
    def RenderSettings "Settings" (
        prepend apiSchemas = ["CmltRenderSettingsAPI"]
    )
    {{
        rel camera = </Cornell/Camera>
        uniform int2 resolution = (256, 256)
        uniform float pixelAspectRatio = 1
        uniform token cmlt:integrator = "pt"
        uniform int cmlt:spp = 32
        uniform int cmlt:seed = 1
    }}
}}
'''
    with open(os.path.join(HERE, "shot.usda"), "w") as fh:
        fh.write(text)


if __name__ == "__main__":
    main()
