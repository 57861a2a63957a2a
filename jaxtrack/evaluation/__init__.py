"""Evaluation: marker errors, failure detection, summaries across sequences, plots.

Metrics only: it reads what trackers produce (2-D markers per frame) and the rendered ground
truth, and returns plain Python results that can be written as JSON. It imports no tracker,
prior, experiment or OpenCV; overlay videos are drawn in ``jaxtrack.vision`` and the protocol
that produces the tracks is ``jaxtrack.experiments``.
"""

from jaxtrack.evaluation.metrics import (
    DEFAULT_EPSILONS,
    compare_methods,
    evaluate_track,
    marker_errors,
    summarise,
    torso_lengths,
)
from jaxtrack.evaluation.plots import (
    plot_errors_over_time,
    plot_fraction_within,
    plot_particle_sweep,
)

__all__ = [
    "DEFAULT_EPSILONS", "compare_methods", "evaluate_track", "marker_errors",
    "plot_errors_over_time", "plot_fraction_within", "plot_particle_sweep", "summarise",
    "torso_lengths",
]
