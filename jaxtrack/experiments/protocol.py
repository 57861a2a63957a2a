"""The evaluation protocol of the latent-space tracker and its baselines (``jaxtrack evaluate``).

1. Train a GPLVM on real clips (:func:`jaxtrack.priors.train.train_prior`): upper-body SPM poses
   seen from several viewpoints (``jaxtrack.priors.poses``), Algorithm 1 of Tian et al.
2. Render held-out clips (other takes or subjects) with exact ground truth
   (:func:`render_test_sequences`): a frontal view and random viewpoints in the training views'
   range, over real-photo and cluttered backgrounds.
3. Track each with a method (:func:`run_method`), all initialised from frame 0's ground truth,
   and score with :func:`jaxtrack.evaluation.evaluate_track`. The baselines learn their
   dynamics from the prior's training poses (``baseline_dynamics="training"``), or, as Tian et
   al. did, from the first 30 frames of the test clip's ground truth (``"test_start"``).

Which clips are training, validation and test subjects: :mod:`jaxtrack.data.splits`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import jax.numpy as jnp
import jax.random as jr
import numpy as np

from jaxtrack.body import (
    UPPER_BODY_12,
    frontal_camera,
    render_motion,
    spm_initial_state,
)
from jaxtrack.priors.train import TrainedPrior
from jaxtrack.trackers import Likelihood, Refinement

__all__ = ["AR_TRAINING_FRAMES", "BASELINE_DYNAMICS", "DEFAULT_PARTICLES", "METHODS",
           "TestSequence", "baseline_training_states", "build_tracker", "render_test_sequences",
           "run_method", "video_tracker"]

METHODS = ("latent", "condensation", "mht")
DEFAULT_PARTICLES = {"latent": 200, "condensation": 1000, "mht": 10}
AR_TRAINING_FRAMES = 30  # Tian et al.: the baseline's AR(2) dynamics come from 30 frames
BASELINE_DYNAMICS = ("training", "test_start")
"""Where CONDENSATION's AR(2) and MHT's step are learned: the prior's training poses (the
default: nothing is learned from the clip that is scored), or the first
:data:`AR_TRAINING_FRAMES` frames of the test clip's ground truth (Tian et al.'s protocol)."""


@dataclass(frozen=True)
class TestSequence:
    """A rendered held-out clip: colour frames, grey frames and the 12 true markers."""

    name: str
    images: np.ndarray
    frames: np.ndarray
    truth: np.ndarray
    fps: float


def render_test_sequences(clip: str, *, views: int = 2, backgrounds: Sequence[str] = ("photo",),
                          fps: float = 30.0, image_size: tuple[int, int] = (640, 480),
                          max_frames: int | None = None, seed: int = 0,
                          progress: bool = False, asf: str | os.PathLike | None = None
                          ) -> list[TestSequence]:
    """Render a held-out clip (a catalogue name, or a path to a ``.bvh`` file or an ``.amc``
    file with its ``asf`` skeleton given or beside it): view 0 is frontal, the others random in
    azimuth ±40° and elevation 0–0.3 rad (inside the training views' range), once per
    background. Sequences are named after the clip's own name (a file's stem)."""
    from jaxtrack.data import resolve_clip
    from jaxtrack.vision import to_grey

    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    source = resolve_clip(clip, asf=asf)
    motion = source.load().resample(fps)
    if max_frames is not None:
        motion = motion.select(0, min(max_frames, motion.num_frames))
    rng = np.random.default_rng(seed)
    sequences = []
    for view in range(views):
        azimuth, elevation = (0.0, 0.1) if view == 0 else (rng.uniform(-0.7, 0.7),
                                                           rng.uniform(0.0, 0.3))
        camera = frontal_camera(motion, image_size, azimuth=azimuth, elevation=elevation)
        for background in backgrounds:
            render_seed = int(rng.integers(2**31))
            rendered = render_motion(motion, camera, image_size=image_size,
                                     background=background, markers=UPPER_BODY_12,
                                     seed=render_seed, progress=progress)
            sequences.append(TestSequence(
                name=f"{source.short_name}_view{view}_{background}",
                images=rendered.images, frames=to_grey(rendered.images),
                truth=np.asarray(rendered.markers_2d, np.float64), fps=fps))
    return sequences


def baseline_training_states(prior: TrainedPrior, sequence: TestSequence,
                             baseline_dynamics: str = "training"
                             ) -> tuple[np.ndarray, np.ndarray | None]:
    """``(states, sequence_ids)`` the baselines learn their dynamics from
    (:data:`BASELINE_DYNAMICS`); ``sequence_ids`` is None for the one test-clip trajectory."""
    if baseline_dynamics == "training":
        if prior.training_states is None:
            raise ValueError("this prior was saved without its training poses, which the "
                             "baselines' dynamics are learned from: train it again "
                             "(jaxtrack train), or use baseline_dynamics='test_start'")
        return prior.training_states, prior.training_sequence_ids
    if baseline_dynamics == "test_start":
        truth = jnp.asarray(sequence.truth[:AR_TRAINING_FRAMES])
        return np.asarray(spm_initial_state(truth, prior.template)), None
    raise ValueError(f"baseline_dynamics must be one of {BASELINE_DYNAMICS}, got "
                     f"{baseline_dynamics!r}")


def build_tracker(method: str, prior: TrainedPrior, sequence: TestSequence, particles: int,
                  likelihood: Likelihood = Likelihood(),
                  refinement: Refinement | None | str = "default", background: bool = True,
                  baseline_dynamics: str = "training", latent_options: dict | None = None,
                  mht_options: dict | None = None, engine_options: dict | None = None):
    """The tracker ``method`` for a test sequence (start it at frame 0's ground truth).

    Every method is scored by the same ``likelihood``; ``refinement`` is the full-state
    refinement stage, the same for every method that takes it (``"default"``: the method's
    default, the latent tracker's :func:`~jaxtrack.trackers.default_refinement` and none for
    CONDENSATION and MHT, which report their own estimates as the paper did; None: none);
    ``background``: with ``"limbs+edges"``, score the arms against the sequence's median
    background too (the foreground term, ``jaxtrack.likelihoods.edges``). CONDENSATION's AR(2)
    and MHT's step are learned as ``baseline_dynamics`` says (:data:`BASELINE_DYNAMICS`).
    ``latent_options``: further keyword arguments of :func:`~jaxtrack.trackers.latent_tracker`
    (e.g. ``{"subject_lengths": True}``); ``mht_options`` those of
    :func:`~jaxtrack.trackers.mht_tracker` (e.g. ``{"prior_scale": 2.0}``);
    ``engine_options`` further settings of the latent tracker's and CONDENSATION's
    :class:`~jaxtrack.trackers.Engine` (e.g. ``{"iterations_per_frame": 3}``)."""
    from jaxtrack import trackers
    from jaxtrack.vision import median_grey_background

    scene = (median_grey_background(sequence.frames)
             if background and likelihood.needs_edges else None)
    if method == "latent":
        return trackers.latent_tracker(prior.model, prior.template,
                                       engine=trackers.Engine(particles,
                                                              **(engine_options or {})),
                                       fps=sequence.fps,
                                       likelihood=likelihood, refinement=refinement,
                                       background=scene, **(latent_options or {}))
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if refinement == "default":
        refinement = None
    states, ids = baseline_training_states(prior, sequence, baseline_dynamics)
    if method == "condensation":
        return trackers.condensation_tracker(prior.template, states,
                                             engine=trackers.Engine(
                                                 particles, **(engine_options or {})),
                                             likelihood=likelihood, refinement=refinement,
                                             background=scene, sequence_ids=ids)
    return trackers.mht_tracker(prior.template, states, num_modes=particles,
                                likelihood=likelihood, refinement=refinement,
                                background=scene, sequence_ids=ids, **(mht_options or {}))


def run_method(method: str, prior: TrainedPrior, sequence: TestSequence, *,
               particles: int | None = None, seed: int = 0,
               likelihood: Likelihood = Likelihood(),
               refinement: Refinement | None | str = "default", background: bool = True,
               baseline_dynamics: str = "training", progress: bool = True):
    """Track a test sequence with one method from frame 0's ground truth; returns the
    :class:`~jaxtrack.trackers.TrackResult` (its ``options`` say what ran; the other
    arguments: :func:`build_tracker`)."""
    from jaxtrack.trackers import track

    particles = particles or DEFAULT_PARTICLES[method]
    tracker = build_tracker(method, prior, sequence, particles, likelihood, refinement,
                            background, baseline_dynamics)
    return track(tracker, jr.PRNGKey(seed), sequence.frames, sequence.truth[0],
                 progress=progress, description=f"{method} N={particles}")


def video_tracker(method: str, prior: TrainedPrior, particles: int, *, fps: float | None,
                  likelihood: Likelihood = Likelihood(),
                  refinement: Refinement | None | str = "default",
                  background: np.ndarray | None = None):
    """The tracker ``method`` (:data:`METHODS`) for a video, as :func:`build_tracker` builds it
    for a test sequence: CONDENSATION's AR(2) and MHT's step learned from the prior's training
    poses (``baseline_dynamics="training"``).

    Args:
        method: ``"latent"``, ``"condensation"`` or ``"mht"``.
        prior: a prior from :func:`jaxtrack.priors.train.train_prior` (``jaxtrack train``);
            CONDENSATION and MHT need its training poses.
        particles: the particles (MHT: the modes).
        fps: the video's frame rate (the latent tracker's dynamics), None when unknown.
        likelihood, refinement: as :func:`build_tracker`'s.
        background: ``(height, width)`` grey empty scene at the tracking size for the
            foreground term, or None.
    """
    from jaxtrack import trackers

    if method == "latent":
        return trackers.latent_tracker(prior.model, prior.template,
                                       engine=trackers.Engine(particles), fps=fps,
                                       likelihood=likelihood, refinement=refinement,
                                       background=background)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if refinement == "default":
        refinement = None
    if prior.training_states is None:
        raise ValueError("this prior was saved without its training poses, which "
                         f"{method}'s dynamics are learned from: train it again "
                         "(jaxtrack train)")
    ids = prior.training_sequence_ids
    if method == "condensation":
        return trackers.condensation_tracker(prior.template, prior.training_states,
                                             engine=trackers.Engine(particles),
                                             likelihood=likelihood, refinement=refinement,
                                             background=background, sequence_ids=ids)
    return trackers.mht_tracker(prior.template, prior.training_states, num_modes=particles,
                                likelihood=likelihood, refinement=refinement,
                                background=background, sequence_ids=ids)
