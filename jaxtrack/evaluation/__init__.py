"""Evaluation: marker errors, failure detection, summaries across sequences, tables, plots.

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
    plot_confusion,
    plot_error_surface,
    plot_errors_over_time,
    plot_fraction_within,
    plot_fraction_within_per_part,
    plot_particle_sweep,
)
from jaxtrack.evaluation.tables import (
    MIXED_STATE_ESTIMATES,
    MIXED_STATE_PARTS,
    mixed_state_label,
    mixed_state_table,
    skeleton_error_table,
    summarise_skeleton_errors,
)

__all__ = [
    "DEFAULT_EPSILONS", "MIXED_STATE_ESTIMATES", "MIXED_STATE_PARTS", "compare_methods",
    "evaluate_track", "marker_errors", "mixed_state_label", "mixed_state_table",
    "plot_confusion", "plot_error_surface", "plot_errors_over_time", "plot_fraction_within",
    "plot_fraction_within_per_part", "plot_particle_sweep", "skeleton_error_table",
    "summarise", "summarise_skeleton_errors", "torso_lengths",
]
