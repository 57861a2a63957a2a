"""What the image trackers share (latent, CONDENSATION, MHT): how they observe a video
(:class:`ImageTracker`), frame 0's SPM pose and templates, the engine's step on a frame read from
the chunk in place, and the per-frame report of a particle cloud."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPMTemplate, spm_initial_state
from jaxtrack.likelihoods import PartTemplates, check_markers, make_appearance_templates
from jaxtrack.trackers._options import Engine, Likelihood
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk
from jaxtrack.vision.observations import ImageObservation, images_of

__all__ = ["ImageTracker", "check_initial_pose", "cloud_estimate", "device_observation",
           "filter_step", "first_info", "frame0_state", "frame0_templates", "initialize_filter",
           "observe_images"]


def observe_images(likelihood: Likelihood, chunk: VideoChunk, out=None) -> ImageObservation:
    """A chunk's :class:`jaxtrack.vision.ImageObservation` as ``likelihood`` reads it: the grey
    frames alone (limb strips, NCC), or with their edge maps (``"limbs+edges"``; the person's
    masks as a fourth channel where given), and a detector's keypoints where the likelihood's
    keypoint term is on. Grey frames may also be edge observations made beforehand, ``(time,
    3 or 4, height, width)``. Anything that does not suit the likelihood is refused in one
    line, naming what to give."""
    from jaxtrack.vision.observations import image_observations

    if chunk.grey is None:
        raise ValueError("the image trackers read grey frames: give grey=... (time, height, "
                         "width)")
    grey = np.asarray(chunk.grey)
    if likelihood.has_keypoints and chunk.keypoints is None:
        raise ValueError("the likelihood's keypoint term (keypoint_weight) reads a detector's "
                         "keypoints: give keypoints=...")
    if chunk.keypoints is not None and not likelihood.has_keypoints:
        raise ValueError("keypoints are read by the likelihood's keypoint term only: give "
                         "Likelihood(keypoint_weight=...) or leave keypoints out")
    if chunk.masks is not None and not likelihood.needs_edges:
        raise ValueError(f"masks are read by the 'limbs+edges' likelihood only (its foreground "
                         f"and coverage terms), not by {likelihood.kind!r}")
    if grey.ndim == 4:  # edge observations made beforehand
        if not likelihood.needs_edges or grey.shape[1] not in (3, 4):
            edges = (" (or (time, 3 or 4, height, width) grey frames with their edge maps)"
                     if likelihood.needs_edges else "")
            raise ValueError(f"frames for the {likelihood.kind!r} likelihood must be (time, "
                             f"height, width) grey images, got shape {grey.shape}{edges}")
        if chunk.masks is not None:
            raise ValueError("edge observations made beforehand carry their own mask channel: "
                             "leave masks out")
        with_mask = grey.shape[1] == 4
        observation = ImageObservation(np.asarray(grey, np.float32), None)
        if chunk.keypoints is not None:
            observation = image_observations(grey[:, 0], edges=False,
                                             keypoints=chunk.keypoints)
            observation = ImageObservation(np.asarray(grey, np.float32), observation.keypoints)
    elif grey.ndim == 3:
        with_mask = chunk.masks is not None
        images = None if out is None else out.images[:len(grey)]
        if images is not None and images.shape[1:] != (
                ((3 + with_mask,) if likelihood.needs_edges else ()) + grey.shape[1:]):
            images = None
        observation = image_observations(grey, edges=likelihood.needs_edges, masks=chunk.masks,
                                         keypoints=chunk.keypoints, out=images)
    else:
        raise ValueError(f"frames must be (time, height, width) grey images, got shape "
                         f"{grey.shape}")
    if likelihood.has_coverage and not with_mask:
        raise ValueError("the likelihood's coverage term (coverage_weight) reads the person's "
                         "masks: give masks=..., or observations with a mask channel")
    return observation


def device_observation(observation, dtype=None):
    """A frame's observation (any pytree) as JAX arrays, floating leaves in ``dtype``."""
    def convert(leaf):
        leaf = np.asarray(leaf)
        if dtype is not None and np.issubdtype(leaf.dtype, np.floating):
            return jnp.asarray(leaf, dtype)
        return jnp.asarray(leaf)

    return jax.tree.map(convert, observation)


class ImageTracker(Tracker):
    """A tracker whose likelihood reads image channels (limb strips, edges, NCC) and, with its
    keypoint term, a detector's keypoints: the latent, CONDENSATION and MHT trackers."""

    likelihood: eqx.AbstractVar[Likelihood]

    @property
    def reads(self) -> tuple[str, ...]:
        return (("grey",) + (("masks",) if self.likelihood.has_coverage else ())
                + (("keypoints",) if self.likelihood.has_keypoints else ()))

    def observe(self, chunk: VideoChunk, out=None) -> ImageObservation:
        return observe_images(self.likelihood, chunk, out)


