"""One time code of a stage -> :class:`cmlt.scene.FrameScene`.

:func:`load_frame` validates the render settings and the camera, traverses
the stage (:mod:`cmlt.usd.traversal`, point instancers in
:mod:`cmlt.usd.instancing`), picks the camera (:mod:`cmlt.usd.camera`) and
the transform motion blur over its shutter (:mod:`cmlt.usd.motion`).
"""
from __future__ import annotations

from typing import List, Tuple

import numpy as np

from pxr import Tf, UsdGeom

from ..scene import FrameScene
from .camera import MAX_COORDINATE, farthest_mesh, \
    camera_at_path, conform_aperture, framing_camera, gf_to_np, \
    instance_bounds, read_camera, stage_cameras
from .errors import UsdLoadError
from .instancing import drop_prototype_placements, prototype_roots
from .lights import DEFAULT_LIGHTS, default_lights, default_lights_note
from .motion import shutter_motion
from .render_settings import (default_resolution, find_settings_prim, settings_camera,
                              settings_camera_problem, settings_resolution)
from .stage import check_time_metadata, composition_warnings, stage_file, stage_state, time_code
from .traversal import FrameReader

__all__ = ["load_frame", "static_signature", "PURPOSES"]

#: the UsdGeom purposes ``--purpose`` may list (``default`` always renders)
PURPOSES = ("default", "render", "proxy", "guide")


def load_frame(stage, time, camera=None, resolution=None, render_settings=None,
               default_light="dome", purposes=None) -> FrameScene:
    """Read the render scene of ``stage`` at the time code ``time``.

    ``camera``: a camera prim path (UsdLoadError if it is not a Camera);
    default: the RenderSettings camera, else the first camera (warning if
    several), else a framing camera (warning). ``resolution``: (w, h),
    overriding the RenderSettings resolution (default: the core's, 640x480).
    ``render_settings``: a RenderSettings prim path; default: the stage's
    ``renderSettingsPrimPath`` metadata, else the first RenderSettings prim
    (:mod:`cmlt.usd.render_settings`). ``default_light``: what lights a stage
    without lights and emissive materials, one of ``DEFAULT_LIGHTS``
    (:func:`cmlt.usd.lights.default_lights`). ``purposes``: None (guide never,
    proxy where no render sibling), else the purposes rendered besides
    ``default`` (a subset of ``PURPOSES``). Non-fatal problems are listed in
    ``FrameScene.warnings``, each naming its prim; fatal ones raise
    :class:`UsdLoadError`.
    """
    try:
        return _load_frame(stage, time, camera, resolution, render_settings, default_light,
                           purposes)
    except Tf.ErrorException as exc:          # USD refused the data outside any one prim
        msg = " ".join(str(exc).split())
        raise UsdLoadError(f"{stage_file(stage)}: time {time}: {msg}") from None


def _resolution(stage, settings, tc, resolution) -> Tuple[int, int]:
    res = settings_resolution(settings, tc)[0] if settings is not None else None
    if resolution is not None:
        try:
            res = (int(resolution[0]), int(resolution[1]))
        except (TypeError, ValueError, IndexError):
            raise UsdLoadError(f"resolution {resolution!r} is not (width, height)") from None
    if res is None:
        res = default_resolution()
    if res[0] <= 0 or res[1] <= 0:
        raise UsdLoadError(f"{stage_file(stage)}: resolution {res[0]}x{res[1]} must be positive")
    return res


