"""The tracker contract: every tracker, whatever its state, starts, updates and reports alike.

    start(key, first_frame, initial_pose) -> state                 (frame 0, on the host)
    update(key, state, frame)             -> (state, FrameEstimate) (every later frame, pure)
    first_estimate(state)                 -> FrameEstimate          (frame 0's report)

``start`` runs once per sequence, outside compiled code: it cuts the appearance templates from
the first frame at the initial pose and solves for whatever the tracker's state needs (the
latent tracker's μ⁻¹ runs in the prior's float64 there). ``update`` is a pure function of
arrays that :func:`jaxtrack.trackers.track` scans over chunks of frames; its ``frame`` may be an
array or a :class:`FrameInChunk`, the chunk and an index into it, so that a tracker reads its
pixels from the chunk in place instead of copying each frame out (:func:`frame_at`).

Every tracker also says how many particles (or modes) it runs (``num_particles``), which
likelihood it scores frames with (``likelihood``: which observations a frame needs) and what
produced it (``options()``: a JSON-able record written into every result file).
See ``docs/trackers.md``.
"""

# no `from __future__ import annotations`: equinox reads AbstractVar from the live annotation
import abc

import equinox as eqx
from jaxtyping import Array, ArrayLike, Float, Int, PRNGKeyArray

__all__ = ["FrameEstimate", "FrameInChunk", "Tracker", "frame_at"]


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
    """``frames[index]``, not cut out of ``frames`` (see the module docstring)."""

    frames: Float[Array, "time ..."]
    index: Int[Array, ""]


def frame_at(frame: Float[ArrayLike, "..."] | FrameInChunk) -> Float[Array, "..."]:
    """The frame an ``update`` was given (a slice of the chunk for a :class:`FrameInChunk`)."""
    if isinstance(frame, FrameInChunk):
        return frame.frames[frame.index]
    return frame


class Tracker(eqx.Module):
    """The contract every tracker implements (module docstring).

    Subclasses declare ``likelihood`` (a :class:`jaxtrack.trackers.Likelihood`) and implement
    the four methods below; nothing else of a tracker is known to the runner.
    """

    likelihood: eqx.AbstractVar[object]

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
