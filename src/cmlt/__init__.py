"""cmlt: Coherent Metropolis Light Transport for animated USD shots."""

# Register cmlt's USD plugins (the CmltRenderSettingsAPI schema) before
# anything imports pxr: USD sees a codeless schema only if it is registered
# before the schema registry is first used (shared/NOTES.md).
from . import _plugins

_plugins.register()

__version__ = "0.1.0"
