"""USD's own diagnostics, caught and turned into cmlt warnings.

usd-core reports composition problems (an unresolved reference or payload,
a sublayer that does not open, ...) through Tf's diagnostic manager, whose
default delegate prints them straight to the process's stderr (file
descriptor 2) as, for example::

    Warning: in _ReportErrors at line 3144 of .../pxr/usd/usd/stage.cpp --
    Recomposing stage on stage @/shots/a.usda@ <0x55d0...>: Could not open asset
    @gone.usda@ for reference introduced by @/shots/a.usda@</World/Ref>.

That bypasses ``--quiet`` and ``--log-json``. usd-core's Python API has no
way to install a diagnostic delegate, so :func:`capture_usd_diagnostics`
redirects file descriptor 2 into a temporary file around the calls that
compose a stage, parses what Tf printed, and hands back one-line messages;
anything else that reached fd 2 meanwhile (not a Tf diagnostic) is written
back to the real stderr unchanged.
"""
from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import threading
from typing import Iterator, List

__all__ = ["capture_usd_diagnostics", "parse_tf_diagnostics", "tf_message"]

#: the start of a diagnostic printed by Tf's default delegate
_TF_START = re.compile(r"^(?:Warning|Error|Coding Error|Runtime Error|Fatal Error|"
                       r"Failed verification|Status)(?::| \()")
#: "Warning: in FUNC at line N of FILE -- " (the C++ source location)
_TF_LOCATION = re.compile(r"^(?P<kind>[A-Za-z ]+?)(?: \([^)]*\))?: in \S+ at line \d+ of \S+ -- ")
#: "<0x55d0c0ffee00>" (object addresses Tf puts after a stage's identifier)
_ADDRESS = re.compile(r"\s*<0x[0-9a-fA-F]+>")

_lock = threading.Lock()


def tf_message(text: str) -> str:
    """One diagnostic as one line: no C++ source location, no object
    addresses, whitespace collapsed; a kind other than Warning stays as a
    prefix (``Error: ...``)."""
    text = " ".join(str(text).split())
    m = _TF_LOCATION.match(text)
    kind = ""
    if m:
        kind = m.group("kind").strip()
        text = text[m.end():]
    elif ": " in text and _TF_START.match(text):
        kind, text = text.split(": ", 1)
    text = _ADDRESS.sub("", text).strip()
    if kind and kind.lower() != "warning":
        text = f"{kind.lower()}: {text}"
    return text


def parse_tf_diagnostics(text: str):
    """Split what Tf printed into (diagnostics, other text). A diagnostic
    starts with ``Warning:``/``Error:``/... and continues over the following
    indented lines; any other line is not USD's."""
    diags: List[str] = []
    other: List[str] = []
    current: List[str] = []

    def close():
        if current:
            msg = tf_message(" ".join(current))
            if msg and msg not in diags:
                diags.append(msg)
            current.clear()

    for line in text.splitlines():
        if _TF_START.match(line):
            close()
            current.append(line)
        elif current and line.strip() and line[:1].isspace():
            current.append(line)
        else:
            close()
            if line.strip():
                other.append(line)
    close()
    return diags, other


@contextlib.contextmanager
def capture_usd_diagnostics() -> Iterator[List[str]]:
    """``with capture_usd_diagnostics() as diags: Usd.Stage.Open(...)``:
    while the block runs, fd 2 goes to a temporary file; afterwards ``diags``
    holds Tf's diagnostics as one-line messages (see :func:`tf_message`) and
    any other output is copied back to stderr. Nested or concurrent uses
    wait for each other (fd 2 is process-wide)."""
    diags: List[str] = []
    with _lock:
        try:
            sys.stderr.flush()
        except Exception:                              # pragma: no cover
            pass
        try:
            saved = os.dup(2)
        except OSError:                                # no fd 2 at all: nothing to catch
            yield diags
            return
        tmp = tempfile.TemporaryFile(mode="w+b")
        try:
            os.dup2(tmp.fileno(), 2)
            try:
                yield diags
            finally:
                try:
                    sys.stderr.flush()
                except Exception:                      # pragma: no cover
                    pass
                os.dup2(saved, 2)
                tmp.seek(0)
                text = tmp.read().decode("utf-8", errors="replace")
                found, other = parse_tf_diagnostics(text)
                diags.extend(found)
                if other:                              # not USD's: give it back
                    try:
                        os.write(2, ("\n".join(other) + "\n").encode("utf-8", "replace"))
                    except OSError:                    # pragma: no cover
                        pass
        finally:
            os.close(saved)
            tmp.close()
