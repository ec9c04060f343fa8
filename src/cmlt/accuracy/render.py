"""One frame of a shot in the core, rendered again and again: to a time budget or a
sample budget, with any integrator and seed, and its converged reference (cached).

The scene is built once per frame (not timed); each render is timed around
``core.render`` alone. Settings: the stage's (``cmlt:*`` on its render settings prim,
e.g. ``maxDepth``) with the integrator, budget, seed and resolution replaced, and an
integrator spec's own overrides on top (``cmlt:tries=4:inner_length=2``).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

__all__ = ["AccuracyError", "IntegratorSpec", "parse_integrator", "ShotFrame", "RenderRun",
           "CmltRenderer", "Reference", "render_reference", "halves_floor", "load_reference", "stage_start",
           "TIME_BUDGET_SPP_CAP", "INTEGRATORS"]

#: the sample budget of a render to a time budget (a cap it never reaches)
TIME_BUDGET_SPP_CAP = 1 << 24
#: cmlt's integrators
INTEGRATORS = ("pt", "bdpt", "pssmlt", "cmlt")
#: the fields a spec may not set (the accuracy sweep owns them)
_OWNED = ("integrator", "spp", "time_budget", "seed", "threads", "width", "height")


class AccuracyError(ValueError):
    """Bad input to an accuracy run (a flag, a spec, a reference file); the message
    names it."""


@dataclass(frozen=True)
class IntegratorSpec:
    """``name[:field=value...]``, e.g. ``cmlt:tries=4:inner_length=2``."""

    text: str
    name: str
    overrides: Tuple[Tuple[str, Any], ...] = ()

    def __str__(self) -> str:
        return self.text


def parse_integrator(text: str, core=None) -> IntegratorSpec:
    """Parse an integrator spec; values take the type of the core's RenderSettings
    field (bool: 1/0, true/false). Raises AccuracyError naming the spec."""
    if core is None:
        import cmlt._core as core
    name, _, opts = text.strip().partition(":")
    if name not in INTEGRATORS:
        raise AccuracyError(f"integrator {text!r}: unknown integrator {name!r}; choose from "
                            f"{', '.join(INTEGRATORS)}")
    defaults = core.RenderSettings()
    out = []
    for kv in [x for x in opts.split(":") if x]:
        key, eq, value = kv.partition("=")
        if not eq:
            raise AccuracyError(f"integrator {text!r}: {kv!r} is not field=value")
        if key in _OWNED:
            raise AccuracyError(f"integrator {text!r}: {key} is set by the accuracy run itself")
        if not hasattr(defaults, key):
            raise AccuracyError(f"integrator {text!r}: the core has no setting {key!r}")
        default = getattr(defaults, key)
        try:
            if isinstance(default, bool):
                if value.lower() not in ("1", "0", "true", "false"):
                    raise ValueError
                v: Any = value.lower() in ("1", "true")
            else:
                v = type(default)(value)
        except (TypeError, ValueError):
            raise AccuracyError(f"integrator {text!r}: {key}={value!r} is not a "
                                f"{type(default).__name__}") from None
        out.append((key, v))
    return IntegratorSpec(text.strip(), name, tuple(out))


def stage_start(shot: str) -> float:
    """The stage's start time code."""
    from ..usd import open_stage
    return float(open_stage(shot).GetStartTimeCode())


@dataclass
class RenderRun:
    """One timed render: the image (float64 (H, W, 3)), its per-pixel variance of the
    mean (pt, bdpt; zeros for the MLT chains), the wall time of ``core.render``, samples
    per pixel (path evaluations for pssmlt and cmlt), and the core's stats."""

    image: np.ndarray
    variance: np.ndarray
    time_s: float
    samples: float
    stats: Dict[str, Any]
    direct: Optional[np.ndarray] = None


