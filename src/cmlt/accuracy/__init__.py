"""What accuracy costs in time: error-time curves of the integrators on a shot
(``cmlt accuracy``), and a render's estimate of its own error.

::

    from cmlt.accuracy import ShotFrame, parse_integrator, render_reference, measure
    sf = ShotFrame("sequences/cornell/shot.usda", resolution=(64, 64), threads=2)
    ref = render_reference(sf, "bdpt", 4096, cache_dir="renders/cache/accuracy")
    run = sf.render(parse_integrator("pt"), seconds=2.0, seed=0)
    measure(run.image, ref.image)             # relMSE, RMSE, mean ratio

    from cmlt.accuracy import estimate_from_variance, estimate_from_groups
    estimate_from_variance(run.image, run.variance).relmse   # pt, bdpt: no reference needed

Modules: :mod:`.render` (a frame in the core, timed renders, cached references),
:mod:`.curves` (rows, fits, CSV, markdown), :mod:`.plot`, :mod:`.peers` (Mitsuba 3 and
LuxCore on the same frame), :mod:`.cli` (the ``cmlt accuracy`` command). The error
estimate is :mod:`cmlt.metrics.error_estimate` (``cmlt render`` records it too), its names
re-exported here.
"""
from ..metrics.error_estimate import (REL_MSE_EPS, ErrorEstimate, estimate_from_groups,
                                      estimate_from_variance, pixel_terms)
from .curves import (CSV_COLUMNS, TARGETS, Fit, Row, Run, aggregate, fit, fits, markdown_table,
                     measure, read_csv, write_csv, write_runs_csv)
from .render import (INTEGRATORS, AccuracyError, IntegratorSpec, Reference, RenderRun, ShotFrame,
                     load_reference, parse_integrator, render_reference, stage_start)

__all__ = [
    "CSV_COLUMNS", "TARGETS", "Fit", "Row", "Run", "aggregate", "fit", "fits", "markdown_table",
    "measure", "read_csv", "write_csv", "write_runs_csv",
    "REL_MSE_EPS", "ErrorEstimate", "estimate_from_groups", "estimate_from_variance",
    "pixel_terms",
    "INTEGRATORS", "AccuracyError", "IntegratorSpec", "Reference", "RenderRun", "ShotFrame",
    "load_reference", "parse_integrator", "render_reference", "stage_start",
]
