"""Flicker and error metrics of DESIGN.md §4.

Notation: ``I_f`` the rendered frame f, ``R_f`` its reference, ``E_f = I_f − R_f``;
``mean_px`` averages over all pixels **and** the three channels.

With a reference (one image for every frame of a static shot, or one per frame):

* ``relMSE_f = mean_px (I_f − R_f)² / (R_f² + 1e-2)`` (per channel, then averaged);
* temporal flicker ``TF = mean_f mean_px |E_{f+1} − E_f| / mean_px R``, where
  ``mean_px R`` is the mean of the reference over all its frames (one number
  for the sequence, so TF is a plain average of the per-transition terms
  ``dE_f = mean_px |E_f − E_{f−1}| / mean_px R`` reported per frame);
* global flicker ``GF = std_f(mean_px I_f / mean_px R_f)``, the **population**
  standard deviation (``ddof = 0``) over frames.

Without a reference (frame-difference mode, meaningful for a static shot,
whose true image is constant, so any change is flicker):

* ``TF = mean_f mean_px |I_{f+1} − I_f| / mean_px I`` (``mean_px I`` over all frames);
* ``GF = std_f(mean_px I_f / mean_px I)``, population std, i.e. the brightness
  of each frame relative to the sequence's mean brightness.

TF needs two frames; with one it is ``None``.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from .sequence import MetricsError

__all__ = ["FlickerReport", "FrameDifferenceFlicker", "flicker", "compare", "rel_mse",
           "REL_MSE_EPS", "motion_compensated_tf", "motion_compensated_terms",
           "reference_floor"]

#: the ε of relMSE's denominator, R² + ε
REL_MSE_EPS = 1e-2


def _as_image(img, what: str) -> np.ndarray:
    a = np.asarray(img, dtype=np.float64)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1:
        raise MetricsError(f"{what}: an image must be (H, W) or (H, W, C), got shape {np.shape(img)}")
    if a.shape[2] == 4:                     # RGBA: drop alpha
        a = a[:, :, :3]
    if not np.isfinite(a).all():
        raise MetricsError(f"{what}: non-finite pixel values")
    return a


def _as_stack(images, what: str) -> np.ndarray:
    if isinstance(images, np.ndarray) and images.ndim == 4:
        seq = [images[i] for i in range(images.shape[0])]
    else:
        seq = list(images)
    if not seq:
        raise MetricsError(f"{what}: no images")
    out = [_as_image(im, f"{what} image {i}") for i, im in enumerate(seq)]
    for i, im in enumerate(out[1:], 1):
        if im.shape != out[0].shape:
            raise MetricsError(f"{what}: image {i} has shape {im.shape} but image 0 has "
                               f"{out[0].shape}")
    return np.stack(out)


def rel_mse(image, reference) -> float:
    """``mean_px (I − R)² / (R² + 1e-2)``."""
    i, r = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    return float(np.mean((i - r) ** 2 / (r * r + REL_MSE_EPS)))


@dataclass
class FlickerReport:
    """Per-frame values (lists over ``frames``) and the summary numbers.

    ``delta[0]`` is ``None``; ``delta[f]`` is the frame's change from the
    previous one (``mean_px |E_f − E_{f−1}|`` or ``|I_f − I_{f−1}|``, divided by
    ``normaliser``), whose mean over frames is ``tf``. ``ratio[f]`` is
    ``mean I_f / mean R_f`` (reference mode) or ``mean I_f / mean I``
    (frame-difference mode); ``gf`` is its population std.
    """

    mode: str                                   # 'reference' | 'frame-difference'
    frames: List[float]
    mean: List[float]                           # mean_px I_f
    ratio: List[Optional[float]]
    delta: List[Optional[float]]
    tf: Optional[float]
    gf: Optional[float]
    normaliser: float                           # mean_px R (all frames), or mean_px I
    reference_mean: Optional[List[float]] = None   # mean_px R_f
    rel_mse: Optional[List[float]] = None
    mean_rel_mse: Optional[float] = None
    static_reference: bool = False              # one reference image for every frame
    size: tuple = (0, 0)                        # (width, height)
    std_convention: str = "population (ddof=0)"
    warnings: List[str] = field(default_factory=list)

    def to_dict(self) -> Dict[str, Any]:
        d = asdict(self)
        d["size"] = list(self.size)
        return _finite_or_none(d)

    def to_json(self, **kw) -> str:
        return json.dumps(self.to_dict(), indent=kw.pop("indent", 2), **kw)


def _finite_or_none(x):
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite_or_none(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


def flicker(images, reference=None, frames: Optional[Sequence[float]] = None) -> FlickerReport:
    """Flicker metrics of a sequence (see the module doc).

    ``images``: a list of ``(H, W[, C])`` arrays or one ``(F, H, W, C)`` array.
    ``reference``: ``None`` (frame-difference mode), one image (used for
    every frame: a static shot), or a sequence with one image per frame.
    ``frames``: frame numbers for the report (default 1..F).
    """
    I = _as_stack(images, "images")
    n = I.shape[0]
    if frames is None:
        frames = [float(i + 1) for i in range(n)]
    frames = [float(f) for f in frames]
    if len(frames) != n:
        raise MetricsError(f"{len(frames)} frame numbers for {n} images")
    size = (int(I.shape[2]), int(I.shape[1]))
    means = I.mean(axis=(1, 2, 3))
    warnings: List[str] = []

    if reference is None:
        norm = float(means.mean())
        if norm <= 0:
            raise MetricsError("the sequence is black (mean 0): frame differences cannot "
                               "be normalised")
        ratio = means / norm
        delta = [None] + [float(np.mean(np.abs(I[k + 1] - I[k])) / norm) for k in range(n - 1)]
        tf = float(np.mean(delta[1:])) if n > 1 else None
        return FlickerReport(mode="frame-difference", frames=frames, mean=means.tolist(),
                             ratio=ratio.tolist(), delta=delta, tf=tf,
                             gf=float(np.std(ratio)), normaliser=norm, size=size,
                             warnings=warnings)

    static = isinstance(reference, np.ndarray) and reference.ndim in (2, 3)
    if static:
        R1 = _as_image(reference, "reference")
        R = None
    else:
        Rs = _as_stack(reference, "reference")
        if Rs.shape[0] == 1:
            static, R1, R = True, Rs[0], None
        elif Rs.shape[0] != n:
            raise MetricsError(f"{n} images but {Rs.shape[0]} reference images")
        else:
            R = Rs
    ref_shape = (R1 if static else R[0]).shape
    if ref_shape[:2] != I.shape[1:3]:
        raise MetricsError(f"images are {size[0]}x{size[1]} but the reference is "
                           f"{ref_shape[1]}x{ref_shape[0]}")
    if ref_shape[2] != I.shape[3]:
        raise MetricsError(f"images have {I.shape[3]} channel(s) but the reference has "
                           f"{ref_shape[2]}")

    def ref(k):
        return R1 if static else R[k]

    ref_means = np.array([float(ref(k).mean()) for k in range(n)])
    norm = float(ref_means.mean())
    if norm <= 0:
        raise MetricsError("the reference is black (mean 0): flicker cannot be normalised")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(ref_means > 0, means / np.where(ref_means > 0, ref_means, 1.0), np.nan)
    if np.isnan(ratio).any():
        black = [f"{frames[k]:g}" for k in np.flatnonzero(np.isnan(ratio))]
        warnings.append(f"reference black at frame(s) {', '.join(black)}: ratio undefined, "
                        "left out of GF")
    gf = float(np.nanstd(ratio)) if np.isfinite(ratio).any() else None
    rel = [rel_mse(I[k], ref(k)) for k in range(n)]
    delta: List[Optional[float]] = [None]
    for k in range(n - 1):
        e0 = I[k] - ref(k)
        e1 = I[k + 1] - ref(k + 1)
        delta.append(float(np.mean(np.abs(e1 - e0)) / norm))
    tf = float(np.mean(delta[1:])) if n > 1 else None
    return FlickerReport(mode="reference", frames=frames, mean=means.tolist(),
                         ratio=[None if not math.isfinite(v) else float(v) for v in ratio],
                         delta=delta, tf=tf, gf=gf, normaliser=norm,
                         reference_mean=ref_means.tolist(), rel_mse=rel,
                         mean_rel_mse=float(np.mean(rel)), static_reference=static,
                         size=size, warnings=warnings)


def reference_floor(reference, second,
                    frames: Optional[Sequence[float]] = None) -> Dict[str, Optional[float]]:
    """The TF and GF a reference's own noise puts under every measurement against it,
    from a second reference rendered the same way with another seed: E = I - R carries
    R's error, and the two references' difference has twice the variance of one
    reference's error, so the pair's TF and GF divided by sqrt(2). One image for every
    frame (a static reference) has no frame-to-frame error: floor 0."""
    def single(x) -> bool:          # one image, not a list or an (F, H, W, C) stack
        return not isinstance(x, (list, tuple)) and np.ndim(x) != 4

    n = len(frames) if frames is not None else max(
        1 if single(x) else len(x) for x in (reference, second))
    a = [reference] * n if single(reference) else reference
    b = [second] * n if single(second) else second
    pair = flicker(a, b, frames=frames)
    scale = 1.0 / math.sqrt(2.0)
    return {"tf": None if pair.tf is None else pair.tf * scale,
            "gf": None if pair.gf is None else pair.gf * scale}


class FrameDifferenceFlicker:
    """The no-reference flicker of :func:`flicker` (frame-difference mode),
    accumulated one frame at a time, so that a renderer can measure it
    without keeping every frame: only the previous image is held.

    ``add(image, follows=True)``: ``follows`` says the image is the frame
    right after the previous one added (a pair ``|I_{f+1} − I_f|`` is
    measured only then; a gap, e.g. frames skipped by ``--resume``, starts a
    new run). ``tf`` is ``mean_pairs mean_px |I_{f+1} − I_f| / mean_px I``
    (``mean_px I`` over every frame added), ``gf`` the population std of
    ``mean_px I_f / mean_px I``: the same numbers :func:`flicker` gives for
    an unbroken run. ``tf`` is ``None`` without a pair, and both are
    ``None`` for a black sequence.
    """

    def __init__(self):
        self._prev: Optional[np.ndarray] = None
        self._means: List[float] = []
        self._deltas: List[float] = []
        self._shape = None

    def add(self, image, follows: bool = True) -> None:
        a = _as_image(image, "flicker: image")
        if self._shape is not None and a.shape != self._shape:
            follows = False                     # another resolution: not comparable
        if follows and self._prev is not None:
            self._deltas.append(float(np.mean(np.abs(a - self._prev))))
        self._means.append(float(a.mean()))
        self._prev = a
        self._shape = a.shape

    @property
    def frames(self) -> int:
        return len(self._means)

    @property
    def pairs(self) -> int:
        return len(self._deltas)

    @property
    def normaliser(self) -> float:
        return float(np.mean(self._means)) if self._means else 0.0

    @property
    def tf(self) -> Optional[float]:
        norm = self.normaliser
        if not self._deltas or not norm > 0:
            return None
        return float(np.mean(self._deltas)) / norm

    @property
    def gf(self) -> Optional[float]:
        norm = self.normaliser
        if not self._means or not norm > 0:
            return None
        return float(np.std(np.asarray(self._means) / norm))

    def as_dict(self) -> Dict[str, Any]:
        """``flicker`` (TF), ``global_flicker`` (GF), ``flicker_pairs``,
        ``flicker_measure`` (what the numbers are)."""
        return {"flicker": self.tf, "global_flicker": self.gf if self.pairs else None,
                "flicker_pairs": self.pairs,
                "flicker_measure": "frame-difference (no reference): "
                                   "mean |I_f+1 - I_f| / mean I"}


def compare(a, b) -> Dict[str, float]:
    """Compare image ``a`` with reference ``b`` (arrays or file paths).

    Returns ``rel_mse`` (``mean (a−b)²/(b²+1e-2)``), ``rmse``, ``mean_ratio``
    (``mean a / mean b``; NaN if b is black), ``max_abs_diff`` and ``psnr``
    in dB with the peak taken as ``max(b)`` (HDR images have no fixed white;
    ``inf`` for identical images).
    """
    from .sequence import load_image

    names = []
    arrs = []
    for x, label in ((a, "a"), (b, "b")):
        if isinstance(x, (str, bytes)) or hasattr(x, "__fspath__"):
            import os
            names.append(os.fspath(x))
            arrs.append(load_image(os.fspath(x)))
        else:
            names.append(label)
            arrs.append(_as_image(x, label))
    A, B = arrs
    if A.shape != B.shape:
        raise MetricsError(f"{names[0]} is {A.shape[1]}x{A.shape[0]}x{A.shape[2]} but "
                           f"{names[1]} is {B.shape[1]}x{B.shape[0]}x{B.shape[2]}")
    diff = A - B
    mse = float(np.mean(diff * diff))
    peak = float(B.max())
    mb = float(B.mean())
    if mse == 0:
        psnr = math.inf
    elif peak <= 0:
        psnr = math.nan
    else:
        psnr = 10.0 * math.log10(peak * peak / mse)
    return {
        "rel_mse": rel_mse(A, B),
        "rmse": math.sqrt(mse),
        "mean_ratio": float(A.mean()) / mb if mb != 0 else math.nan,
        "max_abs_diff": float(np.abs(diff).max()),
        "psnr": psnr,
        "mean_a": float(A.mean()),
        "mean_b": mb,
        "width": int(A.shape[1]),
        "height": int(A.shape[0]),
    }


def motion_compensated_terms(images, refs, flow) -> List[float]:
    """Per frame pair k: mean |E_{k+1}(p') − E_k(p)| / mean R over the pixels p whose
    surface point p' (``flow[k]``: raster positions in frame k+1, NaN where nothing was
    hit) stays in the image, E = I − R. Without references (``refs`` None) E = I and
    the normaliser is mean I (the frame-difference measure along the motion)."""
    I = np.asarray(images, np.float64)
    if refs is None:
        E, norm = I, float(I.mean())
    else:
        R = np.asarray(refs, np.float64)
        E, norm = I - R, float(R.mean())
    H, W = E.shape[1:3]
    terms = []
    for k, fl in enumerate(flow):
        x = np.floor(fl[..., 0])
        y = np.floor(fl[..., 1])
        ok = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x < W) & (y >= 0) & (y < H)
        yy, xx = np.nonzero(ok)
        d = np.abs(E[k + 1][y[ok].astype(int), x[ok].astype(int)] - E[k][yy, xx])
        terms.append(float(d.mean()) / norm if d.size and norm > 0 else math.nan)
    return terms


def motion_compensated_tf(images, refs, flow) -> float:
    """TF with the error of frame f compared to frame f+1's error where that surface
    point went (nearest pixel): the mean of :func:`motion_compensated_terms`. On a
    static shot it is TF."""
    terms = [t for t in motion_compensated_terms(images, refs, flow) if math.isfinite(t)]
    return float(np.mean(terms)) if terms else math.nan
