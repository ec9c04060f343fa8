"""Atomic file writes: write to a hidden temporary name in the target's own
directory, then ``os.replace`` it over the final name.

``os.replace`` is atomic on POSIX when both names are on one file system,
which a sibling temporary guarantees. So a reader (or ``--resume``) sees
either the old complete file or the new complete file, never a torn one, and
an interrupted or failed write leaves the previous file untouched.
"""
from __future__ import annotations

import contextlib
import os
from typing import Iterator

__all__ = ["temp_name", "atomic_path", "atomic_write_text", "TEMP_MARKER"]

#: every temporary name contains this (tests and cleanup look for it)
TEMP_MARKER = ".tmp-"


def temp_name(path: str) -> str:
    """``dir/name.ext`` -> ``dir/.name.tmp-<pid>.ext``.

    The extension is kept so that writers choosing a format by extension
    (OpenImageIO) still see ``.exr``.
    """
    head, tail = os.path.split(path)
    stem, ext = os.path.splitext(tail)
    return os.path.join(head, f".{stem}{TEMP_MARKER}{os.getpid()}{ext}")


@contextlib.contextmanager
def atomic_path(path: str) -> Iterator[str]:
    """Yield a temporary path to write; rename it to ``path`` on success.

    On any exception (including KeyboardInterrupt) the temporary is removed
    and ``path`` is left as it was.
    """
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    tmp = temp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.remove(tmp)
        raise


def atomic_write_text(path: str, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically, flushed to disk."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