class ShotFrame:
    """One frame of a shot, loaded into the core once and rendered many times.

    ``lambert``: make the opaque, non-metallic materials exactly Lambertian (ior 1, no
    specular layer), as the peer renderers' diffuse BSDFs (:mod:`cmlt.accuracy.peers`);
    ``peer_scene`` then holds the converted scene (taken before that change).
    """

    def __init__(self, shot: str, frame: Optional[float] = None,
                 resolution: Optional[Tuple[int, int]] = None, threads: int = 0,
                 lambert: bool = False, camera: Optional[str] = None, peer_scene: bool = False):
        import cmlt._core as core
        from ..settings import SettingsError, resolve_settings
        from ..shot.bridge import SceneBridge
        from ..usd import UsdLoadError, load_frame, open_stage

        if not os.path.exists(shot):
            raise AccuracyError(f"{shot}: no such file")
        self.core = core
        self.shot = shot
        t0 = time.perf_counter()
        try:
            self.stage = open_stage(shot)
            self.frame = float(self.stage.GetStartTimeCode()) if frame is None else float(frame)
            self.fs = load_frame(self.stage, self.frame, camera=camera, resolution=resolution)
        except UsdLoadError as exc:
            raise AccuracyError(str(exc)) from None
        try:
            resolved, _ = resolve_settings(self.stage)
        except SettingsError as exc:
            raise AccuracyError(str(exc)) from None
        self.stage_settings = {k: v for k, v in resolved.as_dict().items()
                               if k not in _OWNED + ("resolution", "camera")}
        self.peer_scene = None
        if peer_scene or lambert:
            from .peers import convert_frame
            self.peer_scene = convert_frame(self.fs, shot)
        self.lambert_materials: List[str] = []
        if lambert:
            from .peers import make_cmlt_lambert
            self.lambert_materials = make_cmlt_lambert(self.fs)
        self.lambert = bool(lambert)
        self.bridge = SceneBridge(core)
        self.scene = self.bridge.update(self.fs)
        self.setup_s = time.perf_counter() - t0
        self.resolution = (int(self.fs.resolution[0]), int(self.fs.resolution[1]))
        self.threads = int(threads)
        self.camera = camera
        self._chainless: Optional[str] = None    # chainless_integrator auto, resolved once
        self.warnings = list(self.fs.warnings)

    @property
    def name(self) -> str:
        """The shot's name: its folder for ``.../<name>/shot.usda``, else the file stem."""
        p = Path(self.shot)
        return p.parent.name if p.stem == "shot" and p.parent.name else p.stem

    @property
    def pixels(self) -> int:
        return self.resolution[0] * self.resolution[1]

    def digest(self) -> str:
        """Short hash of the stage's layers (their files' bytes) and the frame's load
        options: part of a reference's cache key, so an edited shot is not matched."""
        parts = []
        for layer in self.stage.GetUsedLayers():         # a set: sorted below
            path = layer.realPath
            if path and os.path.isfile(path):
                parts.append(os.path.basename(path).encode() + b"\0" + Path(path).read_bytes())
            else:                                        # anonymous (session) layers
                parts.append(layer.ExportToString().encode())
        h = hashlib.sha1()
        for part in sorted(parts):
            h.update(hashlib.sha1(part).digest())
        h.update(repr((self.frame, self.resolution, self.lambert,
                       sorted(self.stage_settings.items()))).encode())
        return h.hexdigest()[:10]

    def settings(self, spec: IntegratorSpec, seconds: Optional[float] = None,
                 spp: Optional[int] = None, seed: int = 0):
        """core.RenderSettings of one render: the stage's settings, then the spec's."""
        core = self.core
        st = core.RenderSettings()
        for key, value in self.stage_settings.items():
            if hasattr(st, key) and value is not None:
                setattr(st, key, value)
        st.width, st.height = self.resolution
        st.integrator = spec.name
        st.seed = int(seed)
        st.threads = self.threads
        st.spp = int(spp) if spp else TIME_BUDGET_SPP_CAP
        st.time_budget = float(seconds) if seconds else 0.0
        for key, value in spec.overrides:
            setattr(st, key, value)
        if spec.name in ("pssmlt", "cmlt") and str(st.chainless_integrator) == "auto":
            st.chainless_integrator = self.chainless_integrator()
        return st

    def chainless_integrator(self) -> str:
        """``chainless_integrator`` auto as ``cmlt render`` resolves it for this shot
        (cmlt.shot.analyse.resolve_chainless_setting: the shot's auto integrator, from
        its first, middle and last frames), so that a Metropolis integrator is measured
        as it renders."""
        if self._chainless is None:
            from ..shot.analyse import chainless_choice, resolve_auto
            from ..usd import stage_info
            auto = resolve_auto(self.stage, stage_info(self.stage), self.core, [self.frame],
                                self.camera, self.resolution, skip_bad=True)
            self._chainless = chainless_choice(auto)[0]
        return self._chainless

    def render(self, spec: IntegratorSpec, seconds: Optional[float] = None,
               spp: Optional[int] = None, seed: int = 0,
               progress: Optional[Callable[[float], None]] = None) -> RenderRun:
        """Render to ``seconds`` of wall time (the core's time budget) and/or ``spp``
        samples (path evaluations) per pixel. ``progress(fraction)`` is called between
        the core's chunks."""
        if not seconds and not spp:
            raise AccuracyError("a render needs a time budget or a sample budget")
        st = self.settings(spec, seconds, spp, seed)
        def cb(done, total):
            progress(float(done) / float(total) if total else 0.0)
            return True
        t0 = time.perf_counter()
        try:
            r = self.core.render(self.scene, st, progress=cb if progress else None)
        except self.core.SettingsError as exc:
            raise AccuracyError(f"integrator {spec}: {exc}") from None
        dt = time.perf_counter() - t0
        image = np.asarray(r.image, dtype=np.float64)
        if not np.isfinite(image).all():
            raise RuntimeError(f"{self.shot}: frame {self.frame:g}: {spec} returned "
                               f"{int((~np.isfinite(image)).sum())} non-finite pixel values")
        stats = dict(r.stats)
        evals = float(stats.get("path_evaluations", stats.get("samples", 0)))
        direct = None if r.direct is None else np.asarray(r.direct, dtype=np.float64)
        return RenderRun(image, np.asarray(r.variance, dtype=np.float64), dt,
                         evals / float(self.pixels), stats, direct)


