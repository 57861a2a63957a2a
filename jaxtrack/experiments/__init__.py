"""Experiments: the protocol that renders held-out clips, tracks them and scores the tracks, and
the video pipeline that runs any tracker on a video file (``track_video``).

The top library layer: it assembles a prior (``jaxtrack.priors.train``), the renderer
(``jaxtrack.body``), the trackers (``jaxtrack.trackers``) and the metrics
(``jaxtrack.evaluation``) into the runs behind ``jaxtrack evaluate``, the demo and the benchmarks.
Nothing below it imports it.
"""

from jaxtrack.experiments.pipeline import ViewRun, Window, track_video, video_background
from jaxtrack.experiments.protocol import (
    AR_TRAINING_FRAMES,
    BASELINE_DYNAMICS,
    DEFAULT_PARTICLES,
    METHODS,
    TestSequence,
    baseline_training_states,
    build_tracker,
    render_test_sequences,
    run_method,
)

__all__ = ["AR_TRAINING_FRAMES", "BASELINE_DYNAMICS", "DEFAULT_PARTICLES", "METHODS",
           "TestSequence", "ViewRun", "Window", "baseline_training_states", "build_tracker",
           "render_test_sequences", "run_method", "track_video", "video_background"]