def _load_frame(stage, time, camera, resolution, render_settings, default_light,
                purposes) -> FrameScene:
    if stage is None:
        raise UsdLoadError("load_frame: no stage")
    if default_light not in DEFAULT_LIGHTS:
        raise UsdLoadError(f"default light {default_light!r}: choose one of "
                           f"{', '.join(DEFAULT_LIGHTS)}")
    check_time_metadata(stage)
    tc = time_code(stage, time)
    warnings: List[str] = []
    state = stage_state(stage)
    for w in state.open_warnings + composition_warnings(stage):
        if w not in warnings:
            warnings.append(w)
    if purposes is not None:
        bad = [p for p in purposes if p not in PURPOSES]
        if bad:
            raise UsdLoadError(f"purpose {bad[0]!r}: choose from {', '.join(PURPOSES)}")
    fr = FrameReader(stage, tc, warnings, purposes)
    up = str(UsdGeom.GetStageUpAxis(stage))

    # settings, camera path (validated before the expensive traversal)
    settings = find_settings_prim(stage, render_settings)
    res = _resolution(stage, settings, tc, resolution)
    cam_prim = None
    if camera is not None:
        cam_prim = camera_at_path(stage, camera)
    elif settings is not None and settings_camera(settings) is not None:
        problem = settings_camera_problem(stage, settings)
        if problem:
            warnings.append(problem)            # does not exist / is not a Camera
        else:
            cam_prim = stage.GetPrimAtPath(settings_camera(settings))

    # geometry, lights, materials
    proto_roots = prototype_roots(stage)
    fr.traverse(stage.GetPseudoRoot(), None)
    fr.warn_unregistered()
    if proto_roots:
        drop_prototype_placements(fr, proto_roots)

    lightless = not fr.lights and not fr.materials.has_emission()

    # camera
    if cam_prim is None:
        cams = stage_cameras(stage)
        if cams:
            cam_prim = cams[0]
            if len(cams) > 1:
                warnings.append(f"{stage_file(stage)}: {len(cams)} cameras and none chosen; "
                                f"using the first, {cam_prim.GetPath()}")
    if cam_prim is not None:
        world = fr.S @ gf_to_np(fr.xc.GetLocalToWorldTransform(cam_prim))
        cam = read_camera(cam_prim, tc, fr.mpu, world, warnings)
        if settings is not None:
            # a UsdRender pipeline: its aspectRatioConformPolicy (fallback expandAperture);
            # without render settings the horizontal aperture spans the width (camera.h)
            from pxr import UsdRender
            policy = str(UsdRender.Settings(settings).GetAspectRatioConformPolicyAttr()
                         .Get(tc) or "expandAperture")
            conform_aperture(cam, res, policy, warnings, where=str(settings.GetPath()))
    else:
        cam = framing_camera(instance_bounds(fr.meshes, fr.instances), up, res)
        reach = float(np.abs(cam.transform[:3, 3]).max())
        if not reach <= MAX_COORDINATE:
            # name the gprim that stretched the bounds, not the camera made from them
            far = farthest_mesh(fr.meshes, fr.instances)
            raise UsdLoadError(f"{far or stage_file(stage)}: its points reach so far that the framing "
                               f"camera (the stage has none) would sit at {reach:.4g}, beyond the "
                               f"{MAX_COORDINATE:g} the renderer can trace; give the stage a camera")
        warnings.append(f"{stage_file(stage)}: no camera; using a framing camera "
                        f"({'+Y' if up == 'Z' else '-Z'} view of the stage bounds)")

    if lightless:          # after the camera: a headlight and a key light follow it
        fr.lights.extend(default_lights(default_light, cam.transform))
        warnings.append(f"{stage_file(stage)}: the stage has no lights and no emissive "
                        f"materials; {default_lights_note(default_light)} (--default-light "
                        f"{'|'.join(DEFAULT_LIGHTS)})")

    blur, blur_reason, blur_times = shutter_motion(fr, cam, tc)
    ftime = float(stage.GetStartTimeCode()) if tc.IsDefault() else float(tc.GetValue())
    return FrameScene(time=ftime, motion_blur=blur, motion_blur_reason=blur_reason,
                      motion_times=blur_times,
                      meshes=fr.meshes, instances=fr.instances,
                      materials=fr.materials.materials or [],
                      lights=fr.lights, camera=cam, resolution=res,
                      meters_per_unit=fr.mpu, up_axis=up, warnings=warnings,
                      static_signature=static_signature(fr.meshes, fr.instances))


def static_signature(meshes, instances) -> Tuple:
    """The structure of a frame (see ``FrameScene.static_signature``)."""
    return (tuple((m.name, len(m.points), len(m.indices), m.normals is None, m.uvs is None,
                   bool(m.deforming)) for m in meshes),
            tuple((i.name, int(i.mesh), bool(i.animated)) for i in instances))
