"""The effects one frame calls for, from its flattened scene (:class:`cmlt.scene.FrameScene`).

Cheap: the arrays the stage reader produced are looked at once, and two questions no
array answers — can a caustic form where the camera sees it, and how hard is the light
to reach — are put to a few thousand probe rays in the core
(``cmlt._core.probe_scene``, ``src/core/analysis/scene_probes.h``). Nothing is rendered.

Only what a rendered gprim uses counts: materials bound to nothing visible, inputs the
UsdPreviewSurface model does not read in the material's workflow, and normal maps on
meshes without texture coordinates are listed as *unseen*, not as effects.

==================  ==========================================================================
effect              on when
==================  ==========================================================================
motion_blur         the shutter is open (``shutter:close > shutter:open``) **and** some
                    instance's transform differs between the shutter's time steps (the
                    stage reader's rule, ``FrameScene.motion_blur``)
depth_of_field      a perspective camera with a finite fStop (> 0) and focusDistance > 0
                    (the core's thin lens, ``Camera::has_lens``)
caustics            a light path L S+ D with D seen directly by the camera exists: a
                    near-specular surface (roughness < CAUSTIC_ROUGHNESS; metal, glass or
                    mirror, the rule of ``scene_probes.h``) that a light reaches and whose
                    chain ends on a diffuse point the camera sees. Found by the probes; the
                    details give the share of the camera-visible diffuse flux it carries
transmission        a used material with opacity < 1 (or opacity textured / from primvars),
                    ior != 1 and no opacityThreshold: the refracting dielectric lobe
clearcoat           a used material with clearcoat > 0 (or clearcoat textured / from primvars)
textures            a texture lookup happens: a used material input the model reads in its
                    workflow is a UsdUVTexture, or a rect / dome light has a texture file
normal_maps         a used material's ``normal`` is a texture and a mesh using it has
                    varying texture coordinates (the core perturbs the normal only with
                    dp/du)
cutouts             a used material lets rays through without scattering: opacityThreshold
                    > 0 with opacity below it somewhere, or an ior-1 surface with opacity < 1
dome_light          a DomeLight (also the white dome cmlt adds to a stage without lights);
                    details say whether it is textured
emissive_meshes     a used material emits (emissiveColor > 0 or textured)
delta_lights        a point light (SphereLight ``treatAsPoint``) or a DistantLight of angle 0
==================  ==========================================================================

Besides the effects, ``unsupported`` lists what the frame asks for that cmlt does not
simulate (volumes, curves, points, unsupported lights and shaders, UsdSkel blend shapes,
deformation blur with an open shutter), from the stage reader's warnings of the frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

import numpy as np

__all__ = ["EFFECT_NAMES", "Effect", "FrameEffects", "analyse_frame", "CAUSTIC_ROUGHNESS",
           "PROBE_SETTINGS", "format_effects_table"]

#: the effects, in the order `cmlt inspect` prints them
EFFECT_NAMES = ("motion_blur", "depth_of_field", "caustics", "transmission", "clearcoat",
                "textures", "normal_maps", "cutouts", "dome_light", "emissive_meshes",
                "delta_lights")

#: a surface is near-specular (caustic-capable) below this UsdPreviewSurface roughness
#: (GGX alpha = roughness^2 < 0.04: a highlight a few degrees wide)
CAUSTIC_ROUGHNESS = 0.2

#: the probes' sizes (core ``probe_scene``); ~4k rays, a few ms on the sequences
PROBE_SETTINGS = dict(light_paths=1024, targeted_paths=1024, camera_paths=256,
                      light_samples=4, max_chain=8)

#: UsdPreviewSurface inputs the core reads, as the bridge hands them over
#: (cmlt.shot.bridge._TEXTURE_INPUTS)
_CORE_INPUTS = ("diffuseColor", "emissiveColor", "specularColor", "normal", "metallic",
                "roughness", "clearcoat", "clearcoatRoughness", "opacity")

#: phrases of the stage reader's warnings about things it does not simulate
_UNSUPPORTED_PHRASES = ("are not supported", "is not supported", "not applied",
                        "unsupported shader", "no UsdPreviewSurface", "not rendered, not emitting",
                        "are not blurred")


@dataclass
class Effect:
    """One effect of a frame: whether it is on, and what the analysis found."""

    on: bool
    detail: Dict[str, object] = field(default_factory=dict)

    def summary(self) -> str:
        d = self.detail
        if "reason" in d:
            return str(d["reason"])
        parts = []
        for k, v in d.items():
            if isinstance(v, (list, tuple)):
                if not v:
                    continue
                shown = ", ".join(str(x) for x in v[:4]) + (f" (+{len(v) - 4})" if len(v) > 4
                                                             else "")
                parts.append(f"{k}: {shown}")
            elif isinstance(v, dict):
                if v:
                    parts.append(f"{k}: {len(v)}")
            elif v is False or v == 0:
                continue
            elif v is True:
                parts.append(k)
            else:
                parts.append(f"{k}: {v}")
        return "; ".join(parts)


@dataclass
class FrameEffects:
    """The effects of one frame (``as_dict`` is what sidecars and ``inspect --json`` hold)."""

    time: float
    effects: Dict[str, Effect]
    unsupported: List[str] = field(default_factory=list)
    #: the core's probe counts (``cmlt._core.probe_scene``), None without a core scene
    probes: Optional[Dict[str, float]] = None

    def __getitem__(self, name: str) -> bool:
        return self.effects[name].on

    @property
    def caustic_share(self) -> float:
        """Share of the flux onto camera-visible diffuse surfaces that arrives through
        near-specular chains (0 without caustics)."""
        p = self.probes or {}
        caustic = _caustic_flux(p)
        total = caustic + float(p.get("direct_flux", 0.0))
        return caustic / total if total > 0.0 else 0.0

    def indirect(self) -> Dict[str, float]:
        """Where the light at the camera's first diffuse hits comes from (the probes'
        luminance estimates, scene_probes.h): ``share`` of the one-bounce indirect
        irradiance in direct + indirect, ``rel_var`` the relative variance of its
        cosine-sampled estimate per bounce, and ``noise`` = share² × rel_var, the relative
        variance a path tracer's first indirect bounce adds to a camera sample (hot spots
        of indirect light make it large)."""
        p = self.probes or {}
        d, i = float(p.get("direct_irradiance", 0.0)), float(p.get("indirect_irradiance", 0.0))
        share = i / (d + i) if d + i > 0.0 else 0.0
        rel_var = float(p.get("indirect_rel_var", 0.0))
        return {"share": share, "rel_var": rel_var, "noise": share * share * rel_var}

    def visibility(self) -> Dict[str, float]:
        p = self.probes or {}
        return {"direct_visible": float(p.get("direct_visible", 0.0)),
                "bounce_visible": float(p.get("bounce_visible", 0.0)),
                "lit_hits": float(p.get("lit_hits", 0.0)),
                "camera_diffuse_hits": int(p.get("camera_diffuse_hits", 0)),
                "camera_paths": int(p.get("camera_paths", 0))}

    def as_dict(self) -> dict:
        return {
            "time": self.time,
            "effects": {n: bool(self.effects[n].on) for n in EFFECT_NAMES},
            "details": {n: _plain(self.effects[n].detail) for n in EFFECT_NAMES},
            "unsupported": list(self.unsupported),
            "caustic_share": round(self.caustic_share, 6),
            "visibility": {k: (round(v, 6) if isinstance(v, float) else v)
                           for k, v in self.visibility().items()},
            "indirect": {k: round(v, 6) for k, v in self.indirect().items()},
            "probes": _plain(self.probes) if self.probes is not None else None,
        }


def _plain(v):
    """JSON-ready: tuples -> lists, numpy scalars -> Python, floats rounded."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return round(f, 6) if math.isfinite(f) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def _caustic_flux(p: Dict[str, float]) -> float:
    if not p:
        return 0.0
    if int(p.get("targeted_paths", 0)) > 0:
        return float(p.get("caustic_flux_targeted", 0.0))
    return float(p.get("caustic_flux_emitted", 0.0))