class CmltRenderer:
    """cmlt in the driver process, with the same ``render`` as the peer renderers' handles
    (:mod:`cmlt.accuracy.peers`): a :class:`ShotFrame` that keeps the converted scene."""

    name = "cmlt"

    def __init__(self, shot_path: str, frame: float, res, lambert: bool, threads: int,
                 pixel_filter: str = "box"):
        from .._version import __version__
        self.sf = ShotFrame(shot_path, frame, res, threads, lambert=lambert, peer_scene=True)
        self.pixel_filter = pixel_filter
        self.core = self.sf.core
        self.version = __version__
        self.fs = self.sf.fs
        self.peer_scene = self.sf.peer_scene
        if self.peer_scene is not None and self.peer_scene.camera is not None:
            self.peer_scene.camera.pixel_filter = pixel_filter
        self.lambert_materials = self.sf.lambert_materials
        self.setup_s = self.sf.setup_s
        self.res = self.sf.resolution
        self.threads = threads

    def render(self, integrator: str, budget: float, seed: int) -> dict:
        from .peers import MAX_DEPTH
        spec = parse_integrator(f"{integrator}:max_depth={MAX_DEPTH}:pixel_filter={self.pixel_filter}",
                                self.core)
        c0 = time.process_time()
        run = self.sf.render(spec, seconds=budget, seed=seed)
        cpu = time.process_time() - c0
        npx = self.res[0] * self.res[1]
        return {"image": run.image, "time_s": run.time_s, "cpu_s": cpu, "setup_s": 0.0,
                "spp": run.samples, "samples_per_s": run.samples * npx / max(run.time_s, 1e-9),
                "extra": {"rays_per_s": float(run.stats.get("rays", 0)) / max(run.time_s, 1e-9)}}


