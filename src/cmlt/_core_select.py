"""Which build of the C++ core (``cmlt._core``) a process loads.

The package ships the core module compiled for portable x86-64 (``cmlt/_core*.so``) and,
beside it, for newer x86-64 levels (``cmlt/x86-64-v4/_core*.so``: the variants the build
made, ``CMLT_CORE_VARIANTS`` in ``CMakeLists.txt``). Every build computes the same images
bit for bit (no FMA contraction; ``tests/python/test_core_select.py`` renders with both);
the newer ones are faster. ``import cmlt`` installs a finder for ``cmlt._core`` that
loads the best build this CPU runs, unless the environment variable ``CMLT_CORE_ISA``
says otherwise:

``auto`` (or unset)   the best available build the CPU supports, else the portable one
``baseline``          the portable build
``x86-64-v4``         that build; an error if it is missing or the CPU lacks it

The module says which it is: ``cmlt._core.isa`` (``"x86-64"`` for the portable one),
recorded in every frame's sidecar as ``core_isa``.
"""
from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import os
import platform
import sys
from pathlib import Path
from typing import FrozenSet, Iterable, List, Optional, Sequence

__all__ = ["ENV", "BASELINE", "VARIANTS", "CoreSelectError", "cpu_flags", "supports", "choose", "variants_beside",
           "install"]

ENV = "CMLT_CORE_ISA"
BASELINE = "baseline"

# The x86-64 levels a variant may be built for, best first, with the /proc/cpuinfo flags
# each needs (x86-64 psABI: v2 = cx16 lahf sahf popcnt sse3 sse4.1 sse4.2 ssse3; v3 adds
# avx avx2 bmi1 bmi2 f16c fma lzcnt movbe xsave; v4 adds avx512f bw cd dq vl). Linux lists
# an AVX or AVX-512 flag only where the kernel saves those registers.
_V2 = {"cx16", "lahf_lm", "popcnt", "pni", "sse4_1", "sse4_2", "ssse3"}
_V3 = _V2 | {"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "abm", "movbe", "xsave"}
_V4 = _V3 | {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}
VARIANTS = {"x86-64-v4": frozenset(_V4), "x86-64-v3": frozenset(_V3)}


class CoreSelectError(ImportError):
    """CMLT_CORE_ISA asks for a build that is missing or that this CPU cannot run."""


def cpu_flags(cpuinfo: str = "/proc/cpuinfo") -> FrozenSet[str]:
    """The CPU's feature flags (Linux on x86-64); empty where unknown."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return frozenset()
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return frozenset(line.split(":", 1)[1].split())
    except OSError:
        pass
    return frozenset()


def supports(isa: str, flags: Iterable[str]) -> bool:
    """Can a CPU with these flags run code built for `isa`?"""
    need = VARIANTS.get(isa)
    return need is not None and need <= set(flags)


def choose(available: Sequence[str], request: Optional[str], flags: Iterable[str]) -> str:
    """The build to load: one of `available` (variant levels found beside the portable
    module) or BASELINE, for the CMLT_CORE_ISA value `request` (None or "" = auto)."""
    flags = set(flags)
    req = (request or "auto").strip().lower()
    if req in ("baseline", "x86-64"):
        return BASELINE
    if req == "auto":
        for isa in VARIANTS:  # best first
            if isa in available and supports(isa, flags):
                return isa
        return BASELINE
    if req not in VARIANTS:
        raise CoreSelectError(f"{ENV}={request!r}: expected auto, baseline or one of {', '.join(VARIANTS)}")
    if req not in available:
        raise CoreSelectError(f"{ENV}={request}: this installation has no core module built for {req} "
                              f"(built: {', '.join(available) or 'only the portable one'})")
    if not supports(req, flags):
        missing = sorted(VARIANTS[req] - flags)
        raise CoreSelectError(f"{ENV}={request}: this CPU cannot run the {req} build "
                              f"(missing: {' '.join(missing) or 'unknown CPU'})")
    return req


def variants_beside(portable: str) -> List[str]:
    """The levels built beside the portable module file `portable` (best first): their
    modules are ``<its folder>/<level>/<its file name>``."""
    origin = Path(portable)
    return [isa for isa in VARIANTS if (origin.parent / isa / origin.name).is_file()]


class _CoreFinder(importlib.abc.MetaPathFinder):
    """Finds ``cmlt._core`` where the other finders do, then swaps in the chosen build."""

    name = "cmlt._core"

    def find_spec(self, fullname, path, target=None):
        if fullname != self.name:
            return None
        base = None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            base = finder.find_spec(fullname, path, target)
            if base is not None:
                break
        if base is None or not base.origin or not os.path.isfile(base.origin):
            return base
        isa = choose(variants_beside(base.origin), os.environ.get(ENV), cpu_flags())
        if isa == BASELINE:
            return base
        origin = Path(base.origin)
        file = str(origin.parent / isa / origin.name)
        return importlib.util.spec_from_file_location(
            fullname, file, loader=importlib.machinery.ExtensionFileLoader(fullname, file))


def install() -> None:
    """Put the finder first on sys.meta_path (once)."""
    if not any(isinstance(f, _CoreFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _CoreFinder())
