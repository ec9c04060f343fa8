"""Flicker and error metrics of image sequences (DESIGN.md §4), for the
``cmlt flicker`` / ``cmlt compare`` commands and for notebooks::

    from cmlt.metrics import load_sequence, flicker, compare
    frames, images = load_sequence("renders/shot.####.exr")
    _, refs = load_sequence("ref/shot.####.exr", frames=frames)
    report = flicker(images, refs, frames=frames)
    report.tf, report.gf, report.mean_rel_mse

See :mod:`cmlt.metrics.flicker` for the exact definitions.
"""
from .flicker import (REL_MSE_EPS, FlickerReport, FrameDifferenceFlicker, compare, flicker,
                      reference_floor, rel_mse)
from .sequence import MetricsError, find_frames, load_image, load_sequence

__all__ = ["MetricsError", "FlickerReport", "FrameDifferenceFlicker", "load_sequence",
           "load_image", "find_frames",
           "flicker", "compare", "rel_mse", "REL_MSE_EPS", "reference_floor"]
