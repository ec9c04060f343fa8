"""cmlt: Coherent Metropolis Light Transport for animated USD shots.

``cmlt.render_sequence`` and ``cmlt.RenderOptions`` are those of
:mod:`cmlt.shot` (imported on first use).
"""

import os as _os

# One BLAS thread (unless the user chose otherwise), set before numpy is first imported:
# cmlt's numpy work is element-wise or N x 3 @ 3 x 3 (colour), which one thread does at
# memory speed, while OpenBLAS' own worker threads busy-wait after each call and so take
# cores from the renderer's threads (perf: 2 % of the samples of a `cmlt render` process
# on 2 cores were in `blas_thread_server`).
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# Register cmlt's USD plugins (the CmltRenderSettingsAPI schema) before
# anything imports pxr: USD sees a codeless schema only if it is registered
# before the schema registry is first used (shared/NOTES.md).
from . import _plugins
from ._version import __version__

_plugins.register()

# cmlt._core: the build of the core for the best instruction set this CPU runs, found
# when first imported (_core_select.py; CMLT_CORE_ISA=baseline forces the portable one).
from . import _core_select

_core_select.install()

__all__ = ["__version__", "render_sequence", "RenderOptions"]


def __getattr__(name):
    # lazily: importing cmlt must not import pxr (see above) nor the frame loop
    if name in ("render_sequence", "RenderOptions"):
        from . import shot
        return getattr(shot, name)
    raise AttributeError(f"module 'cmlt' has no attribute {name!r}")
