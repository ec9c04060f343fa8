"""What a frame writes besides its beauty: the output colour space, the AOV
channels and the ``cmlt:*`` EXR header attributes."""
from __future__ import annotations

import math
import time
from typing import Dict, Optional

import numpy as np

from .._version import __version__
from .errors import RenderError, UsageError

__all__ = ["color_setup", "to_output", "aov_images", "header_metadata", "stage_product",
           "product_channels"]


def color_setup(opts, stage):
    """Install ``--ocio-config`` and check ``--output-colorspace`` before any
    frame renders; returns (EXR header attributes, resolved colour space)."""
    from ..color import ColorError, get_config, header_attributes, load_config, set_config
    from ..color.config import current_config

    # One config for the whole shot, installed before any frame is loaded (the
    # reader converts authored colours to ACEScg with it): --ocio-config, else
    # $OCIO, else the stage's colorConfiguration, else the built-in config.
    try:
        cfg = load_config(opts.ocio_config, stage=stage, rendering_space=opts.rendering_space)
    except ColorError as exc:
        if opts.rendering_space and str(exc).startswith("rendering space"):
            raise UsageError(f"--rendering-space {opts.rendering_space!r}: {exc}") from None
        if opts.ocio_config:
            raise UsageError(f"--ocio-config {opts.ocio_config}: {exc}") from None
        raise RenderError(str(exc)) from None
    current = current_config()  # None: nothing loaded yet (not loaded here only to compare)
    if current is None or (current.location, current.source, current.rendering_space) != \
            (cfg.location, cfg.source, cfg.rendering_space):
        set_config(cfg)         # keep the current one (and its processor cache) if the same
    try:
        attrs = header_attributes(opts.output_colorspace)
        name = get_config().output_colorspace_name(opts.output_colorspace)
    except ColorError as exc:
        raise UsageError(f"--output-colorspace {opts.output_colorspace!r}: {exc}") from None
    display = view = None
    if opts.preview:
        try:
            display, view = get_config().check_display_view(opts.display, opts.view)
        except ColorError as exc:
            flag = (f"--display {opts.display!r}" if str(exc).startswith("unknown display")
                    else f"--view {opts.view!r}")
            raise UsageError(f"{flag}: {exc}") from None
    return attrs, name, display, view


def to_output(image, output_colorspace):
    if output_colorspace is None:
        return image
    from ..color import from_rendering_space
    return from_rendering_space(np.array(image, dtype=np.float32, copy=True), output_colorspace)


def stage_product(stage, opts, out):
    """The stage's render product (:mod:`cmlt.usd.render_products`) for this
    render, or None: its layers choose the EXR's channels unless ``--aov`` was
    given, its productName the output pattern unless ``out`` (``--out``) was."""
    from ..usd import UsdLoadError
    from ..usd.render_products import read_render_product
    from ..usd.render_settings import find_settings_prim

    try:
        product = read_render_product(stage, find_settings_prim(stage))
    except UsdLoadError as exc:
        raise RenderError(str(exc)) from None
    if product is None:
        return None
    if opts.aovs:
        product.layers = []             # the flags choose the channels
    if out:
        product.product_name = ""       # and the path
    return product


def product_channels(images: Dict[str, np.ndarray], layers):
    """The AOV images of a frame rearranged as a render product's layers:
    ``(aovs, layout, half_channels)`` for :func:`cmlt.io.exr.write_exr`
    (``images`` keyed by AOV name, as :func:`aov_images` returns them)."""
    if not layers:
        return images, None, ()
    aovs, layout, halfs = {}, {}, []
    for layer in layers:
        key = layer.channels()[0] if layer.suffixes is None else layer.name
        aovs[key] = images[layer.aov]
        layout[key] = (layer.name, layer.suffixes)
        if layer.half:
            halfs += layer.channels()
    return aovs, layout, tuple(halfs)


