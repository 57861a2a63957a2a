"""Evaluation: marker errors, failure detection, summaries across sequences, plots, overlay videos.

The bottom layer: it reads what trackers produce (2-D markers per frame) and the rendered ground
truth, and returns plain Python results that can be written as JSON.
"""

from jaxtrack.evaluation.metrics import (
    DEFAULT_EPSILONS,
    compare_methods,
    evaluate_track,
    marker_errors,
    summarise,
    torso_lengths,
)
from jaxtrack.evaluation.overlay import (
    METHOD_COLOURS,
    TRUTH_COLOUR,
    draw_tracks,
    write_overlay_video,
)
from jaxtrack.evaluation.plots import (
    plot_errors_over_time,
    plot_fraction_within,
    plot_particle_sweep,
)

__all__ = [
    "DEFAULT_EPSILONS", "METHOD_COLOURS", "TRUTH_COLOUR", "compare_methods", "draw_tracks",
    "evaluate_track", "marker_errors", "plot_errors_over_time", "plot_fraction_within",
    "plot_particle_sweep", "summarise", "torso_lengths", "write_overlay_video",
]
