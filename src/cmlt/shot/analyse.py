"""Frames -> their effects (:mod:`cmlt.analysis`), and ``--integrator auto`` resolved for
a shot before its first frame renders.

The analysis of a frame needs its core scene (the probes trace it): the frame loop hands
in the scene it just built; :func:`analyse_frames` builds its own, one
:class:`SceneBridge` for all the frames it is given, so consecutive frames update the
scene in place as a render does.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

from ..analysis import AutoChoice, FrameEffects, analyse_frame, choose_integrator, sample_frames
from .bridge import BridgeError, SceneBridge
from .errors import RenderError

__all__ = ["analyse_frames", "resolve_auto", "auto_frames", "resolve_auto_setting",
           "resolve_chainless_setting", "chainless_choice", "CHAINLESS_BDPT_RULES",
           "frame_effects", "inspect_effects"]


def analyse_frames(stage, frames: Sequence[float], core, camera: Optional[str] = None,
                   resolution=None, cache: Optional[Dict[float, FrameEffects]] = None,
                   skip_bad: bool = False,
                   memory: Optional[Dict[float, dict]] = None) -> List[FrameEffects]:
    """The effects of each of ``frames`` (time codes) of ``stage``; ``cache`` (time ->
    FrameEffects) is read and filled. Raises RenderError naming the frame when the frame
    cannot be loaded or the core refuses its scene; with ``skip_bad`` such frames are
    left out instead, unless all are bad (then the first one's error): a render decides
    from the frames it can read and reports a bad frame when it reaches it, after the
    frames before it are written. ``memory`` (time -> record), when given, gets the memory
    of each frame's scene built here (:func:`cmlt.shot.memory.scene_memory`)."""
    from ..color import ColorError
    from .memory import scene_memory
    from ..usd import UsdLoadError, load_frame

    out: List[FrameEffects] = []
    bridge = None
    first_error: Optional[RenderError] = None
    for f in frames:
        f = float(f)
        if cache is not None and f in cache:
            out.append(cache[f])
            continue
        try:
            fs = load_frame(stage, f, camera=camera, resolution=resolution)
            if bridge is None:
                bridge = SceneBridge(core)
            try:
                scene = bridge.update(fs) if fs.camera is not None else None
            except (core.SceneError, BridgeError) as exc:
                bridge = None                   # its scene is half updated: start again
                raise RenderError(f"frame {f:g}: {exc}") from None
        except (UsdLoadError, ColorError) as exc:
            err = RenderError(f"frame {f:g}: {exc}")
            if not skip_bad:
                raise err from None
            first_error = first_error or err
            continue
        except RenderError as err:
            if not skip_bad:
                raise
            first_error = first_error or err
            continue
        if memory is not None:
            memory[f] = scene_memory(core, scene)
        fe = analyse_frame(fs, scene, core=core, resolution=resolution)
        if cache is not None:
            cache[f] = fe
        out.append(fe)
    if not out and first_error is not None:
        raise first_error
    return out


def auto_frames(info, frames: Sequence[float]) -> List[float]:
    """The frames ``auto`` decides from: the stage's first, middle and last time codes
    when it authors a range, else those of ``frames``."""
    if info is not None and getattr(info, "has_authored_time_range", False):
        return sample_frames(frames, info.start, info.end)
    return sample_frames(frames)


def resolve_auto(stage, info, core, frames: Sequence[float], camera: Optional[str] = None,
                 resolution=None, cache: Optional[Dict[float, FrameEffects]] = None,
                 skip_bad: bool = False) -> AutoChoice:
    """The integrator ``auto`` means for this shot (:mod:`cmlt.analysis.auto`), from the
    frames :func:`auto_frames` picks (``skip_bad``: those of them that load)."""
    picks = auto_frames(info, frames)
    return choose_integrator(analyse_frames(stage, picks, core, camera, resolution, cache,
                                            skip_bad=skip_bad))


def resolve_auto_setting(stage, info, core, frame_list: Sequence[float], opts, resolved,
                         sources, cache: Dict[float, FrameEffects]) -> Optional[AutoChoice]:
    """``--integrator auto`` in the frame loop: the integrator for the whole shot written
    into ``resolved`` and ``sources`` (``auto (<where auto came from>): <reason>``); the
    AutoChoice, or None when the integrator is not auto. ``frame_list``: the frames to
    render (time codes); ``opts.camera`` already checked."""
    if str(resolved.integrator) != "auto":
        return None
    auto = resolve_auto(stage, info, core, frame_list, opts.camera, opts.resolution, cache,
                        skip_bad=True)
    sources["integrator"] = f"auto ({sources.get('integrator', 'default')}): {auto.reason}"
    resolved.integrator = auto.name
    return auto


#: the auto integrator's rules under which a Metropolis frame without chains is rendered
#: by BDPT (chainless_integrator auto). Indirect hot spots only — the rule that decides
#: only where visibility is not hard (the auto rule checks hard visibility first: door_ajar
#: has hot spots by the same measure, 269 at its slit frame, but hard visibility decides
#: it), i.e. light that is easy to reach but lights the frame through bright patches. At
#: equal time (64x64, 2 s, 2 threads, 3 seeds; tests/bench/results/chainless_integrator.md)
#: BDPT had 2.3x less error than the path-traced direct pass on camera_pan and 3.4x on
#: hard/tiny_sphere_light; under hard visibility it had 1.3x less on hard/slit but 1.0x
#: and 1.6x more on door_ajar's frames 1 and 12, so those frames stay path traced.
CHAINLESS_BDPT_RULES = ("hot_spots",)


def chainless_choice(auto: AutoChoice) -> Tuple[str, str]:
    """(integrator, reason) of chainless_integrator auto from the shot's auto choice."""
    if auto.name == "bdpt" and auto.rule in CHAINLESS_BDPT_RULES:
        return "bdpt", auto.reason
    if auto.name == "bdpt":
        return "pt", f"the path-traced direct pass (the auto integrator's rule '{auto.rule}' " \
                     f"does not move frames without chains to bdpt: {auto.reason})"
    return "pt", auto.reason


def resolve_chainless_setting(stage, info, core, frame_list: Sequence[float], opts, resolved,
                              sources, cache: Dict[float, FrameEffects]) -> Optional[AutoChoice]:
    """``--chainless-integrator auto`` for pssmlt/cmlt: what renders the shot's frames
    that have no chains (``--mlt-paths auto`` on a frame without near-specular materials,
    or ``none``) — ``bdpt`` where the shot's auto integrator (:mod:`cmlt.analysis.auto`,
    the same analysed frames as ``--integrator auto``) picks BDPT for indirect hot spots
    (CHAINLESS_BDPT_RULES), ``pt`` (the path-traced direct pass) otherwise — written into
    ``resolved`` and ``sources`` (``auto: <reason>``). Returns the AutoChoice, or None
    when nothing was resolved (not a Metropolis integrator, the setting not auto, or
    chains on every frame: mlt_paths all or caustics, or direct_fraction 0)."""
    if str(resolved.integrator) not in ("pssmlt", "cmlt") or \
            str(getattr(resolved, "chainless_integrator", "pt")) != "auto":
        return None
    paths = str(getattr(resolved, "mlt_paths", "auto"))
    if paths in ("all", "caustics") or (paths == "auto" and
                                        float(getattr(resolved, "direct_fraction", -1.0)) == 0.0):
        return None                             # every frame has chains: never read
    auto = resolve_auto(stage, info, core, frame_list, opts.camera, opts.resolution, cache,
                        skip_bad=True)
    name, reason = chainless_choice(auto)
    resolved.chainless_integrator = name
    sources["chainless_integrator"] = f"auto ({sources.get('chainless_integrator', 'default')}): " \
                                      f"{reason}"
    return auto


def frame_effects(fs, scene, core, resolution, cache: Optional[Dict[float, FrameEffects]]
                  ) -> dict:
    """The sidecar's ``effects``: what the frame calls for (cmlt.analysis.effects), from
    ``cache`` when ``auto`` already analysed the frame."""
    fe = cache.get(float(fs.time)) if cache is not None else None
    if fe is None:
        fe = analyse_frame(fs, scene, core=core, resolution=resolution)
    return fe.as_dict()


def inspect_effects(stage, info, frames_spec: Optional[str] = None, camera: Optional[str] = None,
                    resolution=None, core=None):
    """What ``cmlt inspect`` reports: (object for ``--json``, text table). The frames are
    ``frames_spec`` (a ``--frames`` spec; default: the stage's start frame, as a render);
    the ``effects`` of the object are on when they are on in any of them; the auto
    choice comes from the frames :func:`auto_frames` picks, as a render makes it."""
    from ..analysis.effects import EFFECT_NAMES, format_effects_table
    from .frames import default_frames, parse_frames

    if core is None:
        try:
            import cmlt._core as core           # noqa: F811 - lazily
        except ImportError as exc:
            raise RenderError(f"the C++ core cmlt._core is not built: {exc}") from None
    if frames_spec is None:
        frames = default_frames(info.start)
    else:
        frames = parse_frames(frames_spec, info.start, info.end, info.has_authored_time_range)
    cache: Dict[float, FrameEffects] = {}
    memory: Dict[float, dict] = {}
    per_frame = analyse_frames(stage, frames, core, camera, resolution, cache, memory=memory)
    auto = resolve_auto(stage, info, core, frames, camera, resolution, cache)
    details = {}
    for name in EFFECT_NAMES:
        fe = next((e for e in per_frame if e[name]), per_frame[0])
        details[name] = fe.as_dict()["details"][name]
    unsupported: List[str] = []
    for fe in per_frame:
        unsupported += [u for u in fe.unsupported if u not in unsupported]
    obj = {
        "shot": info.path,
        "frames": [float(f) for f in frames],
        "effects": {n: any(fe[n] for fe in per_frame) for n in EFFECT_NAMES},
        "details": details,
        "unsupported": unsupported,
        "integrator_auto": auto.as_dict(),
        "per_frame": [fe.as_dict() for fe in per_frame],
        # the scene memory of each frame inspected, and of the first one as the summary
        "memory": memory.get(float(frames[0])) if len(frames) else None,
        "memory_per_frame": [memory.get(float(f)) for f in frames],
    }
    from .memory import format_memory
    return obj, format_effects_table(per_frame, auto) + "\n" + format_memory(obj["memory"])