def aov_images(core, scene, st, r, aovs, opts,
                stats: dict) -> Dict[str, np.ndarray]:
    """The requested AOVs of one frame, by name (see cmlt.io.exr.AOV_CHANNELS).

    albedo, normal, depth come from the core's integrator-independent AOV
    pass (``core.render_aovs``; first hits of ``aov_samples`` camera rays per
    pixel, the beauty's jitter); albedo is a colour and is written in the
    output colour space like the beauty. variance is the render's per-pixel
    variance of the mean, in the rendering space (ACEScg) whatever
    ``--output-colorspace`` says.
    """
    out: Dict[str, np.ndarray] = {}
    if any(a in aovs for a in ("albedo", "normal", "depth")):
        t = time.perf_counter()
        a = core.render_aovs(scene, st, samples=int(opts.aov_samples))
        stats["aov_time_s"] = time.perf_counter() - t
        if "albedo" in aovs:
            out["albedo"] = to_output(np.asarray(a["albedo"]), opts.output_colorspace)
        if "normal" in aovs:
            out["normal"] = np.asarray(a["N"])
        if "depth" in aovs:
            out["depth"] = np.asarray(a["Z"])
    if "variance" in aovs:
        out["variance"] = np.asarray(r.variance)
    if "error" in aovs:                 # the per-pixel relMSE estimate (cmlt.metrics.error_estimate)
        from ..metrics.error_estimate import estimate_render
        out["error"] = estimate_render(r, stats, keep_pixels=True)[0].pixel.astype(np.float32)
    return {name: out[name] for name in aovs}


def _rendering_space() -> str:
    from ..color import get_config
    return get_config().rendering_space


#: RenderResult.stats keys (MLT integrators) -> cmlt:* header attribute names:
#: normalisation (b) estimates and mutation counts, written when present
_MLT_STATS = {
    "b": "b", "b_stderr": "bStderr", "b_bootstrap": "bBootstrap",
    "b_bootstrap_stderr": "bBootstrapStderr", "bootstrap_samples": "bootstrapSamples",
    "chains": "chains", "mutations": "mutations", "mutations_per_pixel": "mutationsPerPixel",
    "acceptance": "acceptance",
}


#: temporal normalisation record (TemporalDriver.finish) -> cmlt:* header attribute names
_TEMPORAL_RECORD = {
    "b_used": "bUsed", "b_boot": "bFresh", "b_ratio": "bRatio", "b_combined": "bCombined",
    "b_smoothed": "bSmoothed", "change_detected": "changeDetected",
}


def header_metadata(frame, fs, shot_abs: str, camera, resolved, stats: dict,
                     temporal: Optional[dict] = None) -> Dict[str, object]:
    """``cmlt:*`` EXR header attributes of one frame: frame, time code,
    shot, camera, integrator and its parameters, seed, samples / mutations,
    render time, b estimates (when the integrator reports them), version.

    ``temporal``: the frame's temporal record (:meth:`TemporalDriver.finish`).
    When it holds a normalisation (MLT integrators), ``cmlt:b`` is the b the
    image was normalised with (``b_used``: smoothed over frames unless
    ``--no-smoothing``; it scales the chains' part, the direct pass being plain
    Monte Carlo), the core's own estimate is ``cmlt:bCore``, and the
    record goes in as ``cmlt:bUsed``, ``bFresh``, ``bRatio``, ``bCombined``,
    ``bSmoothed``, ``changeDetected``; an estimate that does not exist for
    the frame (NaN, e.g. ``b_ratio`` without carried states) is left out.
    """
    params = {k: v for k, v in resolved.as_dict().items() if k not in ("camera", "resolution")}
    md: Dict[str, object] = {
        "frame": float(frame), "timeCode": float(fs.time), "shot": shot_abs,
        "camera": camera or "", "integrator": resolved.integrator,
        "integratorParameters": params,               # JSON text
        "spp": int(resolved.spp), "maxDepth": int(resolved.max_depth),
        "seed": int(resolved.seed),
        "renderingSpace": _rendering_space(),
        "renderTime": float(stats.get("time_s", stats.get("wall_time_s", 0.0))),
        "samples": int(stats.get("samples", 0)),
        "rays": int(stats.get("rays", 0)),
        "raysPerSecond": float(stats.get("rays_per_s", 0.0)),
        "pixelFilter": str(stats.get("pixel_filter", resolved.pixel_filter)),
        "filterRadius": float(stats.get("filter_radius", resolved.filter_radius)),
        "sampler": str(stats.get("sampler", "")),
        "version": __version__,
    }
    for key, name in _MLT_STATS.items():
        if key in stats and stats[key] is not None:
            md[name] = stats[key]
    from ..metrics.error_estimate import estimate_metadata
    md.update(estimate_metadata(stats.get("error_estimate")))   # relMSEEstimate, ...
    rec = temporal or {}
    if rec.get("b_used") is not None and "b" in md:
        md["bCore"] = md["b"]                   # the core's b, before temporal smoothing
        for key, name in _TEMPORAL_RECORD.items():
            value = rec.get(key)
            if isinstance(value, bool):
                md[name] = int(value)
            elif value is not None and math.isfinite(float(value)):
                md[name] = float(value)
        if "bUsed" in md:
            md["b"] = md["bUsed"]               # the b the image was normalised with
    return md
