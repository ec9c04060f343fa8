"""Shots as sequences: frame specs, output patterns, the FrameScene -> core
bridge, the frame loop and its progress display."""
from .errors import RenderCancelled, RenderError, UsageError
from .frames import (FrameSpecError, OutputPatternError, default_frames, expand_outputs,
                     expand_pattern, format_frame, parse_frames)
from .sequence import RenderOptions, SequenceResult, default_output, render_sequence

__all__ = [
    "RenderCancelled", "RenderError", "UsageError", "FrameSpecError", "OutputPatternError",
    "default_frames", "expand_outputs", "expand_pattern", "format_frame", "parse_frames",
    "RenderOptions", "SequenceResult", "default_output",
    "render_sequence",
]
