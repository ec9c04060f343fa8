"""Files the stage refers to, read through USD's asset resolver (``Ar``).

A texture inside a ``.usdz`` package resolves to a *package-relative* path,
``/shots/chair.usdz[textures/wood.png]``: no file of that name exists, so
OpenImageIO cannot open it. USD itself reads layers inside packages through
``Ar``; textures go the same way here: :func:`local_path` asks
``Ar.GetResolver().OpenAsset`` for the bytes and writes them once to a
process-wide cache directory (OpenImageIO's Python API reads only from
files: the ``IOProxy`` memory reader is C++ only), under a name made from a
hash of the bytes plus the original extension (OIIO picks its reader by the
extension). The cache lives in a temporary directory removed at exit.

Plain file paths pass through unchanged, so nothing else pays for this.
"""
from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import tempfile
import threading
from typing import Dict, Optional

__all__ = ["is_package_path", "read_asset", "local_path", "AssetError"]


class AssetError(OSError):
    """An asset the resolver cannot open or read (the message names it)."""


_lock = threading.Lock()
_cache_dir: Optional[str] = None
_extracted: Dict[str, str] = {}          # resolved package path -> extracted file


def is_package_path(path: str) -> bool:
    """``pkg.usdz[inner/file.png]``: a path inside a package."""
    if not path or not path.endswith("]"):
        return False
    from pxr import Ar
    try:
        return bool(Ar.IsPackageRelativePath(path))
    except Exception:                                    # pragma: no cover
        return False


def read_asset(path: str) -> bytes:
    """The bytes of ``path`` (a resolved path; package-relative paths are read
    from inside their package) through ``Ar``. Raises :class:`AssetError`."""
    from pxr import Ar
    try:
        asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(path))
    except Exception as exc:                             # Tf errors from the resolver
        raise AssetError(f"{path}: the asset resolver cannot open it "
                         f"({' '.join(str(exc).split())})") from None
    if asset is None:
        raise AssetError(f"{path}: the asset resolver cannot open it (not in the package?)")
    data = asset.GetBuffer()
    if data is None or len(data) != asset.GetSize():
        raise AssetError(f"{path}: the asset resolver read {0 if data is None else len(data)} "
                         f"of {asset.GetSize()} bytes")
    return bytes(data)


def _inner_name(path: str) -> str:
    from pxr import Ar
    _, inner = Ar.SplitPackageRelativePathInner(path)
    return inner


def _dir() -> str:
    global _cache_dir
    if _cache_dir is None:
        _cache_dir = tempfile.mkdtemp(prefix="cmlt-assets-")
        atexit.register(shutil.rmtree, _cache_dir, True)
    return _cache_dir


def local_path(path: str) -> str:
    """A file OpenImageIO can open for ``path``: ``path`` itself unless it lies
    inside a package; then the package member extracted (once per process)
    to the cache directory. Raises :class:`AssetError` naming ``path``."""
    if not is_package_path(path):
        return path
    with _lock:
        hit = _extracted.get(path)
        if hit is not None and os.path.isfile(hit):
            return hit
        data = read_asset(path)
        ext = os.path.splitext(_inner_name(path))[1].lower()
        name = hashlib.sha1(data).hexdigest() + ext
        out = os.path.join(_dir(), name)
        if not os.path.isfile(out):
            tmp = out + ".part"
            with open(tmp, "wb") as f:
                f.write(data)
            os.replace(tmp, out)                         # never a half-written file
        _extracted[path] = out
        return out
