"""Flicker-free sequences (DESIGN.md §4): stored seeds, carried chain states,
smoothed normalisation and the state files that let a sequence continue in
another job.

* :mod:`.normalization` — b from the fresh estimate and the ratio estimator,
  inverse-variance combination, smoothing with change detection;
* :mod:`.state` — the ``state.####.bin`` format (``CMLTSTAT``, versioned,
  CRC-32 checked);
* :mod:`.driver` — :class:`TemporalDriver`, what the frame loop calls before
  and after each frame's render.
"""
from .driver import TemporalDriver, frame_seed
from .normalization import NormRecord, update_normalization
from .state import STATE_VERSION, FrameState, StateError, read_state, state_path, write_state

__all__ = ["TemporalDriver", "frame_seed", "NormRecord", "update_normalization",
           "STATE_VERSION", "FrameState", "StateError", "read_state", "write_state", "state_path"]
