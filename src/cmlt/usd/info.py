"""Describing a stage: :class:`StageInfo` (``cmlt inspect``, the frame loop)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Tuple

from pxr import Usd, UsdGeom, UsdRender, UsdShade

from .errors import UsdLoadError
from .frame import load_frame
from .materialx import mtlx_references
from .mesh_subdivision import subdiv_level_of
from .render_settings import find_settings_prim, settings_camera_problem
from .stage import (INTRINSIC_TYPES, MESH_TYPES, SUPPORTED_LIGHT_TYPES, one_line,
                    check_time_metadata, composition_warnings, ignored_reason, stage_file,
                    stage_state)
from .variants import variant_sets

__all__ = ["StageInfo", "stage_info"]


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
    #: (prim, variant set, selection or '', variant names) of the composed stage
    variant_sets: List[Tuple[str, str, str, List[str]]] = field(default_factory=list)
    #: the --variant specs the stage was opened with
    variant_specs: List[str] = field(default_factory=list)

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
        lines.append(f"variant sets ({len(self.variant_sets)})"
                     + (f", opened with --variant {' --variant '.join(self.variant_specs)}"
                        if self.variant_specs else ""))
        for prim, vset, sel, names in self.variant_sets[:40]:
            lines.append(f"  {prim}: {vset} = {sel or '(none)'}  [{', '.join(names)}]")
        if len(self.variant_sets) > 40:
            lines.append(f"  ... and {len(self.variant_sets) - 40} more")
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


def _is_light(prim) -> bool:
    return str(prim.GetTypeName()) in SUPPORTED_LIGHT_TYPES


def subdivision_note(prim) -> str:
    scheme = UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Get()
    if scheme and scheme != UsdGeom.Tokens.none:
        level = subdiv_level_of(prim)
        how = (f"refined with OpenSubdiv to level {level}" if level > 0
               else "rendered as the control cage (level 0)")
        return f"{prim.GetPath()}: subdivisionScheme is {scheme}; {how}"
    return ""


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
    try:
        return load_frame(stage, info.start).motion_blur_reason
    except Exception as exc:                          # pragma: no cover
        return f"unknown: {one_line(str(exc))}"


def stage_info(stage) -> StageInfo:
    """Describe ``stage``: time range, units, what will and will not render."""
    if stage is None:
        raise UsdLoadError("stage_info: no stage")
    check_time_metadata(stage)
    state = stage_state(stage)
    layer = stage.GetRootLayer()
    info = StageInfo(
        path=stage_file(stage),
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
        if prim.HasAuthoredReferences():
            for doc, _, _ in mtlx_references(prim):
                info.notes.append(f"{path}: references the MaterialX document {doc}, read by "
                                  "cmlt's MaterialX reader (usd-core composes no .mtlx)")
        reason = ignored_reason(prim)
        if reason:
            info.ignored.append((path, t, reason))
    info.prim_counts = counts
    info.variant_sets = variant_sets(stage)
    info.variant_specs = list(state.variant_specs)
    info.motion_blur = _motion_blur_summary(stage, info)
    try:
        settings = find_settings_prim(stage)
    except UsdLoadError:                # reported by the settings (cmlt.settings)
        settings = None
    info.settings_camera_warning = settings_camera_problem(stage, settings)
    if info.settings_camera_warning:
        warnings.append(info.settings_camera_warning)
    from ..color.stage_config import stage_color_warnings   # (cmlt.color: PyOpenColorIO, lazily)
    warnings.extend(w for w in stage_color_warnings(stage) if w not in warnings)
    if info.meters_per_unit <= 0 or not math.isfinite(info.meters_per_unit):
        warnings.append(f"{info.path}: metersPerUnit is {info.meters_per_unit:g}; using 0.01")
    info.warnings = warnings
    return info
