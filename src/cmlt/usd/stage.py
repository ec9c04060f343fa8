"""Opening a stage, what the reader supports, and the per-stage state it keeps
between frames (describing a stage: :mod:`cmlt.usd.info`)."""
from __future__ import annotations

import math
import os
import re
import weakref
from typing import Dict, List

from pxr import Sdf, Tf, Usd, UsdGeom, UsdLux

from .diagnostics import capture_usd_diagnostics
from .errors import UsdLoadError
from .variants import apply_variants, select_render_settings

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


def one_line(text: str) -> str:
    """Collapse a (Tf) error text to one line, without C++ source locations."""
    text = _TF_PREFIX.sub("", str(text))
    parts = [p.strip().strip("'").strip() for p in text.replace("\t", " ").splitlines()]
    return "; ".join(p for p in parts if p)


def prim_at(stage, path: str):
    """The prim at an absolute prim path, or None (no prim, or not such a path)."""
    ok = Sdf.Path.IsValidPathString(path) and Sdf.Path(path).IsAbsolutePath()
    prim = stage.GetPrimAtPath(path) if ok else None
    return prim if prim else None


def stage_file(stage) -> str:
    """The file of the stage's root layer (its identifier if it has none)."""
    layer = stage.GetRootLayer()
    return layer.realPath or layer.identifier


#: an asset path of a MaterialX document in a USD message (``@look.mtlx@``, with
#: the file-format arguments USD appends when it looks for a plugin)
_MTLX_ASSET = re.compile(r"@[^@]*\.mtlx(?::SDF_FORMAT_ARGS:[^@]*)?@", re.IGNORECASE)


def is_mtlx_composition_error(msg: str) -> bool:
    """USD's complaint that a reference to a ``.mtlx`` document does not compose
    (usd-core has no MaterialX file-format plugin). cmlt's MaterialX reader reads
    such documents itself and names the material and the file when it cannot, so
    the raw USD line is not repeated as a warning (a ``.mtlx`` payload or sublayer,
    which the reader does not read, still warns)."""
    return ("Could not open asset" in msg and "for reference" in msg
            and bool(_MTLX_ASSET.search(msg)))


def composition_warnings(stage) -> List[str]:
    """Non-fatal composition problems (unresolved references, payloads,
    sublayers), one line each, naming the layer that introduced them; those
    about ``.mtlx`` documents are left to the MaterialX reader
    (:func:`is_mtlx_composition_error`)."""
    out: List[str] = []
    try:
        errors = stage.GetCompositionErrors()
    except Exception:                                   # pragma: no cover (old USD)
        errors = []
    for err in errors:
        msg = one_line(str(err))
        if msg and msg not in out and not is_mtlx_composition_error(msg):
            out.append(msg)
    return out


class StageState:
    """Per-stage state kept between calls: warnings from opening, and the
    mesh caches of :mod:`cmlt.usd.traversal`. Invalidated when the stage changes."""

    def __init__(self, stage):
        self.stage_ref = weakref.ref(stage)
        self.open_warnings: List[str] = []
        #: the --variant specs applied when opening, and the (prim, set, variant)
        #: selections they authored in the session layer (cmlt.usd.variants)
        self.variant_specs: List[str] = []
        self.variant_selections: List[tuple] = []
        self.mesh_cache: Dict[object, object] = {}
        self.shape_cache: Dict[object, object] = {}
        # (prim path, stop path) -> the transform might vary in time (traversal.py)
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
    path = stage_file(stage)
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


def open_stage(path, variants=(), render_settings=None) -> "Usd.Stage":
    """Open a stage (.usd, .usda, .usdc, .usdz) with all payloads loaded.

    ``variants``: ``--variant`` specs (``SET=VALUE``, ``/prim:SET=VALUE``,
    :mod:`cmlt.usd.variants`) applied in order in the stage's session layer;
    a spec that does not fit the stage raises
    :class:`cmlt.usd.variants.VariantError` (a UsdLoadError).
    ``render_settings``: a ``UsdRender.Settings`` prim path authored as the
    stage's ``renderSettingsPrimPath`` in the session layer (after the
    variants), so every reader of the settings uses it; VariantError if it
    names no RenderSettings prim.

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
            raise UsdLoadError(f"{path}: cannot open the stage: {one_line(exc)}") from None
        except Exception as exc:                        # pragma: no cover
            raise UsdLoadError(f"{path}: cannot open the stage: {one_line(exc)}") from None
        if stage is None:
            raise UsdLoadError(f"{path}: cannot open the stage")
        applied = apply_variants(stage, variants, where=path) if variants else []
        if render_settings:
            select_render_settings(stage, render_settings, where=path)
        composed = composition_warnings(stage)
    check_time_metadata(stage)
    state = stage_state(stage)
    state.open_warnings = composed + usd_diagnostic_warnings(stage, diags, composed)
    state.variant_specs = [str(v) for v in variants or ()]
    state.variant_selections = applied
    return stage


def usd_diagnostic_warnings(stage, diagnostics: List[str], known: List[str]) -> List[str]:
    """USD's diagnostics caught while composing ``stage`` as cmlt warnings
    naming the stage's layer; those that only repeat a composition error
    already in ``known`` (which names the layer that introduced it) are
    dropped."""
    out: List[str] = []
    layer = stage_file(stage)
    for d in diagnostics:
        if any(k.rstrip(".") in d for k in known) or is_mtlx_composition_error(d):
            continue
        msg = f"{layer}: USD: {d}"
        if msg not in out:
            out.append(msg)
    return out


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


def time_code(stage, time) -> Usd.TimeCode:
    """``time`` (a number, a Usd.TimeCode or None: the default time) as a time code;
    UsdLoadError naming the stage if it is not a finite number."""
    if isinstance(time, Usd.TimeCode):
        tc = time
    elif time is None:
        tc = Usd.TimeCode.Default()
    else:
        try:
            t = float(time)
        except (TypeError, ValueError):
            raise UsdLoadError(f"{stage_file(stage)}: time {time!r} is not a number") from None
        if not math.isfinite(t):
            raise UsdLoadError(f"{stage_file(stage)}: time {t} is not finite")
        tc = Usd.TimeCode(t)
    return tc


def tstr(tc) -> str:
    """A time code in messages: ``default`` or its value."""
    return "default" if tc.IsDefault() else f"{tc.GetValue():g}"
