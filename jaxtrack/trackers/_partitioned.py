"""Partitioned sampling (MacCormick & Isard, ECCV 2000) for the latent tracker on a prior with
one latent space per body part (:class:`~jaxtrack.priors.gplvm.PartsGPLVM`).

With a whole-body likelihood, one sharp term (the waving arm's strips) decides which particles
survive a frame, and the parts it does not see (the other arm) drift with whatever those
particles carry. Partitioned sampling moves one part at a time and resamples by the likelihood
terms of that part before the next one moves: the torso (its latent dimensions and the
placement) is drawn and weighted by the head, spine and hip strips, then the right arm by its
two strips, then the left arm by its two strips and the shoulder line (which needs both
shoulders). The likelihood is the product of its strips' terms, so after the last stage the
particles are weighted by the whole likelihood, as one CONDENSATION step would weight them; the
difference is that each part was selected by its own evidence.

A frame's log evidence increment is the sum of the stages' (each stage's particles are
resampled to equal weights before it); its ESS is the last stage's. A stage in which every
particle has zero likelihood keeps its particles with equal weights and flags the frame
degenerate (the whole-body engine re-seeds from the initial cloud instead).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.likelihoods import LIMB_SEGMENTS
from jaxtrack.trackers._tracker import FrameInChunk, frame_at

__all__ = ["STAGE_STRIPS", "Stage", "partitioned_step", "stages_of"]

STAGE_STRIPS: dict[str, tuple[str, ...]] = {
    "torso": ("head", "upper spine", "lower spine", "hips"),
    "right_arm": ("right upper arm", "right forearm and hand"),
    "left_arm": ("left upper arm", "left forearm and hand", "shoulders"),
}
"""Per part of ``UPPER_BODY_PARTS`` (in that order), the strips of ``LIMB_SEGMENTS`` that weigh
it: each strip in the first stage at which every marker it joins is placed."""


class Stage(eqx.Module):
    """One part's stage: which latent dimensions move, whether the placement moves with them,
    and the strips (indices into ``LIMB_SEGMENTS``) that weigh them."""

    dims: tuple[int, ...] = eqx.field(static=True)
    strips: tuple[int, ...] = eqx.field(static=True)
    placement: bool = eqx.field(static=True)


def stages_of(prior) -> tuple[Stage, ...]:
    """The stages of a :class:`~jaxtrack.priors.gplvm.PartsGPLVM` whose parts are
    ``UPPER_BODY_PARTS`` (torso, right arm, left arm), in that order; a ValueError otherwise."""
    names = tuple(getattr(prior, "names", ()))
    if names != tuple(STAGE_STRIPS):
        raise ValueError(f"partitioned sampling needs a PartsGPLVM with the parts "
                         f"{tuple(STAGE_STRIPS)} (train_prior(..., parts=UPPER_BODY_PARTS)), "
                         f"got {names or type(prior).__name__}")
    strip_index = {segment[0]: index for index, segment in enumerate(LIMB_SEGMENTS)}
    offsets = np.cumsum([0] + [part.latent_dim for part in prior.parts])
    return tuple(Stage(dims=tuple(range(int(offsets[k]), int(offsets[k + 1]))),
                       strips=tuple(strip_index[name] for name in STAGE_STRIPS[part]),
                       placement=k == 0)
                 for k, part in enumerate(names))


def _move(walk, key: PRNGKeyArray, particle: dict, stage: Stage) -> dict:
    """The latent walk (eq. 6, with jumps to training latents) on the stage's dimensions only,
    and the placement's walk in the stage that carries it (``LatentWalk.move``)."""
    return walk.move(key, particle, stage.dims, stage.placement)


def partitioned_step(key: PRNGKeyArray, state: smc.FilterState, frame: Array | FrameInChunk,
                     model, stages: tuple[Stage, ...], resampler: smc.Resampler
                     ) -> tuple[smc.FilterState, smc.StepInfo]:
    """One frame of partitioned sampling over ``stages`` (module docstring) for the latent
    tracker's ``model`` (a :class:`~jaxtrack.trackers.latent.LatentModel`).

    Every stage resamples (``resampler``), moves its part and weighs it by its strips."""
    observation = frame_at(frame)
    num = state.log_weights.shape[0]
    particles, log_weights = state.particles, state.log_weights
    lineage = jnp.arange(num, dtype=jnp.int32)
    increment = jnp.zeros((), log_weights.dtype)
    degenerate = jnp.asarray(False)
    num_invalid = jnp.zeros((), jnp.int32)
    for stage, stage_key in zip(stages, jax.random.split(key, len(stages)), strict=True):
        key_select, key_move = jax.random.split(stage_key)
        ancestors, carried = resampler(key_select, log_weights)
        particles = jax.tree.map(lambda leaf, a=ancestors: leaf[a], particles)
        lineage = lineage[ancestors]
        particles = jax.vmap(lambda k, p, s=stage: _move(model.walk, k, p, s))(
            jax.random.split(key_move, num), particles)

        def weigh(particle, s=stage):
            terms = model.templates.part_log_likelihoods(
                model.markers_of(particle), observation, model.sharpness, model.nearest,
                s.strips)
            return jnp.sum(terms)

        log_likelihood = jax.vmap(weigh)(particles)
        invalid = jnp.isnan(log_likelihood)
        num_invalid = num_invalid + jnp.sum(invalid, dtype=jnp.int32)
        weighted = carried + jnp.where(invalid, -jnp.inf, log_likelihood)
        total = jax.nn.logsumexp(weighted)
        lost = ~jnp.isfinite(total)
        degenerate = degenerate | lost
        increment = increment + jnp.where(lost, -jnp.inf, total - jax.nn.logsumexp(carried))
        log_weights = jnp.where(lost, jnp.full_like(weighted, -jnp.log(num)),
                                weighted - total)
    ess = jnp.where(degenerate, 0.0, smc.effective_sample_size(log_weights))
    info = smc.StepInfo(increment, ess.astype(log_weights.dtype), jnp.asarray(True), degenerate,
                        num_invalid, lineage)
    new_state = smc.FilterState(particles, log_weights, state.time + 1,
                                state.log_evidence + increment)
    return new_state, info