def check_initial_pose(initial_pose: Float[ArrayLike, "markers 2"]) -> np.ndarray:
    """``initial_pose`` as ``(markers, 2)`` float64 image markers in ``SPM_MARKERS`` order, or a
    ValueError that says what is wrong."""
    check_markers(initial_pose, name="initial_pose", finite=True)
    return np.asarray(initial_pose, np.float64)


def frame0_templates(likelihood: Likelihood, first_frame: Float[ArrayLike, "..."],
                     markers: np.ndarray, background: Array | None, dtype
                     ) -> PartTemplates:
    """The likelihood's templates cut from frame 0 (as the likelihood observes it) at its
    markers, in ``dtype``."""
    first_frame = np.asarray(images_of(first_frame))
    if likelihood.needs_edges and (first_frame.ndim != 3 or first_frame.shape[0] not in (3, 4)):
        raise ValueError(f"first_frame must be the {likelihood.kind!r} likelihood's observation, "
                         f"(3, height, width): the grey frame and its edge maps "
                         f"(jaxtrack.vision.edge_observations), or (4, height, width) with the "
                         f"person's mask, got shape {first_frame.shape}")
    if not likelihood.needs_edges and first_frame.ndim != 2:
        raise ValueError(f"first_frame must be a (height, width) grey frame for the "
                         f"{likelihood.kind!r} likelihood, got shape {first_frame.shape}")
    if not np.all(np.isfinite(first_frame)):
        raise ValueError("first_frame holds non-finite values")
    cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
    return make_appearance_templates(likelihood.kind, cast(first_frame), cast(markers),
                                     background, **likelihood.edge_options)


def frame0_state(markers: np.ndarray, template: SPMTemplate, dtype) -> Float[Array, " 25"]:
    """Frame 0's SPM state from its markers, in ``dtype`` (the template already in it)."""
    return spm_initial_state(jnp.asarray(np.asarray(markers, np.float64), dtype), template)


class _FrameOfChunk(smc.StateSpaceModel):
    """``model`` with observations ``(frames, index)`` standing for ``frames[index]``."""

    model: smc.StateSpaceModel

    def init(self, key: PRNGKeyArray):
        return self.model.init(key)

    def propagate(self, key: PRNGKeyArray, particle, time):
        return self.model.propagate(key, particle, time)

    def log_likelihood(self, particle, observation) -> Float[Array, ""]:
        frames, index = observation
        return self.model.log_likelihood(particle,
                                         jax.tree.map(lambda leaf: leaf[index], frames))


def filter_step(engine: Engine, key: PRNGKeyArray, state: smc.FilterState,
                frame: Array | FrameInChunk, model: smc.StateSpaceModel
                ) -> tuple[smc.FilterState, smc.StepInfo]:
    """The engine's step on ``frame``. A :class:`FrameInChunk` is never cut out of the chunk: the
    engine hands its observation to the re-seeding branch of a ``lax.cond``, and a frame sliced
    from the chunk would be copied whole into a buffer for it on every frame (1.2 MB at
    640 × 480); here the cond gets the chunk and the index, and each particle's likelihood
    reads its pixels from the chunk directly."""
    if isinstance(frame, FrameInChunk):
        return engine.step(key, state, (frame.frames, frame.index), _FrameOfChunk(model))
    return engine.step(key, state, frame, model)


@eqx.filter_jit
def initialize_filter(key: PRNGKeyArray, model: smc.StateSpaceModel, frame: Array,
                      num_particles: int) -> smc.FilterState:
    """The filter's state at frame 0: ``num_particles`` from ``model.init``, weighted by it."""
    return smc.initialize(key, model, frame, num_particles)[0]


def first_info(state: smc.FilterState) -> smc.StepInfo:
    """Frame 0's ``StepInfo`` of a filter that was initialised on it: degenerate when no
    initial particle had a finite likelihood there (the engine then re-seeded and reports its
    log evidence as −inf), with an ESS of 0 then, as the engine reports a degenerate frame."""
    num = state.log_weights.shape[0]
    degenerate = ~jnp.isfinite(state.log_evidence)
    ess = jnp.where(degenerate, 0, smc.effective_sample_size(state.log_weights))
    return smc.StepInfo(state.log_evidence, ess, jnp.asarray(False), degenerate,
                        jnp.asarray(0), jnp.arange(num))


def cloud_estimate(state: smc.FilterState, info: smc.StepInfo, markers: Array,
                   markers_of) -> FrameEstimate:
    """A particle cloud's report: ``markers`` (the tracker's estimate), the best particle's
    markers (``markers_of``), the ESS, the log evidence increment and the degenerate flag."""
    best = smc.best_particle(state.particles, state.log_weights)
    return FrameEstimate(markers=markers, best_markers=markers_of(best), ess=info.ess,
                         log_likelihood=info.log_evidence_increment,
                         degenerate=info.degenerate)