# ---------------------------------------------------------------- materials

def _input(m, name):
    return (m.inputs or {}).get(name)


def _textured(m, name) -> bool:
    rec = _input(m, name)
    return isinstance(rec, dict) and bool(rec.get("texture"))


def _varies(m, name) -> bool:
    """The input varies over the surface: a texture or a UsdPrimvarReader."""
    rec = _input(m, name)
    return isinstance(rec, dict) and (bool(rec.get("texture")) or
                                      rec.get("primvar_request") is not None)


def _unseen_reason(m, name: str) -> str:
    """Why the model does not read input ``name`` of material ``m`` ('' if it does)."""
    if name not in _CORE_INPUTS:
        return "not an input cmlt renders"
    if name == "specularColor" and not m.use_specular_workflow:
        return "metallic workflow (useSpecularWorkflow 0) ignores specularColor"
    if name == "metallic" and m.use_specular_workflow:
        return "specular workflow ignores metallic"
    if name == "clearcoatRoughness" and not (m.clearcoat > 0 or _varies(m, "clearcoat")):
        return "clearcoat is 0"
    return ""


def _used_materials(fs) -> Dict[int, List[int]]:
    """{material index: [mesh indices using it]} over the rendered instances."""
    used: Dict[int, List[int]] = {}
    meshes = {int(i.mesh) for i in fs.instances}
    for mi in sorted(meshes):
        mesh = fs.meshes[mi]
        ids = [0] if mesh.material_ids is None else \
            np.unique(np.asarray(mesh.material_ids, dtype=np.int64)).tolist()
        for k in ids:
            if 0 <= k < len(fs.materials):
                used.setdefault(int(k), []).append(mi)
    return used


