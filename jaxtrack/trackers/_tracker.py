"""The tracker contract: every tracker, whatever its state, starts, updates and reports alike.

    observe(chunk)                        -> observations           (a chunk of video, host)
    start(key, first_frame, initial_pose) -> state                 (frame 0, on the host)
    update(key, state, frame)             -> (state, FrameEstimate) (every later frame, pure)
    first_estimate(state)                 -> FrameEstimate          (frame 0's report)
    smooth(estimates)                     -> FrameEstimate or None  (optional, offline)

``observe`` turns a :class:`VideoChunk` (the frames as a video gives them: grey, colour, the
person's masks, a detector's keypoints, a static background) into the tracker's own
observations: a pytree (an ``eqx.Module``) whose leaves have a leading ``time`` axis, holding
what its likelihood reads (image channels, silhouette features and nearest-point maps, contour
normals, keypoints). It runs on the host, with OpenCV, chunk by chunk; :attr:`Tracker.reads`
names the fields of the chunk it needs, so that a pipeline prepares only those.
``start`` runs once per sequence, outside compiled code: it cuts the appearance templates from
the first frame at the initial pose and solves for whatever the tracker's state needs (the
latent tracker's μ⁻¹ runs in the prior's float64 there). ``update`` is a pure function of
arrays that :func:`jaxtrack.trackers.track` scans over chunks of frames; its ``frame`` may be an
array or a :class:`FrameInChunk`, the chunk and an index into it, so that a tracker reads its
pixels from the chunk in place instead of copying each frame out (:func:`frame_at`).

Every tracker also says how many particles (or modes) it runs (``num_particles``), which
likelihood it scores frames with (``likelihood``: which observations a frame needs) and what
produced it (``options()``: a JSON-able record written into every result file). A tracker with
a whole-sequence smoother gives the smoothed estimate of every frame from what ``update``
reported (``smooth``: the per-frame estimates ``track()`` collected, a leading ``time`` axis on
every leaf); the others return None, and an offline pipeline reports the filter's estimate.
See ``docs/trackers.md``.
"""

# no `from __future__ import annotations`: equinox reads AbstractVar from the live annotation
import abc
from dataclasses import dataclass

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int, PRNGKeyArray, PyTree

__all__ = ["FrameEstimate", "FrameInChunk", "Tracker", "VideoChunk", "frame_at"]

VIDEO_FIELDS = ("grey", "colour", "masks", "keypoints", "background")
"""What a :class:`VideoChunk` may hold, the names :attr:`Tracker.reads` uses."""


@dataclass(frozen=True)
class VideoChunk:
    """Consecutive frames of a video as a pipeline prepares them (NumPy, on the host).

    Attributes:
        grey: ``(time, height, width)`` grey frames (floats in [0, 1] or uint8), or, for the
            image trackers, frames they observed already (``(time, 3 or 4, height, width)``
            edge maps).
        colour: ``(time, height, width, 3)`` uint8 RGB frames.
        masks: ``(time, height, width)`` bool person masks (silhouettes).
        keypoints: a detector's ``(points (time, 12, 2), confidence (time, 12))``.
        background: ``(height, width, 3)`` uint8 RGB empty scene of a static camera.
    """

    grey: np.ndarray | None = None
    colour: np.ndarray | None = None
    masks: np.ndarray | None = None
    keypoints: tuple[np.ndarray, np.ndarray] | None = None
    background: np.ndarray | None = None

    def __len__(self) -> int:
        for value in (self.grey, self.colour, self.masks):
            if value is not None:
                return int(np.shape(value)[0])
        if self.keypoints is not None:
            return int(np.shape(self.keypoints[0])[0])
        raise ValueError("the video chunk holds no frames (no grey, colour, masks or keypoints)")

    def frames(self, begin: int, end: int) -> "VideoChunk":
        """Frames ``begin:end`` (the background is the scene's, shared)."""
        cut = lambda value: None if value is None else value[begin:end]  # noqa: E731
        keypoints = None if self.keypoints is None else tuple(
            values[begin:end] for values in self.keypoints)
        return VideoChunk(cut(self.grey), cut(self.colour), cut(self.masks), keypoints,
                          self.background)

    def require(self, fields: tuple[str, ...], method: str) -> None:
        """Refuse (ValueError, one line) unless every one of ``fields`` is given."""
        missing = [name for name in fields if getattr(self, name) is None]
        if missing:
            raise ValueError(f"the {method} tracker reads the video's {' and '.join(missing)}: "
                             f"give {', '.join(name + '=...' for name in missing)}")


