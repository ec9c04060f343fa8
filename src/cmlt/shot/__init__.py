"""Shots as sequences: frame specs and output patterns (``frames``), the
options (``options``), the settings handed to the core (``core_settings``),
the FrameScene -> core bridge (``bridge``), one frame's job (``frame_job``,
``output``), the sequence loop (``sequence``) and its progress display."""
from .errors import RenderCancelled, RenderError, UsageError
from .frames import (FrameSpecError, OutputPatternError, default_frames, expand_outputs,
                     expand_pattern, format_frame, parse_frames)
from .options import RenderOptions, default_output
from .sequence import SequenceResult, render_sequence

__all__ = [
    "RenderCancelled", "RenderError", "UsageError", "FrameSpecError", "OutputPatternError",
    "default_frames", "expand_outputs", "expand_pattern", "format_frame", "parse_frames",
    "RenderOptions", "SequenceResult", "default_output",
    "render_sequence",
]
