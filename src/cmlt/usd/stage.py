"""Opening a stage and describing it (``cmlt inspect``)."""
from __future__ import annotations

import math
import os
import re
import weakref
from dataclasses import dataclass, field
from typing import Dict, List, Tuple

from pxr import Sdf, Tf, Usd, UsdGeom, UsdLux, UsdRender, UsdShade

from .diagnostics import capture_usd_diagnostics
from .errors import UsdLoadError

# Gprim types the reader turns into triangles.
MESH_TYPES = ("Mesh",)
INTRINSIC_TYPES = ("Sphere", "Cube", "Cylinder", "Cone", "Capsule", "Plane",
                   "Cylinder_1", "Capsule_1")
SUPPORTED_LIGHT_TYPES = {
    "RectLight": "rect", "DiskLight": "disk", "SphereLight": "sphere",
    "DistantLight": "distant", "DomeLight": "dome", "DomeLight_1": "dome",
    "CylinderLight": "cylinder",
}


_TF_PREFIX = re.compile(r"Error in '[^']*' at line \d+ in file \S+ : ")


def _one_line(text: str) -> str:
    """Collapse a (Tf) error text to one line, without C++ source locations."""
    text = _TF_PREFIX.sub("", str(text))
    parts = [p.strip().strip("'").strip() for p in text.replace("\t", " ").splitlines()]
    return "; ".join(p for p in parts if p)


def _stage_file(stage) -> str:
    layer = stage.GetRootLayer()
    return layer.realPath or layer.identifier


def composition_warnings(stage) -> List[str]:
    """Non-fatal composition problems (unresolved references, payloads,
    sublayers), one line each, naming the layer that introduced them."""
    out: List[str] = []
    try:
        errors = stage.GetCompositionErrors()
    except Exception:                                   # pragma: no cover (old USD)
        errors = []
    for err in errors:
        msg = _one_line(str(err))
        if msg and msg not in out:
            out.append(msg)
    return out


class StageState:
    """Per-stage state kept between calls: warnings from opening, and the
    mesh caches of :mod:`cmlt.usd.frame`. Invalidated when the stage changes."""

    def __init__(self, stage):
        self.stage_ref = weakref.ref(stage)
        self.open_warnings: List[str] = []
        self.mesh_cache: Dict[object, object] = {}
        self.shape_cache: Dict[object, object] = {}
        # (prim path, stop path) -> the transform might vary in time (frame.py)
        self.xform_anim: Dict[object, bool] = {}
        # (gprim key, material signature) -> (tri_face, material ids): one array
        # object per static mesh, so the bridge recognises it by identity
        self.material_ids_cache: Dict[object, object] = {}
        self.skel = None                # cmlt.usd.skel.SkelBindings, made on first use
        self._listener = Tf.Notice.Register(Usd.Notice.ObjectsChanged, self._changed, stage)

    def _changed(self, notice, sender):
        self.mesh_cache.clear()
        self.xform_anim.clear()
        self.material_ids_cache.clear()
        self.skel = None


_STATES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def stage_state(stage) -> StageState:
    st = _STATES.get(stage)
    if st is None:
        st = StageState(stage)
        _STATES[stage] = st
    return st


def check_time_metadata(stage) -> None:
    """Raise :class:`UsdLoadError` for a time range cmlt cannot render."""
    path = _stage_file(stage)
    tcps = stage.GetTimeCodesPerSecond()
    if not (math.isfinite(tcps) and tcps > 0):
        raise UsdLoadError(f"{path}: timeCodesPerSecond is {tcps:g}; it must be > 0")
    fps = stage.GetFramesPerSecond()
    if not (math.isfinite(fps) and fps > 0):
        raise UsdLoadError(f"{path}: framesPerSecond is {fps:g}; it must be > 0")
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    if not (math.isfinite(start) and math.isfinite(end)):
        raise UsdLoadError(f"{path}: startTimeCode/endTimeCode are not finite ({start:g}, {end:g})")
    if start > end:
        raise UsdLoadError(f"{path}: startTimeCode {start:g} is after endTimeCode {end:g}")


