"""Trackers: the published systems and their baselines side by side, on one contract.

Five trackers: the latent-space tracker (Tian et al.), CONDENSATION and MHT (its baselines),
the linear-combination tracker (Ong & Gong) and the mixed-state tracker (Kwatra et al.). Every
tracker is a :class:`Tracker` (``observe``, ``start``, ``update``, ``first_estimate``,
``options``),
assembled from a prior or dynamics, a :class:`Likelihood` and, optionally, the full-state
:class:`Refinement` stage that every tracker can take; :func:`track` runs any of them over a
video in compiled chunks. See ``docs/trackers.md``.
"""

from jaxtrack.trackers._gauss_newton import ArmijoGaussNewton, refine_pose, refinement_cost
from jaxtrack.trackers._options import (
    DEFAULT_ARM_GRID,
    DEFAULT_ARM_MARGIN,
    DEFAULT_ARM_MOMENTUM,
    DEFAULT_ARM_SPAN,
    DEFAULT_REFINE_STEPS,
    RESAMPLERS,
    ArmSearch,
    Engine,
    Likelihood,
    Refinement,
    options_record,
)
from jaxtrack.trackers._particles import DetectionLikelihood, ImageTracker, detection_observations
from jaxtrack.trackers._refinement import RefinementState, refine, score_pose, search_arms
from jaxtrack.trackers._runner import TrackResult, track
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk, frame_at
from jaxtrack.trackers.condensation import (
    CondensationModel,
    CondensationState,
    CondensationTracker,
    condensation_tracker,
    random_walk_tracker,
)
from jaxtrack.trackers.latent import (
    DEFAULT_JUMP_PROBABILITY,
    LatentModel,
    LatentState,
    LatentTracker,
    default_refinement,
    latent_tracker,
)
from jaxtrack.trackers.linear_combination import (
    LinearCombinationEstimate,
    LinearCombinationTracker,
    linear_combination_tracker,
)
from jaxtrack.trackers.mht import MHTModel, MHTState, MHTTracker, ModePool, mht_tracker
from jaxtrack.trackers.mixed_state import MixedStateModel, MixedStateTracker

__all__ = [
    "DEFAULT_ARM_GRID", "DEFAULT_ARM_MARGIN", "DEFAULT_ARM_MOMENTUM", "DEFAULT_ARM_SPAN",
    "DEFAULT_JUMP_PROBABILITY", "DEFAULT_REFINE_STEPS", "RESAMPLERS",
    "ArmSearch", "ArmijoGaussNewton", "DetectionLikelihood", "Engine", "CondensationModel",
    "CondensationState",
    "CondensationTracker", "FrameEstimate", "FrameInChunk", "ImageTracker", "LatentModel",
    "LatentState", "LatentTracker", "Likelihood", "LinearCombinationEstimate",
    "LinearCombinationTracker", "MHTModel", "MHTState", "MHTTracker", "MixedStateModel",
    "MixedStateTracker", "ModePool", "Refinement", "RefinementState", "TrackResult", "Tracker",
    "VideoChunk", "condensation_tracker", "default_refinement", "detection_observations",
    "frame_at", "latent_tracker",
    "linear_combination_tracker", "mht_tracker",
    "options_record", "random_walk_tracker", "refine", "refine_pose", "refinement_cost",
    "score_pose", "search_arms", "track",
]
