"""cmlt: Coherent Metropolis Light Transport for animated USD shots.

``cmlt.render_sequence`` and ``cmlt.RenderOptions`` are those of
:mod:`cmlt.shot` (imported on first use).
"""

# Register cmlt's USD plugins (the CmltRenderSettingsAPI schema) before
# anything imports pxr: USD sees a codeless schema only if it is registered
# before the schema registry is first used (shared/NOTES.md).
from . import _plugins
from ._version import __version__

_plugins.register()

__all__ = ["__version__", "render_sequence", "RenderOptions"]


def __getattr__(name):
    # lazily: importing cmlt must not import pxr (see above) nor the frame loop
    if name in ("render_sequence", "RenderOptions"):
        from . import shot
        return getattr(shot, name)
    raise AttributeError(f"module 'cmlt' has no attribute {name!r}")