def _varying_uvs(mesh) -> bool:
    """Texture coordinates that vary over the mesh: the core gets dp/du (a tangent frame
    for normal maps) only from them; a missing st primvar reads a constant fallback."""
    if mesh.uvs is None:
        return False
    uv = np.asarray(mesh.uvs, dtype=np.float64).reshape(-1, 2)
    return len(uv) > 0 and bool((uv.max(axis=0) - uv.min(axis=0)).max() > 0)


def _is_transmissive(m) -> bool:
    if m.opacity_threshold > 0:
        return False
    if abs(m.ior - 1.0) < 1e-3:
        return False
    return m.opacity < 1.0 or _varies(m, "opacity")


def _cutout_kind(m) -> str:
    """'cut-out' / 'pass-through' / '' (the core's may_pass_rays rule)."""
    if any(c > 0 for c in m.emission) or _textured(m, "emissiveColor"):
        return ""                       # emissive surfaces stay scattering vertices
    if m.opacity_threshold > 0:
        if m.opacity < m.opacity_threshold or _varies(m, "opacity"):
            return "cut-out"
        return ""
    if abs(m.ior - 1.0) < 1e-3 and (m.opacity < 1.0 or _varies(m, "opacity")):
        return "pass-through"
    return ""


def _may_be_specular(m) -> bool:
    """The core's candidate rule (scene_probes.cpp may_be_specular) on constants."""
    rough_varies = _varies(m, "roughness")
    if not (m.roughness < CAUSTIC_ROUGHNESS) and not rough_varies:
        return False
    metal = (not m.use_specular_workflow) and (m.metallic >= 0.5 or _varies(m, "metallic"))
    mirror = m.use_specular_workflow and (max(m.specular) >= 0.5 or _varies(m, "specularColor"))
    glass = abs(m.ior - 1.0) >= 1e-3 and not m.opacity_threshold > 0 and \
        (m.opacity <= 0.5 or _varies(m, "opacity"))
    return metal or mirror or glass


# ---------------------------------------------------------------- the analysis

