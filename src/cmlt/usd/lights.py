"""UsdLux lights -> :class:`cmlt.scene.Light`.

Units: ``Light.transform`` is rigid (rotation + translation in metres: the
scale of the light's world transform, metersPerUnit included, is taken out)
and the sizes (width, height, radius, length) are world sizes in metres, the
authored local sizes times the scale along the matching axes. Normalised
lights divide by the world area in square metres.

Dome lights: the core's lat-long dome has its top pole on light-space +Y. A
``DomeLight_1`` whose ``poleAxis`` is ``Z`` (or ``scene``, its default, on a
Z-up stage) gets a 90 degree rotation about X first (:func:`dome_pole_axis`),
the one ``UsdLuxDomeLight.OrientToStageUpAxis`` authors; a ``DomeLight`` keeps
+Y, as UsdLux specifies.
"""
from __future__ import annotations

import math
from typing import List, Optional, Tuple

import numpy as np
from pxr import Sdf, UsdGeom

from ..scene import Light
from .color import to_rendering_space
from .stage import SUPPORTED_LIGHT_TYPES


def light_input(prim, name: str, default, time):
    """Read a UsdLux input under its ``inputs:`` name (USD >= 21) or its old
    bare name, else the schema fallback, else ``default``."""
    for attr_name in ("inputs:" + name, name):
        attr = prim.GetAttribute(attr_name)
        if attr and attr.HasAuthoredValue():
            v = attr.Get(time)
            if v is not None:
                return v
    attr = prim.GetAttribute("inputs:" + name)
    if attr:
        v = attr.Get(time)
        if v is not None:
            return v
    return default


# ------------------------------------------------------------ colour temperature

def _cie_xyz_bar(lam_nm: np.ndarray):
    """CIE 1931 2° colour matching functions, multi-lobe Gaussian fit
    (Wyman, Sloan, Shirley 2013)."""
    def g(x, mu, s1, s2):
        s = np.where(x < mu, s1, s2)
        return np.exp(-0.5 * ((x - mu) / s) ** 2)
    x = (1.056 * g(lam_nm, 599.8, 37.9, 31.0) + 0.362 * g(lam_nm, 442.0, 16.0, 26.7)
         - 0.065 * g(lam_nm, 501.1, 20.4, 26.2))
    y = 0.821 * g(lam_nm, 568.8, 46.9, 40.5) + 0.286 * g(lam_nm, 530.9, 16.3, 31.1)
    z = 1.217 * g(lam_nm, 437.0, 11.8, 36.0) + 0.681 * g(lam_nm, 459.0, 26.0, 13.8)
    return x, y, z


_XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                           [-0.9692660, 1.8760108, 0.0415560],
                           [0.0556434, -0.2040259, 1.0572252]])


def blackbody_rgb(kelvin: float) -> Tuple[float, float, float]:
    """Linear Rec.709 colour of a blackbody, normalised to luminance 1
    (negative components clipped). Valid roughly for 1000 K .. 40000 K."""
    t = float(np.clip(kelvin if math.isfinite(kelvin) else 6500.0, 1000.0, 40000.0))
    lam = np.linspace(380.0, 780.0, 401)
    lam_m = lam * 1e-9
    c1, c2 = 3.741771852e-16, 1.438776877e-2
    spd = c1 / (lam_m ** 5 * (np.exp(c2 / (lam_m * t)) - 1.0))
    xb, yb, zb = _cie_xyz_bar(lam)
    xyz = np.array([np.sum(spd * xb), np.sum(spd * yb), np.sum(spd * zb)])
    rgb = np.clip(_XYZ_TO_REC709 @ xyz, 0.0, None)
    lum = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
    rgb = rgb / lum if lum > 0 else np.ones(3)
    return (float(rgb[0]), float(rgb[1]), float(rgb[2]))


# ------------------------------------------------------------ transforms

