"""What the particle-filter trackers share: frame 0's SPM pose and templates, the engine's step
on a frame read from the chunk in place, and the per-frame report of a particle cloud."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPMTemplate, spm_initial_state
from jaxtrack.likelihoods import PartTemplates, check_markers, make_appearance_templates
from jaxtrack.trackers._options import Engine, Likelihood
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk

__all__ = ["check_initial_pose", "cloud_estimate", "filter_step", "first_info", "frame0_state",
           "frame0_templates", "initialize_filter"]


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
    first_frame = np.asarray(first_frame)
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
        return self.model.log_likelihood(particle, frames[index])


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

