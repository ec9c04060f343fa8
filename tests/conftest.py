"""Shared pytest fixtures: fixed seeds, tiny stages written into tmp_path.

The stages are written by the tests themselves (not read from tests/data),
so each test states exactly what it renders.
"""
from __future__ import annotations

import os
import sys
import textwrap

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SRC = os.path.join(ROOT, "src")
try:                        # the editable install (make install) provides cmlt
    import cmlt  # noqa: F401
except ImportError:         # pure-Python tests still run from a bare checkout
    sys.path.insert(0, SRC)

#: a closed-ish box of two quads (floor + back wall), a rect light, a camera
#: and a cube that moves along X over frames 1..3; 32x24 pixels.
TINY_SHOT = textwrap.dedent('''\
    #usda 1.0
    (
        defaultPrim = "World"
        startTimeCode = 1
        endTimeCode = 3
        timeCodesPerSecond = 24
        framesPerSecond = 24
        metersPerUnit = 1
        upAxis = "Y"
        renderSettingsPrimPath = "/Render/Settings"
    )

    def Xform "World"
    {
        def Mesh "Floor" (prepend apiSchemas = ["MaterialBindingAPI"])
        {
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)]
            rel material:binding = </World/Looks/White>
        }
        def Mesh "Back" (prepend apiSchemas = ["MaterialBindingAPI"])
        {
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(-2, 0, -2), (2, 0, -2), (2, 4, -2), (-2, 4, -2)]
            rel material:binding = </World/Looks/Red>
        }
        def Mesh "Box" (prepend apiSchemas = ["MaterialBindingAPI"])
        {
            uniform token subdivisionScheme = "none"
            int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
            int[] faceVertexIndices = [0, 1, 3, 2,  4, 6, 7, 5,  0, 4, 5, 1,  2, 3, 7, 6,  0, 2, 6, 4,  1, 5, 7, 3]
            point3f[] points = [(-0.5, 0, -0.5), (-0.5, 0, 0.5), (-0.5, 1, -0.5), (-0.5, 1, 0.5),
                                (0.5, 0, -0.5), (0.5, 0, 0.5), (0.5, 1, -0.5), (0.5, 1, 0.5)]
            double3 xformOp:translate.timeSamples = {1: (-1, 0, 0), 2: (0, 0, 0), 3: (1, 0, 0)}
            uniform token[] xformOpOrder = ["xformOp:translate"]
            rel material:binding = </World/Looks/White>
        }
        def RectLight "Light"
        {
            float inputs:intensity = 8
            float inputs:width = 1.5
            float inputs:height = 1.5
            double3 xformOp:translate = (0, 3.5, 0)
            float3 xformOp:rotateXYZ = (-90, 0, 0)
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
        }
        def Camera "Cam"
        {
            float focalLength = 24
            float horizontalAperture = 36
            float verticalAperture = 27
            float2 clippingRange = (0.1, 100)
            double3 xformOp:translate = (0, 1.5, 7)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }
        def Scope "Looks"
        {
            def Material "White"
            {
                token outputs:surface.connect = </World/Looks/White/S.outputs:surface>
                def Shader "S"
                {
                    uniform token info:id = "UsdPreviewSurface"
                    color3f inputs:diffuseColor = (0.7, 0.7, 0.7)
                    token outputs:surface
                }
            }
            def Material "Red"
            {
                token outputs:surface.connect = </World/Looks/Red/S.outputs:surface>
                def Shader "S"
                {
                    uniform token info:id = "UsdPreviewSurface"
                    color3f inputs:diffuseColor = (0.7, 0.1, 0.1)
                    token outputs:surface
                }
            }
        }
    }

    def Scope "Render"
    {
        def RenderSettings "Settings"
        {
            int2 resolution = (32, 24)
            rel camera = </World/Cam>
        }
    }
    ''')


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


@pytest.fixture
def tiny_shot(tmp_path):
    """Path of a 3-frame animated stage (32x24) in a fresh directory."""
    path = tmp_path / "tiny.usda"
    path.write_text(TINY_SHOT)
    return str(path)


@pytest.fixture
def make_shot(tmp_path):
    """Write a variant of TINY_SHOT: make_shot(name, replace={old: new})."""
    def make(name="shot.usda", replace=None):
        text = TINY_SHOT
        for old, new in (replace or {}).items():
            assert old in text, old
            text = text.replace(old, new)
        path = tmp_path / name
        path.write_text(text)
        return str(path)
    return make


@pytest.fixture
def builtin_color_config(monkeypatch):
    """The built-in OpenColorIO config (no $OCIO) as the process-wide one for the
    test, reset afterwards (``pytestmark = pytest.mark.usefixtures(...)``)."""
    from cmlt.color import load_config, set_config

    monkeypatch.delenv("OCIO", raising=False)
    set_config(load_config())
    yield
    set_config(None)