def rigid_and_scale(m: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Split a column-vector 4x4 into a rigid transform (polar rotation +
    translation) and the lengths of the three local axes."""
    a = m[:3, :3]
    scale = np.linalg.norm(a, axis=0)
    out = np.eye(4)
    out[:3, 3] = m[:3, 3]
    try:
        u, _, vt = np.linalg.svd(a)
        r = u @ vt
    except np.linalg.LinAlgError:                        # pragma: no cover
        r = np.eye(3)
    if not np.isfinite(r).all():
        r = np.eye(3)
    out[:3, :3] = r
    return out, scale


def _asset(v, path: str, warnings: List[str], light=None) -> Optional[str]:
    if isinstance(v, Sdf.AssetPath):
        if v.path and not v.resolvedPath:
            if light is not None:
                light.texture_unresolved = True
            warnings.append(f"{path}: texture:file {v.path} cannot be resolved; the light is "
                            "not textured")
        return v.resolvedPath or v.path or None
    return str(v) if v else None


#: light space with its pole on +Z from the core's +Y-pole dome: a rotation of 90
#: degrees about X, the one UsdLuxDomeLight.OrientToStageUpAxis authors on Z-up stages
_Y_POLE_TO_Z = np.array([[1.0, 0.0, 0.0, 0.0],
                         [0.0, 0.0, -1.0, 0.0],
                         [0.0, 1.0, 0.0, 0.0],
                         [0.0, 0.0, 0.0, 1.0]])


def dome_pole_axis(prim, warnings: Optional[List[str]] = None) -> str:
    """The axis of a dome light's top pole in its own space: ``Y`` for a
    ``DomeLight`` (the OpenEXR lat-long convention; Z-up stages rotate the light
    themselves), ``poleAxis`` for a ``DomeLight_1`` (``scene``, the default, is the
    stage's up axis; not inherited by children)."""
    if str(prim.GetTypeName()) != "DomeLight_1":
        return "Y"
    attr = prim.GetAttribute("poleAxis")
    value = str(attr.Get()) if attr and attr.Get() is not None else "scene"
    if value == "scene":
        return str(UsdGeom.GetStageUpAxis(prim.GetStage()))
    if value not in ("Y", "Z"):
        if warnings is not None:
            warnings.append(f"{prim.GetPath()}: poleAxis {value!r} is not scene, Y or Z; "
                            "using the stage's up axis")
        return str(UsdGeom.GetStageUpAxis(prim.GetStage()))
    return value


def read_light(prim, time, world_m: np.ndarray, warnings: List[str]) -> Optional[Light]:
    """Read a supported UsdLux light. ``world_m`` is its light->world matrix
    (column convention) already in metres."""
    path = str(prim.GetPath())
    kind = SUPPORTED_LIGHT_TYPES.get(str(prim.GetTypeName()))
    if kind is None:
        return None
    if not np.isfinite(np.asarray(world_m, dtype=np.float64)).all():
        warnings.append(f"{path}: its transform is not finite (time {_t(time)}); not rendered")
        return None
    xf, s = rigid_and_scale(world_m)

    def num(name, default):
        try:
            v = float(light_input(prim, name, default, time))
        except (TypeError, ValueError):
            v = float(default)
        if not math.isfinite(v):
            warnings.append(f"{path}: inputs:{name} is not finite (time {_t(time)}); "
                            f"using {default}")
            v = float(default)
        return v

    intensity = num("intensity", 1.0)
    exposure = num("exposure", 0.0)
    color = light_input(prim, "color", (1.0, 1.0, 1.0), time)
    cattr = prim.GetAttribute("inputs:color") or prim.GetAttribute("color")
    rgb = np.array(to_rendering_space(color, cattr if cattr else prim, prim=prim))
    if bool(light_input(prim, "enableColorTemperature", False, time)):
        # blackbody_rgb is linear Rec.709; the light colour is already ACEScg
        rgb = rgb * np.array(to_rendering_space(blackbody_rgb(num("colorTemperature", 6500.0)),
                                                "lin_rec709"))
    normalize = bool(light_input(prim, "normalize", False, time))
    radiance = intensity * (2.0 ** exposure) * rgb

    light = Light(name=path, kind=kind, transform=xf, normalize=normalize)
    area = None
    if kind == "rect":
        light.width = float(abs(num("width", 1.0)) * s[0])
        light.height = float(abs(num("height", 1.0)) * s[1])
        light.texture = _asset(light_input(prim, "texture:file", None, time), path, warnings,
                               light)
        area = light.width * light.height
    elif kind == "disk":
        light.radius = float(abs(num("radius", 0.5)) * 0.5 * (s[0] + s[1]))
        area = math.pi * light.radius ** 2
    elif kind == "sphere":
        light.radius = float(abs(num("radius", 0.5)) * np.mean(s))
        light.treat_as_point = bool(light_input(prim, "treatAsPoint", False, time))
        area = 4.0 * math.pi * light.radius ** 2
    elif kind == "cylinder":
        light.length = float(abs(num("length", 1.0)) * s[0])
        light.radius = float(abs(num("radius", 0.5)) * 0.5 * (s[1] + s[2]))
        light.treat_as_point = bool(light_input(prim, "treatAsLine", False, time))
        area = 2.0 * math.pi * light.radius * light.length
    elif kind == "distant":
        light.angle = abs(num("angle", 0.53))
        half = math.radians(min(light.angle, 360.0)) / 2.0
        area = 2.0 * math.pi * (1.0 - math.cos(half))        # solid angle of the cone
    elif kind == "dome":
        light.texture = _asset(light_input(prim, "texture:file", None, time), path, warnings,
                               light)
        pole = dome_pole_axis(prim, warnings)
        if pole == "Z":
            light.transform = xf @ _Y_POLE_TO_Z
    if kind in ("rect", "disk", "sphere", "cylinder"):
        light.cone_angle = num("shaping:cone:angle", 180.0)
        light.cone_softness = num("shaping:cone:softness", 0.0)
        light.focus = num("shaping:focus", 0.0)
        tint = light_input(prim, "shaping:focusTint", (0.0, 0.0, 0.0), time)
        try:
            tint = tuple(float(c) for c in tint)
        except (TypeError, ValueError):
            tint = (0.0, 0.0, 0.0)
        if len(tint) == 3 and all(math.isfinite(c) for c in tint):
            light.focus_tint = tint
        ies = prim.GetAttribute("inputs:shaping:ies:file")
        if ies and ies.HasAuthoredValue() and ies.Get(time):
            warnings.append(f"{path}: inputs:shaping:ies:file (IES profile) is not "
                            f"supported; ignored")
    for size in ("width", "height", "radius", "length"):
        v = getattr(light, size)
        with np.errstate(over="ignore"):
            ok = bool(np.isfinite(np.float32(v)))   # the core holds sizes in float32
        if not ok:
            warnings.append(f"{path}: its {size} is not finite in world space ({v:g}, time "
                            f"{_t(time)}); not rendered")
            return None
    if kind == "distant" and not math.isfinite(light.angle):     # pragma: no cover (num() checks)
        light.angle = 0.53
    if area is not None and not math.isfinite(area):
        warnings.append(f"{path}: its area overflows (time {_t(time)}); not rendered")
        return None
    if normalize and area is not None:
        if area > 0:
            radiance = radiance / area
        else:
            warnings.append(f"{path}: normalize is on but the light has zero size; "
                            f"radiance not normalised")
    with np.errstate(over="ignore", invalid="ignore"):
        single = np.isfinite(radiance.astype(np.float32))   # the core holds it in float32
    if not single.all():
        warnings.append(f"{path}: its radiance is not finite in single precision "
                        f"({_fmt(radiance)}, time {_t(time)}); those components set to 0")
        radiance = np.where(single, radiance, 0.0)
    if (radiance < 0).any():
        warnings.append(f"{path}: its radiance has negative components ({_fmt(radiance)}, time "
                        f"{_t(time)}: intensity, exposure and color multiplied); clamped to 0")
        radiance = np.maximum(radiance, 0.0)
    light.radiance = (float(radiance[0]), float(radiance[1]), float(radiance[2]))
    return light


def _fmt(v) -> str:
    return ", ".join(f"{float(c):g}" for c in v)


def _t(time) -> str:
    return "default" if time.IsDefault() else f"{time.GetValue():g}"


def default_dome() -> Light:
    """White dome light of radiance 1, for stages without any light."""
    return Light(name="<default dome>", kind="dome", transform=np.eye(4),
                 radiance=(1.0, 1.0, 1.0))


#: ``--default-light`` choices: what a stage without lights (and without emissive
#: materials) is lit by
DEFAULT_LIGHTS = ("dome", "headlight", "dome-key")

#: the sun's angular diameter of the default distant lights, degrees
_DEFAULT_SUN_ANGLE = 1.0


def _looking_along(d) -> np.ndarray:
    """A rotation (column-vector 4x4) whose local -Z is the unit direction ``d``
    (a distant light travels along its -Z)."""
    z = -np.asarray(d, np.float64) / np.linalg.norm(d)
    helper = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, z
    return m


def _sun(name: str, travel, irradiance: float) -> Light:
    """A distant light travelling along ``travel`` whose irradiance at normal
    incidence is ``irradiance`` (its radiance times the solid angle of its cone)."""
    half = math.radians(_DEFAULT_SUN_ANGLE) / 2.0
    omega = 2.0 * math.pi * (1.0 - math.cos(half))
    L = irradiance / omega
    return Light(name=name, kind="distant", transform=_looking_along(travel),
                 radiance=(L, L, L), angle=_DEFAULT_SUN_ANGLE)


def default_lights(kind: str, camera_transform) -> List[Light]:
    """The lights of a stage that has none (``--default-light``):

    * ``dome``: a white dome of radiance 1 (a white diffuse surface comes out 1
      wherever it sees the whole sky: a furnace, which hides shape and material);
    * ``headlight``: a distant light travelling along the camera's view, as
      usdrecord and Storm light a stage without lights; irradiance pi at normal
      incidence (a white diffuse surface facing the camera comes out 1);
    * ``dome-key``: a dome of radiance 0.25 for fill plus a key light from the
      camera's upper left, behind it (irradiance 0.8 pi), so that shading, shadows and
      highlights show.

    ``camera_transform``: the camera's rigid camera -> world matrix (column vectors).
    """
    if kind not in DEFAULT_LIGHTS:
        raise ValueError(f"default light {kind!r}: choose one of {', '.join(DEFAULT_LIGHTS)}")
    if kind == "dome":
        return [default_dome()]
    rot = np.asarray(camera_transform, np.float64)[:3, :3]
    if kind == "headlight":
        return [_sun("<default headlight>", rot @ np.array([0.0, 0.0, -1.0]), math.pi)]
    fill = Light(name="<default fill dome>", kind="dome", transform=np.eye(4),
                 radiance=(0.25, 0.25, 0.25))
    key = _sun("<default key light>", rot @ np.array([1.0, -1.0, -1.0]), 0.8 * math.pi)
    return [fill, key]


def default_lights_note(kind: str) -> str:
    """What the warning about a lightless stage says was added."""
    return {"dome": "adding a white dome light (radiance 1)",
            "headlight": "adding a headlight (a distant light along the camera's view)",
            "dome-key": "adding a fill dome (radiance 0.25) and a key light from the "
                        "camera's upper left"}[kind]