def open_stage(path) -> "Usd.Stage":
    """Open a stage (.usd, .usda, .usdc, .usdz) with all payloads loaded.

    Raises :class:`UsdLoadError` (one line, naming the file) for a missing
    file, an unreadable root layer, ``timeCodesPerSecond <= 0`` or
    ``startTimeCode > endTimeCode``. Unresolved references, payloads and
    sublayers are not fatal: they are kept as warnings naming the layer that
    introduced them (see :func:`stage_info` and ``FrameScene.warnings``).
    """
    path = os.fspath(path)
    if not path:
        raise UsdLoadError("no stage file given")
    if "://" not in path and not os.path.isfile(path):
        if os.path.isdir(path):
            raise UsdLoadError(f"{path}: is a directory, not a USD file")
        raise UsdLoadError(f"{path}: no such file")
    try:
        if not Sdf.FileFormat.FindByExtension(Sdf.FileFormat.GetFileExtension(path)):
            raise UsdLoadError(f"{path}: not a USD file (unknown extension)")
    except UsdLoadError:
        raise
    except Exception:
        pass
    # USD prints its own diagnostics (e.g. "Warning: in _ReportErrors at line ... of
    # stage.cpp") straight to fd 2, past --quiet and --log-json: catch them here
    with capture_usd_diagnostics() as diags:
        try:
            stage = Usd.Stage.Open(path, Usd.Stage.LoadAll)
        except Tf.ErrorException as exc:
            raise UsdLoadError(f"{path}: cannot open the stage: {_one_line(exc)}") from None
        except Exception as exc:                        # pragma: no cover
            raise UsdLoadError(f"{path}: cannot open the stage: {_one_line(exc)}") from None
        if stage is None:
            raise UsdLoadError(f"{path}: cannot open the stage")
        composed = composition_warnings(stage)
    check_time_metadata(stage)
    state = stage_state(stage)
    state.open_warnings = composed + usd_diagnostic_warnings(stage, diags, composed)
    return stage


def usd_diagnostic_warnings(stage, diagnostics: List[str], known: List[str]) -> List[str]:
    """USD's diagnostics caught while composing ``stage`` as cmlt warnings
    naming the stage's layer; those that only repeat a composition error
    already in ``known`` (which names the layer that introduced it) are
    dropped."""
    out: List[str] = []
    layer = _stage_file(stage)
    for d in diagnostics:
        if any(k.rstrip(".") in d for k in known):
            continue
        msg = f"{layer}: USD: {d}"
        if msg not in out:
            out.append(msg)
    return out


@dataclass
class StageInfo:
    """What is in a stage, for ``cmlt inspect`` and for the frame loop."""

    path: str
    start: float
    end: float
    time_codes_per_second: float
    fps: float
    meters_per_unit: float
    up_axis: str
    has_authored_time_range: bool
    prim_counts: Dict[str, int] = field(default_factory=dict)   # by type name
    meshes: List[str] = field(default_factory=list)             # meshes and intrinsic gprims
    lights: List[str] = field(default_factory=list)
    materials: List[str] = field(default_factory=list)
    cameras: List[str] = field(default_factory=list)
    render_settings: List[str] = field(default_factory=list)
    point_instancers: List[str] = field(default_factory=list)
    ignored: List[Tuple[str, str, str]] = field(default_factory=list)  # (path, type, reason)
    notes: List[str] = field(default_factory=list)
    warnings: List[str] = field(default_factory=list)
    motion_blur: str = ""            # "on: ..." / "off: ..." at the first frame, and why
    #: the render settings' camera cannot be used (also in ``warnings``; moot with --camera)
    settings_camera_warning: str = ""

    @property
    def frame_count(self) -> int:
        return int(math.floor(self.end - self.start + 1e-9)) + 1

    def format(self) -> str:
        """A readable multi-line report."""
        lines = [f"stage      {self.path}"]
        rng = f"{self.start:g} .. {self.end:g}"
        if not self.has_authored_time_range:
            rng += " (not authored)"
        lines.append(f"time       {rng}, {self.time_codes_per_second:g} time codes/s, {self.fps:g} fps")
        lines.append(f"units      metersPerUnit {self.meters_per_unit:g}, upAxis {self.up_axis}")
        if self.motion_blur:
            lines.append(f"motion blur {self.motion_blur}")
        if self.prim_counts:
            counts = ", ".join(f"{k} {v}" for k, v in sorted(self.prim_counts.items()))
            lines.append(f"prims      {counts}")
        for title, items in (("meshes", self.meshes), ("lights", self.lights),
                             ("materials", self.materials), ("cameras", self.cameras),
                             ("render settings", self.render_settings),
                             ("point instancers", self.point_instancers)):
            lines.append(f"{title} ({len(items)})")
            shown = items[:20]
            lines.extend(f"  {p}" for p in shown)
            if len(items) > len(shown):
                lines.append(f"  ... and {len(items) - len(shown)} more")
        if self.ignored:
            lines.append(f"ignored ({len(self.ignored)})")
            lines.extend(f"  {p} [{t}]: {r}" for p, t, r in self.ignored)
        if self.notes:
            lines.append(f"notes ({len(self.notes)})")
            lines.extend(f"  {n}" for n in self.notes)
        if self.warnings:
            lines.append(f"warnings ({len(self.warnings)})")
            lines.extend(f"  {w}" for w in self.warnings)
        return "\n".join(lines)


