"""The render scene of one frame: flat numpy arrays, ready for the C++ core.

This module is the contract between the USD reader (:mod:`cmlt.usd`) and the
core (:mod:`cmlt._core`, driven from :mod:`cmlt.shot`). It imports neither.

Conventions
-----------
* World space is the stage's world space converted to metres
  (``metersPerUnit`` applied) and kept in the stage's up axis; the camera
  carries its own orientation, so the up axis matters only where cmlt invents
  something (the framing camera, the default dome light).
* Matrices are ``float64 (4, 4)`` in the column-vector convention:
  ``p_world = M @ [x, y, z, 1]`` (the transpose of a ``Gf.Matrix4d``).
* Colours are linear RGB in the rendering space, already converted from their
  authored colour space at load time.
* Point arrays handed to the core are ``float32 (N, 3)``, C-contiguous, and
  come from :func:`padded_points`: Embree reads the last vertex as 16 bytes,
  so the buffer carries one spare row that is not part of the view.
* Index arrays are ``uint32 (M, 3)`` triangles, counter-clockwise seen from
  the front (``orientation = leftHanded`` is flipped at load time).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np


def padded_points(points) -> np.ndarray:
    """Return ``points`` as float32 (N, 3) whose buffer has one spare row.

    The spare row lets Embree read the last vertex as a 16-byte vector
    without reading past the allocation (Embree's shared-buffer padding rule).
    """
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    buf = np.zeros((pts.shape[0] + 1, 3), dtype=np.float32)
    buf[:-1] = pts
    return buf[:-1]


@dataclass
class Material:
    """A UsdPreviewSurface (or fallback) material, in rendering-space RGB."""

    name: str                                   # material prim path
    diffuse: Tuple[float, float, float] = (0.18, 0.18, 0.18)
    emission: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    # the other UsdPreviewSurface inputs (the core's material parameters,
    # cmlt.shot.material_table.MATERIAL_PARAM_COLUMNS)
    specular: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    use_specular_workflow: bool = False
    metallic: float = 0.0
    roughness: float = 0.5
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.01
    opacity: float = 1.0
    opacity_threshold: float = 0.0
    ior: float = 1.5
    # every authored input of the surface shader, by name (textures, normal maps …)
    inputs: Dict[str, object] = field(default_factory=dict)


@dataclass
class Mesh:
    """A triangle mesh in its own object space (a prototype for instances)."""

    name: str                                   # prim path of the source gprim
    points: np.ndarray                          # float32 (N, 3), from padded_points
    indices: np.ndarray                         # uint32 (M, 3)
    normals: Optional[np.ndarray] = None        # float32 (N, 3) per vertex, or None
    uvs: Optional[np.ndarray] = None            # float32 (N, 2) per vertex, or None
    material_ids: Optional[np.ndarray] = None   # uint32 (M,) index into FrameScene.materials
    deforming: bool = False                     # points (or normals) may vary in time:
                                                # the bridge re-sends them each frame;
                                                # False = never looked at after the first frame
    # Motion blur: the points at the shutter's time steps (each like ``points``),
    # evenly spaced over [shutter open, shutter close]; None = no deformation blur.
    motion_points: Optional[List[np.ndarray]] = None
    # Per-vertex values that material inputs read through UsdPrimvarReaders:
    # {key: float32 (N, w)}, the key being the ``primvar_request`` of the
    # material input that reads it (``Material.inputs[name]["primvar_request"]``,
    # a cmlt.usd.shading.PrimvarRequest or any hashable for hand-built scenes;
    # w = 3 for colour inputs, 1 for scalar ones). None = no such values.
    primvars: Optional[Dict[object, np.ndarray]] = None


@dataclass
class Instance:
    """One placement of a mesh in the world."""

    name: str                                   # prim path (or instancer path + index)
    mesh: int                                   # index into FrameScene.meshes
    transform: np.ndarray                       # float64 (4, 4), object -> world (metres;
                                                # includes metersPerUnit and authored scale)
    # The transform may vary in time (an xformOp of the prim or of an ancestor,
    # or a point instancer's arrays, has time samples). False = never looked at
    # after the first frame. Hand-built scenes default to True (compared).
    animated: bool = True
    # Motion blur: object -> world at the shutter's time steps, evenly spaced
    # over [shutter open, shutter close]; None = no transform blur.
    motion_transforms: Optional[List[np.ndarray]] = None


@dataclass
class Light:
    """An analytic UsdLux light. Emissive meshes are not listed here: the
    core finds them from materials with non-zero emission.

    ``transform`` is rigid (rotation + translation in metres): the scale of
    the light's world transform, metersPerUnit included, is taken out of it
    and applied to the sizes, which are therefore world sizes in metres.
    A normalised light's radiance is divided by that world area in m²
    (distant light: by the solid angle of its cone)."""

    name: str                                   # light prim path
    kind: str                                   # 'rect' | 'disk' | 'sphere' | 'distant' | 'dome' | 'cylinder'
    transform: np.ndarray                       # float64 (4, 4), light -> world (metres)
    # Emitted radiance in rendering-space RGB: intensity * 2^exposure * color
    # (* colour temperature), divided by the surface area when `normalize` is on.
    radiance: Tuple[float, float, float] = (1.0, 1.0, 1.0)
    width: float = 1.0                          # rect, along local X (metres)
    height: float = 1.0                         # rect, along local Y (metres)
    radius: float = 0.5                         # disk, sphere, cylinder (metres)
    length: float = 1.0                         # cylinder, along local X (metres)
    angle: float = 0.53                         # distant: angular diameter, degrees
    treat_as_point: bool = False                # sphere treatAsPoint; cylinder treatAsLine
    texture: Optional[str] = None               # rect / dome texture file (resolved path)
    texture_unresolved: bool = False            # the stage's path did not resolve (warned)
    normalize: bool = False
    # UsdLux ShapingAPI (rect, disk, sphere, cylinder): cone half-angle about the
    # light's -Z in degrees (180: none), cone softness in [0, 1], focus exponent and
    # focus tint (rendering-space RGB). Formula: src/core/lights/shaping.h.
    cone_angle: float = 180.0
    cone_softness: float = 0.0
    focus: float = 0.0
    focus_tint: Tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class Camera:
    """A UsdGeom.Camera. Looks down local -Z with +Y up, as USD's cameras do.

    ``transform`` is rigid (rotation + translation in metres; any authored
    scale is removed). Focal length and apertures stay in the authored lens
    unit (see ``lens_unit``); near, far and focus_distance are metres."""

    name: str                                   # camera prim path, or '<framing>'
    transform: np.ndarray                       # float64 (4, 4), camera -> world (metres)
    projection: str = "perspective"             # 'perspective' | 'orthographic'
    focal_length: float = 50.0                  # in the same unit as the apertures
    horizontal_aperture: float = 20.955
    vertical_aperture: float = 15.2908
    horizontal_aperture_offset: float = 0.0
    vertical_aperture_offset: float = 0.0
    near: float = 0.01                          # clipping range, metres
    far: float = 1.0e6
    f_stop: float = 0.0                         # 0 = pinhole (kept for depth of field)
    focus_distance: float = 0.0                 # metres
    shutter_open: float = 0.0
    shutter_close: float = 0.0
    # metres per lens unit (focal length, apertures): USD lens values are in
    # tenths of a scene unit, so this is metersPerUnit / 10 (0.001 = mm).
    lens_unit: float = 0.001


@dataclass
class FrameScene:
    """Everything the core needs to render one time code."""

    time: float                                 # USD time code
    meshes: List[Mesh] = field(default_factory=list)
    instances: List[Instance] = field(default_factory=list)
    materials: List[Material] = field(default_factory=list)
    lights: List[Light] = field(default_factory=list)
    camera: Optional[Camera] = None
    resolution: Tuple[int, int] = (640, 480)    # (width, height), from RenderSettings or default
    meters_per_unit: float = 0.01
    up_axis: str = "Y"
    warnings: List[str] = field(default_factory=list)
    # The structure of the frame: per mesh (name, #points, #triangles, has normals,
    # has uvs, deforming) and per instance (name, mesh, animated). Equal signatures
    # on consecutive frames mean the bridge can update in place. None: unknown
    # (hand-built scenes); the bridge then checks the structure itself.
    static_signature: Optional[Tuple] = None
    # Motion blur over the camera shutter: on only when the shutter is open and
    # something moves within it; ``motion_blur_reason`` says why it is on or off.
    motion_blur: bool = False
    motion_blur_reason: str = ""
    motion_times: List[float] = field(default_factory=list)   # time codes of the steps
