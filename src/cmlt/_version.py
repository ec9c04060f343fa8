"""The package version, from the installed distribution (pyproject.toml is the
one place it is written).

Read from the distribution's ``METADATA`` file directly: ``importlib.metadata``
imports the ``email`` package to parse it, about 35 ms of every process's start-up
(a per-frame farm job pays it every frame). Where no ``cmlt-*.dist-info`` is on
``sys.path`` (another kind of install), ``importlib.metadata`` answers.
"""
import os
import sys


def _from_dist_info():
    """The ``Version:`` of the first ``cmlt-*.dist-info`` on ``sys.path``, else None."""
    for entry in sys.path:
        base = entry or "."
        try:
            with os.scandir(base) as it:
                names = sorted(e.name for e in it
                               if e.name.startswith("cmlt-") and e.name.endswith(".dist-info"))
        except OSError:                 # a zip file, a missing directory
            continue
        for name in names:
            try:
                with open(os.path.join(base, name, "METADATA"), encoding="utf-8") as f:
                    for line in f:
                        if line.startswith("Version:"):
                            return line.split(":", 1)[1].strip()
                        if not line.strip():    # the headers end at the first blank line
                            break
            except OSError:
                continue
    return None


def _version():
    found = _from_dist_info()
    if found:
        return found
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("cmlt")
    except PackageNotFoundError:        # a bare source tree (PYTHONPATH=src), not installed
        return "0+unknown"


__version__ = _version()