# ------------------------------------------------------------------ references

@dataclass
class Reference:
    """A converged image of one frame, where it came from, and its own relMSE: the floor
    of what can be measured against it. ``relmse_floor`` is the larger of two estimates
    of it (when it has them): from its per-pixel variance, and from the difference of
    its two independent halves (``relmse_floor_halves``, :func:`halves_floor`), which
    also sees rare bright paths one half found and the other did not."""

    image: np.ndarray
    source: str                               # cache file or user file
    integrator: str = ""
    spp: int = 0
    time_s: float = math.nan
    relmse_floor: float = math.nan
    relmse_floor_stderr: float = math.nan
    cached: bool = False
    meta: Dict[str, Any] = field(default_factory=dict)
    relmse_floor_variance: float = math.nan
    relmse_floor_halves: float = math.nan

    def warning(self) -> Optional[str]:
        """A one-line warning when the halves differ by far more than the variance says
        (HALVES_WARN_RATIO): the reference has not converged where a few pixels carry
        rare bright paths, and errors below its floor mean nothing; else None."""
        v, hv = self.relmse_floor_variance, self.relmse_floor_halves
        if not (math.isfinite(v) and math.isfinite(hv)) or hv <= HALVES_WARN_RATIO * max(v, 1e-12):
            return None
        return (f"the reference's two halves differ by relMSE ~ {hv:.2g} ({hv / max(v, 1e-12):.0f}x "
                f"what its variance says): a few pixels with rare bright paths have not "
                f"converged, so errors below ~{hv:.2g} cannot be measured against it "
                f"(raise --reference-spp, or give a --reference you trust)")


#: the halves' floor beyond which a reference is reported as not converged: for a
#: reference whose per-pixel variance is right, the two estimates agree to within the
#: noise of a mean over every pixel (a few percent)
HALVES_WARN_RATIO = 3.0
#: how references are made (part of the cache key): "h2" = two independent halves
REFERENCE_METHOD = "h2"


def halves_floor(a: np.ndarray, b: np.ndarray) -> float:
    """The relMSE of the mean of two independent renders of equal budget, from their
    difference: E[(A − B)²] = 4 Var((A + B) / 2) per pixel and channel, so
    mean((A − B)² / 4 / (R² + ε)) with R = (A + B) / 2 (the relMSE's denominator,
    cmlt.metrics.flicker.REL_MSE_EPS). Unlike a render's own per-pixel variance it counts
    what one half found and the other missed."""
    from ..metrics.flicker import REL_MSE_EPS

    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    r = 0.5 * (a + b)
    return float(np.mean((a - b) ** 2 / 4.0 / (r * r + REL_MSE_EPS)))


def _reference_key(sf: ShotFrame, integrator: str, spp: int, seed: int) -> str:
    w, h = sf.resolution
    lam = "_lambert" if sf.lambert else ""
    return (f"{sf.name}_f{sf.frame:g}_{w}x{h}_{integrator}_{spp}spp_s{seed}{lam}_"
            f"{REFERENCE_METHOD}_{sf.digest()}.exr")


