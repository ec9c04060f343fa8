"""The same USD frame for peer renderers: cmlt's loaded frame converted for Mitsuba 3
and LuxCore, each peer rendering in a worker process of its own, so that their
error-time curves can be drawn beside cmlt's (``cmlt accuracy --peers``,
``tests/bench/peers.py``).

The peers are not cmlt dependencies: ``pip install mitsuba pyluxcore``. A peer that is not
installed, does not import or fails a 16x16 probe render is reported with the reason
(:func:`start_peer`) and left out.

The package:

* ``scene``: the neutral scene (:func:`convert_frame`: what is converted and how) and the
  brightness measures;
* ``mitsuba``, ``luxcore``: one module per peer renderer;
* ``harness``: the worker processes, the probe, ``--peers`` and :class:`PeerSession`.
"""

from .harness import (DEFAULT_PEER_INTEGRATORS, PEER_MODULES, PeerSession, RemoteRenderer, Worker,
                      WorkerDied, parse_peers, small_copy, start_peer, worker_main)
from .luxcore import LuxCoreRenderer, import_luxcore
from .mitsuba import MitsubaRenderer, find_libllvm, setup_llvm_env
from .scene import (LUX_SPHERE_SEGMENTS, MAX_DEPTH, PCamera, PMaterial, PMesh, PScene, PSphere,
                    clipped_ratio, convert_frame, luminance, make_cmlt_lambert, uv_sphere_same_area)

__all__ = [
    "DEFAULT_PEER_INTEGRATORS", "PEER_MODULES", "PeerSession", "RemoteRenderer", "Worker", "WorkerDied",
    "parse_peers", "small_copy", "start_peer", "worker_main", "LuxCoreRenderer", "import_luxcore",
    "MitsubaRenderer", "find_libllvm", "setup_llvm_env", "LUX_SPHERE_SEGMENTS", "MAX_DEPTH", "PCamera",
    "PMaterial", "PMesh", "PScene", "PSphere", "clipped_ratio", "convert_frame", "luminance",
    "make_cmlt_lambert", "uv_sphere_same_area",
]
