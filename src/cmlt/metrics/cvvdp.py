"""ColorVideoVDP (Mantiuk et al. 2024) of a rendered sequence against its references:
a perceptual video difference in JOD (just-objectionable differences; 10 = no visible
difference), which sees temporal flicker as a viewer does.

Optional: it needs the ``cvvdp`` package from PyPI (``pip install cvvdp``), which pulls
PyTorch. On Linux x86-64 PyPI's PyTorch is the CUDA build: with its NVIDIA libraries
about 5.7 GB installed (measured on this project's machine: about 15 minutes to
install, 45 s to import), and PyTorch does not import without those libraries even on
a CPU. So it is not a dependency of cmlt or of ``make test``; :func:`unavailable` says
why it cannot run.

How frames are shown to the metric: scene-linear ACEScg is converted to linear Rec.709,
1.0 is taken as 100 cd/m^2 (diffuse white of an SDR grade) on cvvdp's
``standard_hdr_linear`` display (linear input in cd/m^2), and each frame is enlarged by
``upscale`` (nearest neighbour, default 4) so that a small benchmark frame (48 x 48)
covers a few degrees of visual field instead of under one.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ["CvvdpUnavailable", "unavailable", "video_jod", "ACESCG_TO_REC709"]

#: linear ACEScg (AP1, D60) -> linear Rec.709 (D65), Bradford-adapted (row-major)
ACESCG_TO_REC709 = np.array([[1.70505, -0.62179, -0.08326],
                             [-0.13026, 1.14080, -0.01055],
                             [-0.02400, -0.12897, 1.15297]])

_METRIC = {}


class CvvdpUnavailable(RuntimeError):
    """ColorVideoVDP cannot run here; the message says why."""


def unavailable() -> Optional[str]:
    """None if ColorVideoVDP can run, else the reason."""
    try:
        import pycvvdp  # noqa: F401
    except ImportError as exc:
        return ("ColorVideoVDP is not installed: `pip install cvvdp` (it pulls PyTorch; "
                "PyPI's Linux build brings its CUDA libraries, about 5.7 GB) "
                f"[{exc}]")
    except Exception as exc:                    # torch present but broken (missing CUDA libs)
        return f"ColorVideoVDP does not import: {type(exc).__name__}: {exc}"
    return None


def _metric():
    if "m" not in _METRIC:
        why = unavailable()
        if why:
            raise CvvdpUnavailable(why)
        import pycvvdp
        import torch
        _METRIC["m"] = pycvvdp.cvvdp(display_name="standard_hdr_linear", quiet=True,
                                     device=torch.device("cpu"))
    return _METRIC["m"]


def _display(frames, upscale: int, white_nits: float) -> np.ndarray:
    a = np.asarray(frames, dtype=np.float64)
    if a.ndim == 3:
        a = a[None]
    if a.ndim != 4 or a.shape[-1] < 3:
        raise ValueError(f"cvvdp: expected (F, H, W, 3) frames, got shape {a.shape}")
    rgb = np.clip(a[..., :3] @ ACESCG_TO_REC709.T, 0.0, None) * white_nits
    if upscale > 1:
        rgb = rgb.repeat(upscale, axis=1).repeat(upscale, axis=2)
    return rgb.astype(np.float32)


def video_jod(images, references, fps: float = 24.0, upscale: int = 4,
              white_nits: float = 100.0) -> float:
    """JOD of ``images`` (F, H, W, 3 scene-linear ACEScg) against ``references`` (the
    same shape) as a video at ``fps``. Raises :class:`CvvdpUnavailable`."""
    m = _metric()
    test = _display(images, upscale, white_nits)
    ref = _display(references, upscale, white_nits)
    if test.shape != ref.shape:
        raise ValueError(f"cvvdp: images {test.shape} and references {ref.shape} differ")
    import torch
    with torch.no_grad():
        jod, _ = m.predict(test, ref, dim_order="FHWC", frames_per_second=float(fps))
    return float(jod)
