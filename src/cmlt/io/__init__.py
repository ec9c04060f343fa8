"""Writing frames: scene-linear OpenEXR through OpenImageIO, JSON stats
sidecars, and the atomic-rename discipline both use."""
from .atomic import atomic_path, atomic_write_text, temp_name
from .exr import ExrWriteError, read_exr, write_exr, COMPRESSIONS
from .sidecar import sidecar_path, write_sidecar, read_sidecar

__all__ = [
    "atomic_path", "atomic_write_text", "temp_name",
    "ExrWriteError", "read_exr", "write_exr", "COMPRESSIONS",
    "sidecar_path", "write_sidecar", "read_sidecar",
]
