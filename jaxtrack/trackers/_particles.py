"""What the image trackers share (latent, CONDENSATION, MHT): how they observe a video
(:class:`ImageTracker`), frame 0's SPM pose and templates, the engine's step on a frame read from
the chunk in place, and the per-frame report of a particle cloud.

Any of them scores a per-frame detector's people by the normalised detection density
(:mod:`jaxtrack.likelihoods.detections`) when its ``likelihood`` is a
:class:`DetectionLikelihood`: the density alone, or times an image likelihood. Each frame's
detections travel in the observation (``ImageObservation.detections``, a ``DetectionsFrame``
of ``(people, markers)``), made by :func:`detection_observations`; nothing else of the trackers
changes, and the runner does not know which likelihood a tracker holds."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPM_MARKERS, SPMTemplate, spm_initial_state
from jaxtrack.likelihoods import PartTemplates, check_markers, make_appearance_templates
from jaxtrack.likelihoods.detections import (
    DetectionModel,
    DetectionsFrame,
    DetectionTemplates,
    check_detections_frames,
    detections_frames,
)
from jaxtrack.trackers._options import Engine, Likelihood
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk
from jaxtrack.vision.observations import ImageObservation, images_of

__all__ = ["DetectionLikelihood", "ImageTracker", "check_initial_pose", "cloud_estimate",
           "detection_observations", "device_observation",
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

    if isinstance(likelihood, DetectionLikelihood):
        raise ValueError("a detection likelihood reads each frame's detected people, which a "
                         "video chunk does not carry: track observations made beforehand, "
                         "jaxtrack.trackers.detection_observations(detections, grey=...)")
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
        if isinstance(self.likelihood, DetectionLikelihood):
            # the detections come with the observations (detection_observations), not as a
            # field of a video chunk; the image likelihood's frames where there is one
            return () if self.likelihood.image is None else ImageTracker._reads(
                self.likelihood.image)
        return self._reads(self.likelihood)

    @staticmethod
    def _reads(likelihood) -> tuple[str, ...]:
        return (("grey",) + (("masks",) if likelihood.has_coverage else ())
                + (("keypoints",) if likelihood.has_keypoints else ()))

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
    markers, in ``dtype``; a :class:`DetectionLikelihood`'s are the detection density's, times
    its image likelihood's where it has one."""
    if isinstance(likelihood, DetectionLikelihood):
        image = None if likelihood.image is None else frame0_templates(
            likelihood.image, first_frame, markers, background, dtype)
        params = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), likelihood.detections)
        return DetectionTemplates(image, params)
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



class DetectionLikelihood(eqx.Module):
    """How an image tracker scores a frame with a detector's people: the normalised detection
    density (:mod:`jaxtrack.likelihoods.detections`), alone or times an image likelihood.

    Stands where a :class:`~jaxtrack.trackers.Likelihood` stands (a tracker's ``likelihood``)
    and answers what the trackers ask of one. Its parameters are arrays, so that they can be
    learned from the video (:func:`jaxtrack.experiments.detection_tracking.fit_detection_model`).

    Attributes:
        detections: the density's parameters (:func:`jaxtrack.likelihoods.detection_model`,
            the tracker's 12 markers).
        image: the image likelihood the density multiplies; None: the detections alone (no
            frames read; no refinement has anything but the detections to climb).
    """

    detections: DetectionModel
    image: Likelihood | None = None

    def __check_init__(self):
        if not isinstance(self.detections, DetectionModel):
            raise ValueError(f"detections must be a DetectionModel (jaxtrack.likelihoods."
                             f"detection_model()), got {type(self.detections).__name__}")
        if self.detections.joint_scales.shape != (len(SPM_MARKERS),):
            raise ValueError(f"the detection model must be for the tracker's "
                             f"{len(SPM_MARKERS)} markers (SPM_MARKERS), got "
                             f"{self.detections.joint_scales.shape[0]}")
        if self.image is not None and not isinstance(self.image, Likelihood):
            raise ValueError(f"image must be a Likelihood or None, got "
                             f"{type(self.image).__name__}")

    @property
    def kind(self) -> str:
        return "detections" if self.image is None else f"{self.image.kind}+detections"

    @property
    def sharpness(self) -> float | None:
        return None if self.image is None else self.image.sharpness

    @property
    def lam(self) -> float:
        return 1.0 if self.image is None else self.image.lam

    @property
    def nearest(self) -> bool:
        return True if self.image is None else self.image.nearest

    @property
    def needs_edges(self) -> bool:
        return self.image is not None and self.image.needs_edges

    @property
    def has_coverage(self) -> bool:
        return self.image is not None and self.image.has_coverage

    @property
    def has_keypoints(self) -> bool:
        return self.image is not None and self.image.has_keypoints

    @property
    def edge_options(self) -> dict:
        return {} if self.image is None else self.image.edge_options

    def record(self) -> dict:
        """A JSON-able record: the image likelihood's options and the density's parameters."""
        from jaxtrack.trackers._options import options_record

        params = self.detections
        return {"kind": self.kind, "image": options_record(self.image),
                "joint_scales": np.asarray(params.joint_scales).tolist(),
                **{name: float(getattr(params, name)) for name in (
                    "pixel_noise", "outlier_rate", "swap_probability", "absent_probability")}}