def _plural(type_name: str) -> str:
    if type_name.endswith("s"):
        return type_name                          # BasisCurves, Points
    if type_name.endswith(("ch", "sh", "x")):
        return type_name + "es"                   # NurbsPatches, TetMeshes
    return type_name + "s"                        # Volumes


def unregistered_type(prim) -> bool:
    """``prim`` names a type no loaded USD schema defines (``def FooBarType
    "x"``: a typo, or a plugin that is not installed)."""
    type_name = str(prim.GetTypeName())
    if not type_name:
        return False
    try:
        return bool(prim.GetPrimTypeInfo().GetSchemaType().isUnknown)
    except Exception:                                   # pragma: no cover (old USD)
        return bool(Usd.SchemaRegistry.GetTypeFromName(type_name).isUnknown)


#: the reason given for a prim of an unregistered type
UNREGISTERED_REASON = ("{type} is not a registered prim type (no loaded USD schema defines it; "
                       "a typo or a missing plugin?); not rendered, and its own transform is "
                       "not applied to its children")


def ignored_reason(prim) -> str:
    """Why an (unsupported) prim is not rendered, or '' if it is not ignored."""
    type_name = str(prim.GetTypeName())
    if unregistered_type(prim):
        return UNREGISTERED_REASON.format(type=type_name)
    if prim.IsA(UsdGeom.Gprim):
        if type_name in MESH_TYPES or type_name in INTRINSIC_TYPES:
            return ""
        return f"{_plural(type_name)} are not supported and are not rendered"
    if prim.HasAPI(UsdLux.LightAPI) or prim.IsA(UsdLux.BoundableLightBase) \
            or prim.IsA(UsdLux.NonboundableLightBase):
        if type_name in SUPPORTED_LIGHT_TYPES:
            return ""
        if prim.IsA(UsdGeom.Gprim):
            return ""
        return f"{type_name or 'LightAPI'} lights are not supported and are not rendered"
    return ""


def _is_light(prim) -> bool:
    return str(prim.GetTypeName()) in SUPPORTED_LIGHT_TYPES


def subdivision_note(prim) -> str:
    scheme = UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Get()
    if scheme and scheme != UsdGeom.Tokens.none:
        from .mesh import subdiv_level_of
        level = subdiv_level_of(prim)
        how = (f"refined with OpenSubdiv to level {level}" if level > 0
               else "rendered as the control cage (level 0)")
        return f"{prim.GetPath()}: subdivisionScheme is {scheme}; {how}"
    return ""


def settings_camera_problem(stage, settings) -> str:
    """Why the ``camera`` relationship of a ``UsdRender.Settings`` cannot be
    used ('' when it can, or when it is not authored): its target does not
    exist, or is not a Camera. One line naming the settings prim and the
    target; the frame loop then renders from another camera."""
    if settings is None:
        return ""
    rs = settings if isinstance(settings, UsdRender.Settings) else UsdRender.Settings(settings)
    targets = rs.GetCameraRel().GetForwardedTargets()
    if not targets:
        return ""
    path = targets[0]
    prim = stage.GetPrimAtPath(path)
    if not prim:
        why = "does not exist"
    elif not prim.IsA(UsdGeom.Camera):
        why = f"is a {prim.GetTypeName() or 'typeless prim'}, not a Camera"
    else:
        return ""
    return f"{rs.GetPath()}: camera {path} {why}; rendering from another camera"