class FrameEstimate(eqx.Module):
    """What a tracker reports for one frame.

    Attributes:
        markers: ``(markers, 2)`` the tracker's estimate (pixels).
        best_markers: ``(markers, 2)`` the single best hypothesis.
        ess: effective sample size (number of modes for MHT).
        log_likelihood: the frame's log evidence increment log p(z_t | z_<t) for particle
            filters; the best hypothesis's log-likelihood for MHT.
        degenerate: every hypothesis had zero likelihood (the tracker re-seeded).
    """

    markers: Float[Array, "markers 2"]
    best_markers: Float[Array, "markers 2"]
    ess: Float[Array, ""]
    log_likelihood: Float[Array, ""]
    degenerate: Array


class FrameInChunk(eqx.Module):
    """``frames[index]``, not cut out of ``frames`` (see the module docstring); ``frames`` is
    a chunk of observations, a pytree whose leaves have a leading ``time`` axis."""

    frames: PyTree[Float[Array, "time ..."]]
    index: Int[Array, ""]


def frame_at(frame) -> PyTree[Array]:
    """The frame an ``update`` was given (every leaf of the chunk indexed, for a
    :class:`FrameInChunk`)."""
    if isinstance(frame, FrameInChunk):
        return jax.tree.map(lambda leaf: leaf[frame.index], frame.frames)
    return frame


class Tracker(eqx.Module):
    """The contract every tracker implements (module docstring).

    Subclasses declare ``likelihood`` (what scores a frame), say which fields of a
    :class:`VideoChunk` they read (:attr:`reads`) and implement the methods below; nothing
    else of a tracker is known to the runner.
    """

    likelihood: eqx.AbstractVar[object]

    @property
    @abc.abstractmethod
    def reads(self) -> tuple[str, ...]:
        """The fields of a :class:`VideoChunk` that :meth:`observe` needs (of
        :data:`VIDEO_FIELDS`)."""

    @abc.abstractmethod
    def observe(self, chunk: VideoChunk, out=None):
        """The observations of ``chunk``'s frames: a pytree whose leaves have a leading
        ``time`` axis (NumPy; on the host). ``out``: an earlier result's structure of
        buffers, at least as long, that may be written into (or ignored)."""

    @property
    @abc.abstractmethod
    def num_particles(self) -> int:
        """Particles (or modes) per frame."""

    @abc.abstractmethod
    def start(self, key: PRNGKeyArray, first_frame: Float[ArrayLike, "..."],
              initial_pose: Float[ArrayLike, "markers 2"]):
        """The state at frame 0, given its observation and its ``(markers, 2)`` pose."""

    @abc.abstractmethod
    def first_estimate(self, state) -> FrameEstimate:
        """Frame 0's report (the initial pose, as the tracker holds it)."""

    @abc.abstractmethod
    def update(self, key: PRNGKeyArray, state, frame: "Float[Array, '...'] | FrameInChunk"
               ) -> tuple[object, FrameEstimate]:
        """The state at the next frame and that frame's estimate (pure; jit and scan it)."""

    @abc.abstractmethod
    def options(self) -> dict:
        """A JSON-able record of the method and every option that produced it."""

    def smooth(self, estimates: FrameEstimate) -> FrameEstimate | None:
        """Every frame's estimate given the whole sequence, from the per-frame estimates
        :func:`jaxtrack.trackers.track` collected (``TrackResult.estimates``: a leading
        ``time`` axis on every leaf); None where the tracker has no smoother (this default)."""
        return None
