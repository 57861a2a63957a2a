"""Trackers: the published systems and their baselines, each an assembled state-space model.

Every tracker has ``start(key, frame)`` and ``update(key, state, frame)``; :func:`track` runs
one over a video in compiled chunks.
"""

from jaxtrack.trackers._runner import FrameEstimate, ParticleTracker, TrackResult, track
from jaxtrack.trackers.latent import LatentModel, LatentTracker, latent_tracker

__all__ = ["FrameEstimate", "LatentModel", "LatentTracker", "ParticleTracker", "TrackResult",
           "latent_tracker", "track"]
