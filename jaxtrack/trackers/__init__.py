"""Trackers: the published systems and their baselines, each an assembled state-space model.

Every tracker has ``start(key, frame)`` and ``update(key, state, frame)``; :func:`track` runs
one over a video in compiled chunks.
"""

from jaxtrack.trackers._runner import FrameEstimate, ParticleTracker, TrackResult, track
from jaxtrack.trackers.condensation import (
    AR2Dynamics,
    CondensationModel,
    CondensationTracker,
    condensation_tracker,
    fit_ar2,
    random_walk_dynamics,
    random_walk_tracker,
)
from jaxtrack.trackers.latent import LatentModel, LatentState, LatentTracker, latent_tracker
from jaxtrack.trackers.mht import MHTState, MHTTracker, mht_tracker, refine_pose

__all__ = ["FrameEstimate", "LatentModel", "LatentState", "LatentTracker", "ParticleTracker",
           "TrackResult", "latent_tracker", "track"]
__all__ += ["AR2Dynamics", "CondensationModel", "CondensationTracker", "MHTState", "MHTTracker",
            "condensation_tracker", "fit_ar2", "mht_tracker", "random_walk_dynamics",
            "random_walk_tracker", "refine_pose"]