def analyse_frame(fs, scene=None, core=None, resolution=None, seed: int = 0) -> FrameEffects:
    """The effects of ``fs`` (a FrameScene). ``scene``: its committed core scene (the
    frame loop's, or one :class:`cmlt.shot.bridge.SceneBridge` built), which the probes
    trace; None skips them (caustics and visibility then say 'not probed').
    ``resolution``: the image the camera frames (default ``fs.resolution``)."""
    probes = scene is not None
    used = _used_materials(fs)
    mats = fs.materials
    eff: Dict[str, Effect] = {}

    # motion blur: the reader's rule (shutter open and something moves within it)
    n_moving = sum(1 for i in fs.instances if i.motion_transforms)
    eff["motion_blur"] = Effect(bool(fs.motion_blur), {
        "reason": fs.motion_blur_reason or ("on" if fs.motion_blur else "off"),
        "instances": n_moving, "time_steps": len(fs.motion_times or [])})

    # depth of field: the core's thin lens
    cam = fs.camera
    if cam is None:
        eff["depth_of_field"] = Effect(False, {"reason": "no camera"})
    else:
        f_stop, focus = float(cam.f_stop), float(cam.focus_distance)
        persp = str(cam.projection) == "perspective"
        on = persp and f_stop > 0 and focus > 0
        if on:
            radius = float(cam.focal_length) * float(cam.lens_unit or 0.001) / (2.0 * f_stop)
            eff["depth_of_field"] = Effect(True, {
                "reason": f"f/{f_stop:g}, focus {focus:g} m, lens radius {radius * 1000:.3g} mm",
                "f_stop": f_stop, "focus_distance": focus, "lens_radius": radius})
        else:
            why = ("orthographic camera" if not persp else
                   "pinhole: fStop 0" if not f_stop > 0 else "focusDistance 0")
            eff["depth_of_field"] = Effect(False, {"reason": why, "f_stop": f_stop,
                                                   "focus_distance": focus})

    # materials
    trans, coat, cut, emit, spec = [], [], [], [], []
    tex_inputs: Dict[str, List[str]] = {}
    unseen: List[str] = []
    nmap, nmap_unseen = [], []
    for k in sorted(used):
        m = mats[k]
        if _is_transmissive(m):
            trans.append(m.name)
        if m.clearcoat > 0 or _varies(m, "clearcoat"):
            coat.append(m.name)
        kind = _cutout_kind(m)
        if kind:
            cut.append(f"{m.name} ({kind})")
        if any(c > 0 for c in m.emission) or _textured(m, "emissiveColor"):
            emit.append(m.name)
        if _may_be_specular(m):
            spec.append(m.name)
        for name, rec in (m.inputs or {}).items():
            if not (isinstance(rec, dict) and rec.get("texture")):
                continue
            why = _unseen_reason(m, name)
            if why:
                unseen.append(f"{m.name}: {name} ({why})")
                continue
            if name == "normal":
                with_uv = [fs.meshes[i].name for i in used[k] if _varying_uvs(fs.meshes[i])]
                if not with_uv:
                    nmap_unseen.append(f"{m.name}: normal (no mesh using it has varying "
                                       f"texture coordinates, so no tangent frame)")
                    unseen.append(nmap_unseen[-1])
                    continue
                nmap.append(m.name)
            tex_inputs.setdefault(m.name, []).append(name)
    for k, m in enumerate(mats):
        if k in used:
            continue
        names = [n for n, rec in (m.inputs or {}).items()
                 if isinstance(rec, dict) and rec.get("texture")]
        for n in names:
            unseen.append(f"{m.name}: {n} (the material is bound to no rendered gprim)")
    light_tex = [f"{l.name} ({l.kind})" for l in fs.lights
                 if getattr(l, "texture", None) and l.kind in ("dome", "rect")]
    inputs = sorted({n for v in tex_inputs.values() for n in v})
    eff["transmission"] = Effect(bool(trans), {"materials": trans})
    eff["clearcoat"] = Effect(bool(coat), {"materials": coat})
    eff["textures"] = Effect(bool(inputs or light_tex), {
        "inputs": inputs, "materials": {k: sorted(v) for k, v in tex_inputs.items()},
        "lights": light_tex, "unseen": unseen})
    eff["normal_maps"] = Effect(bool(nmap), {"materials": nmap, "unseen": nmap_unseen})
    eff["cutouts"] = Effect(bool(cut), {"materials": cut})
    eff["emissive_meshes"] = Effect(bool(emit), {"materials": emit})

    # lights
    domes = [l for l in fs.lights if l.kind == "dome"]
    eff["dome_light"] = Effect(bool(domes), {
        "lights": [l.name for l in domes],
        "textured": any(bool(getattr(l, "texture", None)) for l in domes),
        "default": any(l.name == "<default dome>" for l in domes)})
    delta = [l.name for l in fs.lights
             if (l.kind == "sphere" and l.treat_as_point) or
             (l.kind == "distant" and not float(l.angle) > 0)]
    eff["delta_lights"] = Effect(bool(delta), {"lights": delta})

    # caustics: the probes
    probe = None
    if not spec:
        eff["caustics"] = Effect(False, {
            "reason": f"no near-specular surface (metal, glass or mirror with roughness < "
                      f"{CAUSTIC_ROUGHNESS:g})", "specular_materials": []})
    elif not probes:
        eff["caustics"] = Effect(False, {"reason": "not probed", "specular_materials": spec})
    if probes and cam is not None:
        probe = _probe(fs, scene, core, resolution, seed)
    if spec and probe is not None:
        n = int(probe["targeted_caustics"]) + int(probe["light_caustics"])
        fe = FrameEffects(0.0, {}, probes=probe)
        share = fe.caustic_share
        if n > 0:
            reason = (f"{n} probe path(s) L S+ D end on diffuse points the camera sees; "
                      f"{share * 100:.3g}% of the flux onto visible diffuse surfaces")
        elif int(probe["targeted_reached"]) == 0 and int(probe["light_hit_specular"]) == 0:
            reason = (f"no light reaches the near-specular surfaces "
                      f"({probe['targeted_paths']} targeted probes)")
        else:
            reason = ("light reaches the near-specular surfaces, but no specular chain ends "
                      "on a diffuse point the camera sees")
        eff["caustics"] = Effect(n > 0, {"reason": reason, "specular_materials": spec,
                                         "probe_paths": n, "flux_share": share})
    elif spec and "caustics" not in eff:
        eff["caustics"] = Effect(False, {"reason": "no camera to probe from",
                                         "specular_materials": spec})

    unsupported = [w for w in fs.warnings if any(p in w for p in _UNSUPPORTED_PHRASES)]
    if fs.motion_blur:
        deforming = [m.name for m in fs.meshes if m.deforming]
        if deforming:
            unsupported.append(f"{len(deforming)} deforming mesh(es) with the shutter open "
                               f"are not blurred (only transforms are): "
                               f"{', '.join(deforming[:4])}")
    return FrameEffects(time=float(fs.time), effects={n: eff[n] for n in EFFECT_NAMES},
                        unsupported=unsupported, probes=probe)