def detection_observations(detections, *, grey: np.ndarray | None = None,
                           likelihood: Likelihood | None = None, masks: np.ndarray | None = None,
                           frame_size: tuple[float, float] | None = None,
                           dtype=np.float32) -> ImageObservation:
    """A video's observations for an image tracker with a :class:`DetectionLikelihood`: each
    frame's detected people (and, with ``grey``, its image channels as ``likelihood``
    observes them), every leaf with a leading ``time`` axis; track them with
    ``jaxtrack.trackers.track(tracker, key, observations, initial_pose)``.

    Args:
        detections: a :class:`jaxtrack.vision.detections.Detections` (its markers must include
            the tracker's 12, ``SPM_MARKERS``; its frames consecutive), or a
            :class:`~jaxtrack.likelihoods.detections.DetectionsFrame` with a time axis in
            ``SPM_MARKERS`` order.
        grey: ``(time, height, width)`` grey frames, for a density times an image likelihood.
        likelihood: the image likelihood ``grey`` is observed for (the
            :class:`DetectionLikelihood`'s ``image``; needed with ``grey``).
        masks: person masks for the image likelihood's coverage term.
        frame_size: ``(width, height)``; default the detections' own, else the frames'.
        dtype: the floating dtype of the detections' arrays.

    Raises:
        ValueError (one line): detections of the wrong type, shape or values, frames missing
        from the sequence, an unknown frame size, or frames that disagree with them.
    """
    from jaxtrack.vision.detections import Detections

    if isinstance(detections, Detections):
        name = detections.source or "detections"
        missing = [marker for marker in SPM_MARKERS if marker not in detections.markers]
        if missing:
            raise ValueError(f"{name}: the tracker's markers {', '.join(missing)} are not among "
                             f"the detections' ({', '.join(detections.markers)})")
        if len(detections.people) < 1:
            raise ValueError(f"{name} hold no frame")
        ids = np.asarray(detections.frame_ids)
        steps = np.diff(ids)
        if np.any(steps != 1):
            gap = int(np.argmax(steps != 1))
            raise ValueError(f"{name}: frames are missing or out of order between frame ids "
                             f"{ids[gap]} and {ids[gap + 1]}; give one entry per frame (an "
                             f"empty frame has people 0)")
        size = frame_size or detections.frame_size
        if size is None and grey is not None:
            size = (np.shape(grey)[-1], np.shape(grey)[-2])
        if size is None:
            raise ValueError(f"{name}: the frame size is unknown; pass frame_size=(width, "
                             f"height) in pixels")
        frames = detections_frames(detections, markers=SPM_MARKERS, frame_size=size)
    elif isinstance(detections, DetectionsFrame):
        frames = detections
    else:
        raise ValueError(f"detections must be a jaxtrack.vision.Detections or a "
                         f"DetectionsFrame, got {type(detections).__name__}")
    check_detections_frames(frames, len(SPM_MARKERS))
    frames = DetectionsFrame(np.asarray(frames.points, dtype),
                             np.asarray(frames.confidence, dtype),
                             np.asarray(frames.num_people, np.int32),
                             np.asarray(frames.image_size, dtype))
    count = frames.points.shape[0]
    if grey is None:
        if masks is not None:
            raise ValueError("masks are read by an image likelihood: give grey=... too")
        return ImageObservation(None, None, frames)
    if likelihood is None or isinstance(likelihood, DetectionLikelihood):
        raise ValueError("give likelihood=, the image likelihood the frames are observed for "
                         "(the DetectionLikelihood's image)")
    if np.shape(grey)[0] != count:
        raise ValueError(f"grey holds {np.shape(grey)[0]} frames, the detections {count}; give "
                         f"one detections frame per video frame")
    images = observe_images(likelihood, VideoChunk(grey=np.asarray(grey), masks=masks))
    height, width = np.shape(images.images)[-2:]
    if not np.allclose(np.asarray(frames.image_size), [width, height]):
        raise ValueError(f"the detections' frame size {tuple(frames.image_size[0])} is not the "
                         f"frames' ({width}, {height})")
    return ImageObservation(images.images, images.keypoints, frames)