def _motion_blur_summary(stage, info) -> str:
    """Motion blur at the first frame: cheap when no camera has an open
    shutter (the common case); otherwise the frame is read to see whether
    something moves within the shutter."""
    open_shutter = False
    for path in info.cameras:
        cam = UsdGeom.Camera(stage.GetPrimAtPath(path))
        o = cam.GetShutterOpenAttr().Get(info.start)
        c = cam.GetShutterCloseAttr().Get(info.start)
        if o is not None and c is not None and c > o:
            open_shutter = True
    if not info.cameras:
        return "off: no camera (the framing camera has a closed shutter)"
    if not open_shutter:
        return "off: shutter closed (shutter:close <= shutter:open)"
    from .frame import load_frame                     # noqa: E402 (cycle)
    try:
        return load_frame(stage, info.start).motion_blur_reason
    except Exception as exc:                          # pragma: no cover
        return f"unknown: {_one_line(str(exc))}"


def stage_info(stage) -> StageInfo:
    """Describe ``stage``: time range, units, what will and will not render."""
    if stage is None:
        raise UsdLoadError("stage_info: no stage")
    check_time_metadata(stage)
    state = stage_state(stage)
    layer = stage.GetRootLayer()
    info = StageInfo(
        path=_stage_file(stage),
        start=stage.GetStartTimeCode(),
        end=stage.GetEndTimeCode(),
        time_codes_per_second=stage.GetTimeCodesPerSecond(),
        fps=stage.GetFramesPerSecond(),
        meters_per_unit=UsdGeom.GetStageMetersPerUnit(stage),
        up_axis=str(UsdGeom.GetStageUpAxis(stage)),
        has_authored_time_range=bool(layer.HasStartTimeCode() and layer.HasEndTimeCode()),
    )
    warnings = list(state.open_warnings)
    for w in composition_warnings(stage):
        if w not in warnings:
            warnings.append(w)
    counts: Dict[str, int] = {}
    for prim in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()):
        if prim.IsPseudoRoot():
            continue
        t = str(prim.GetTypeName()) or "(typeless)"
        counts[t] = counts.get(t, 0) + 1
        path = str(prim.GetPath())
        if t in MESH_TYPES or t in INTRINSIC_TYPES:
            info.meshes.append(path)
            if t == "Mesh":
                note = subdivision_note(prim)
                if note:
                    info.notes.append(note)
        elif _is_light(prim):
            info.lights.append(path)
        elif prim.IsA(UsdShade.Material):
            info.materials.append(path)
        elif prim.IsA(UsdGeom.Camera):
            info.cameras.append(path)
        elif prim.IsA(UsdRender.Settings):
            info.render_settings.append(path)
        elif prim.IsA(UsdGeom.PointInstancer):
            info.point_instancers.append(path)
        elif t == "SkelRoot":
            info.notes.append(f"{path}: UsdSkel skinning is applied per frame with usd-core's "
                              f"UsdSkel (skinning queries); blend shapes are not applied")
        reason = ignored_reason(prim)
        if reason:
            info.ignored.append((path, t, reason))
    info.prim_counts = counts
    info.motion_blur = _motion_blur_summary(stage, info)
    from .frame import _render_settings               # noqa: E402 (cycle)
    try:
        settings = _render_settings(stage, None)
    except UsdLoadError:                               # pragma: no cover
        settings = None
    info.settings_camera_warning = settings_camera_problem(stage, settings)
    if info.settings_camera_warning:
        warnings.append(info.settings_camera_warning)
    from ..color.config import stage_color_warnings     # noqa: E402 (PyOpenColorIO: lazily)
    warnings.extend(w for w in stage_color_warnings(stage) if w not in warnings)
    if info.meters_per_unit <= 0 or not math.isfinite(info.meters_per_unit):
        warnings.append(f"{info.path}: metersPerUnit is {info.meters_per_unit:g}; using 0.01")
    info.warnings = warnings
    return info
