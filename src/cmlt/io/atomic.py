"""Atomic file writes: write to a hidden temporary name in the target's own
directory, then ``os.replace`` it over the final name.

``os.replace`` is atomic on POSIX when both names are on one file system,
which a sibling temporary guarantees. So a reader (or ``--resume``) sees
either the old complete file or the new complete file, never a torn one, and
an interrupted or failed write leaves the previous file untouched.

A process killed mid-write (SIGKILL, power loss) cannot remove its temporary:
:func:`remove_stale_temps` does, on the next run in that directory. It removes
only names of this module's pattern whose writer is gone: written on this host
(the host is in the name: a render farm shares directories between machines,
whose process ids mean nothing here) by a process id that is no longer alive.
"""
from __future__ import annotations

import contextlib
import os
import re
import socket
import stat
import time
from typing import Iterator, List, Optional, Sequence, Tuple

__all__ = ["temp_name", "atomic_path", "staged_paths", "atomic_write_text", "TEMP_MARKER",
           "parse_temp_name", "remove_stale_temps"]

#: every temporary name contains this (tests and cleanup look for it)
TEMP_MARKER = ".tmp-"
#: a temporary name without a host (written before the host was part of it) is
#: stale only if also this old: its writer may have run on another machine
LEGACY_TEMP_AGE_S = 3600.0

_TEMP = re.compile(r"^\.(?P<stem>.+)" + re.escape(TEMP_MARKER)
                   + r"(?:(?P<host>[A-Za-z0-9_]+)-)?(?P<pid>\d+)(?P<ext>\.[^.]*)?\Z")


def _host() -> str:
    """This machine's name as it goes into temporary names: letters, digits
    and ``_`` only (so that ``-<pid>`` stays unambiguous), at most 32."""
    try:
        name = socket.gethostname()
    except OSError:                                 # pragma: no cover
        name = ""
    return (re.sub(r"[^A-Za-z0-9]", "_", name)[:32]) or "localhost"


def temp_name(path: str) -> str:
    """``dir/name.ext`` -> ``dir/.name.tmp-<host>-<pid>.ext``.

    The extension is kept so that writers choosing a format by extension
    (OpenImageIO) still see ``.exr``.
    """
    head, tail = os.path.split(path)
    stem, ext = os.path.splitext(tail)
    return os.path.join(head, f".{stem}{TEMP_MARKER}{_host()}-{os.getpid()}{ext}")


def parse_temp_name(name: str) -> Optional[Tuple[Optional[str], int]]:
    """``(host, pid)`` of a file name :func:`temp_name` made (host ``None``
    for the older ``.name.tmp-<pid>.ext``), else ``None``."""
    m = _TEMP.match(os.path.basename(name))
    if not m:
        return None
    return m.group("host"), int(m.group("pid"))


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:                         # alive, someone else's
        return True
    except OSError:                                 # pragma: no cover
        return True
    return True


def remove_stale_temps(directory: str) -> List[str]:
    """Remove the temporaries of dead writers in ``directory`` (not its
    subdirectories); returns the paths removed.

    A file is removed only if its name is one :func:`temp_name` makes, it is a
    regular file, and its writer is gone: this host's name and a process id
    that is not alive (nor this process's). A name without a host must also
    be older than :data:`LEGACY_TEMP_AGE_S`. Anything else is left alone.
    """
    removed: List[str] = []
    try:
        names = os.listdir(directory or ".")
    except OSError:
        return removed
    host, me, now = _host(), os.getpid(), time.time()
    for name in names:
        parsed = parse_temp_name(name)
        if parsed is None:
            continue
        owner, pid = parsed
        if pid == me or (owner is not None and owner != host):
            continue
        path = os.path.join(directory, name)
        try:
            st = os.lstat(path)
        except OSError:
            continue
        if not stat.S_ISREG(st.st_mode):
            continue
        if owner is None and now - st.st_mtime < LEGACY_TEMP_AGE_S:
            continue
        if _pid_alive(pid):
            continue
        with contextlib.suppress(OSError):
            os.remove(path)
            removed.append(path)
    return removed


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


@contextlib.contextmanager
def staged_paths(paths: Sequence[str]) -> Iterator[List[str]]:
    """:func:`atomic_path` for several files that belong together (a frame's
    preview, state, sidecar and image): yields their temporary paths; once the
    block has written all of them, renames them into place in the order given
    (the last one last). On any exception in the block every temporary is
    removed and no final name is touched. (The renames themselves are not one
    atomic step: a failing rename, e.g. a full directory inode table, leaves
    the earlier ones done and removes the rest.)"""
    tmps = []
    for path in paths:
        directory = os.path.dirname(path)
        if directory:
            os.makedirs(directory, exist_ok=True)
        tmps.append(temp_name(path))
    try:
        yield list(tmps)
        for tmp, path in zip(tmps, paths):
            os.replace(tmp, path)
    except BaseException:
        for tmp in tmps:
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
