"""The package version, from the installed distribution (pyproject.toml is the
one place it is written)."""
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cmlt")
except PackageNotFoundError:            # a bare source tree (PYTHONPATH=src), not installed
    __version__ = "0+unknown"