def render_reference(sf: ShotFrame, integrator: str = "bdpt", spp: int = 4096,
                     cache_dir: Optional[str] = None, seed: int = 12345,
                     progress: Optional[Callable[[float], None]] = None) -> Reference:
    """The frame's reference: ``integrator`` at ``spp`` samples per pixel, from
    ``cache_dir`` if rendered before (key: shot, frame, resolution, integrator, spp,
    seed, the Lambert switch, REFERENCE_METHOD and a hash of the stage's files), else
    rendered and cached there as an EXR (image + variance channels + ``cmlt:*``
    metadata). pt and bdpt references are the mean of two independent halves (seeds
    ``seed`` and ``seed + 1``), so that their floor is also estimated from the halves'
    difference (Reference.warning tells when that is far above the variance's)."""
    from ..io.exr import read_exr, write_exr
    from ..metrics.error_estimate import estimate_from_variance

    spec = parse_integrator(integrator, sf.core)
    path = None
    if cache_dir:
        path = Path(cache_dir) / _reference_key(sf, integrator, spp, seed)
        if path.exists():
            data, meta = read_exr(str(path))
            names = list(meta.get("channelnames", ()))
            img = data[..., [names.index(c) for c in ("R", "G", "B")]].astype(np.float64)
            info = json.loads(str(meta.get("cmlt:reference", "{}")))
            return Reference(img, str(path), integrator, int(spp), float(info.get("time_s", math.nan)),
                             float(info.get("relmse_floor", math.nan)),
                             float(info.get("relmse_floor_stderr", math.nan)), True, info,
                             float(info.get("relmse_floor_variance", math.nan)),
                             float(info.get("relmse_floor_halves", math.nan)))
    floor = floor_se = floor_var = floor_halves = math.nan
    if spec.name in ("pt", "bdpt") and spp >= 2:
        # two independent halves (seeds seed, seed + 1), their mean the reference
        n1 = spp // 2
        n2 = spp - n1
        def part(lo, hi):       # a half's progress as a share of the whole reference's
            return (lambda f: progress(lo + (hi - lo) * f)) if progress else None
        ra = sf.render(spec, spp=n1, seed=seed, progress=part(0.0, n1 / spp))
        rb = sf.render(spec, spp=n2, seed=seed + 1, progress=part(n1 / spp, 1.0))
        wa, wb = n1 / spp, n2 / spp
        image = wa * ra.image + wb * rb.image
        variance = wa * wa * ra.variance + wb * wb * rb.variance
        time_s = ra.time_s + rb.time_s
        est = estimate_from_variance(image, variance, passes=spp, keep_pixels=False)
        floor_var, floor_se = est.relmse, est.stderr
        floor_halves = halves_floor(ra.image, rb.image) * (4.0 * wa * wb)   # unequal halves: Var(A − B)
        floor = max(floor_var, floor_halves)
    else:
        run = sf.render(spec, spp=spp, seed=seed, progress=progress)
        image, variance, time_s = run.image, run.variance, run.time_s
        if spec.name in ("pt", "bdpt"):
            est = estimate_from_variance(image, variance, passes=int(run.stats.get("spp", 0)),
                                         keep_pixels=False)
            floor = floor_var = est.relmse
            floor_se = est.stderr
    info = {"shot": os.path.abspath(sf.shot), "frame": sf.frame, "resolution": list(sf.resolution),
            "integrator": integrator, "spp": int(spp), "seed": int(seed), "time_s": time_s,
            "relmse_floor": floor, "relmse_floor_stderr": floor_se,
            "relmse_floor_variance": floor_var, "relmse_floor_halves": floor_halves,
            "method": REFERENCE_METHOD, "lambert": sf.lambert, "digest": sf.digest()}
    ref = Reference(image, str(path) if path else "", integrator, int(spp), time_s,
                    floor, floor_se, False, info, floor_var, floor_halves)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_exr(str(path), image.astype(np.float32), colorspace="ACEScg",
                  metadata={"reference": json.dumps(info)},
                  aovs={"variance": np.asarray(variance).astype(np.float32)})
    return ref


def load_reference(path: str, sf: ShotFrame) -> Reference:
    """A user's reference image (any format OpenImageIO reads, RGB in the rendering
    space, ACEScg), checked against the frame's resolution."""
    from ..metrics import MetricsError, load_image

    try:
        img = load_image(path)
    except MetricsError as exc:
        raise AccuracyError(f"--reference {exc}") from None
    h, w = img.shape[:2]
    if (w, h) != sf.resolution:
        raise AccuracyError(f"--reference {path}: the image is {w}x{h} but the renders are "
                            f"{sf.resolution[0]}x{sf.resolution[1]} (give --res {w}x{h})")
    return Reference(img, path, meta={"file": os.path.abspath(path)})
