"""Small USD stages as .usda text, for the tests that render a stage through the
command line: a header, a UsdPreviewSurface material, a quad facing the camera at
a known distance, and a closed box seen from inside."""
from __future__ import annotations

import textwrap

import numpy as np


def header(start: int = 1, end: int = 2) -> str:
    return textwrap.dedent(f'''\
        #usda 1.0
        (
            startTimeCode = {start}
            endTimeCode = {end}
            metersPerUnit = 1
            upAxis = "Y"
        )
        ''')


def preview_material(diffuse, extra_inputs: str = "", path: str = "/Looks/M") -> str:
    """A Scope "Looks" holding Material "M" with a UsdPreviewSurface "S" of
    ``diffuse`` (plus ``extra_inputs`` lines)."""
    extra = "".join(f"\n                {line}" for line in extra_inputs.splitlines() if line)
    return textwrap.dedent(f'''\
        def Scope "Looks"
        {{
            def Material "M"
            {{
                token outputs:surface.connect = <{path}/S.outputs:surface>
                def Shader "S"
                {{
                    uniform token info:id = "UsdPreviewSurface"
                    color3f inputs:diffuseColor = {tuple(diffuse)}{extra}
                    token outputs:surface
                }}
            }}
        }}
        ''')


CAMERA = textwrap.dedent('''\
    def Camera "Cam"
    {
        float focalLength = 24
        float horizontalAperture = 36
        float verticalAperture = 24
        float2 clippingRange = (0.1, 100)
    }
    ''')


def facing_quad_shot(distance: float, diffuse, extra: str = "") -> str:
    """A 3x2 quad of ``diffuse`` at ``distance`` in front of /Cam (looking down
    -Z, 36x24 aperture at focal length 24), lit by a distant light; frames 1-2;
    ``extra`` is appended (render settings, ...)."""
    d = -float(distance)
    return header() + textwrap.dedent(f'''\
        def Mesh "Quad" (prepend apiSchemas = ["MaterialBindingAPI"])
        {{
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(-1.5, -1, {d}), (1.5, -1, {d}), (1.5, 1, {d}), (-1.5, 1, {d})]
            rel material:binding = </Looks/M>
        }}
        ''') + preview_material(diffuse) + textwrap.dedent('''\
        def DistantLight "Sun"
        {
            float inputs:intensity = 1
        }
        ''') + CAMERA + extra


def closed_box_shot(diffuse, extra_inputs: str = "") -> str:
    """A closed 2x2x2 box around /Cam at the origin, its faces turned inward
    (double sided too), all of one UsdPreviewSurface material; frame 1."""
    pts = []
    for n in np.vstack([np.eye(3), -np.eye(3)]):        # inward normals
        a = np.array([0, 1.0, 0]) if abs(n[1]) < 0.9 else np.array([1.0, 0, 0])
        t1 = np.cross(a, n)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        pts += [-n - t1 - t2, -n + t1 - t2, -n + t1 + t2, -n - t1 + t2]
    p = ", ".join(f"({x:g}, {y:g}, {z:g})" for x, y, z in pts)
    return header(1, 1) + textwrap.dedent(f'''\
        def Mesh "Box" (prepend apiSchemas = ["MaterialBindingAPI"])
        {{
            uniform token subdivisionScheme = "none"
            uniform bool doubleSided = 1
            int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
            int[] faceVertexIndices = [{", ".join(str(i) for i in range(24))}]
            point3f[] points = [{p}]
            rel material:binding = </Looks/M>
        }}
        ''') + preview_material(diffuse, extra_inputs) + CAMERA.replace("(0.1, 100)",
                                                                     "(0.01, 100)")


def exr_channels(path):
    """(spec, {channel name: (H, W) float32}) of an image file."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    pix = np.asarray(inp.read_image(oiio.FLOAT), dtype=np.float32)
    inp.close()
    pix = pix.reshape(spec.height, spec.width, spec.nchannels)
    return spec, {n: pix[..., i] for i, n in enumerate(spec.channelnames)}