def _probe(fs, scene, core, resolution, seed) -> Dict[str, float]:
    if core is None:
        import cmlt._core as core               # noqa: F811 - lazily
    w, h = resolution or fs.resolution
    return dict(core.probe_scene(scene, int(w), int(h), seed=int(seed),
                                 specular_roughness=CAUSTIC_ROUGHNESS, **PROBE_SETTINGS))


def format_effects_table(frames: Sequence[FrameEffects], auto=None) -> str:
    """The text form of ``cmlt inspect``: one row per effect (on in any frame), its
    frames and what the analysis found in the first frame where it is on."""
    lines = ["effects:"]
    rows = []
    for name in EFFECT_NAMES:
        on_in = [fe.time for fe in frames if fe[name]]
        first = next((fe for fe in frames if fe[name]), frames[0] if frames else None)
        detail = first.effects[name].summary() if first is not None else ""
        if len(frames) > 1:
            where = "all frames" if len(on_in) == len(frames) else \
                (", ".join(f"{t:g}" for t in on_in[:6]) + (" ..." if len(on_in) > 6 else "")
                 if on_in else "")
            detail = (f"[{where}] " if where else "") + detail
        rows.append((name, "yes" if on_in else "no", detail))
    w0 = max(len(r[0]) for r in rows)
    lines.append(f"  {'effect':<{w0}}  on   detail")
    lines += [f"  {n:<{w0}}  {v:<3}  {d}" for n, v, d in rows]
    unsupported = []
    for fe in frames:
        for u in fe.unsupported:
            if u not in unsupported:
                unsupported.append(u)
    if unsupported:
        lines.append("  not simulated:")
        lines += [f"    {u}" for u in unsupported]
    if frames:
        v = frames[0].visibility()
        lines.append(f"  visibility (frame {frames[0].time:g}): {v['direct_visible'] * 100:.3g}% "
                     f"of light samples at the camera's first diffuse hits reach a light, "
                     f"{v['bounce_visible'] * 100:.3g}% one bounce further")
    if auto is not None:
        lines.append(f"integrator auto: {auto.name} ({auto.reason})")
    return "\n".join(lines)
