"""The particle-filter engine: ``initialize``, ``step`` and ``run`` (one ``lax.scan`` over frames).

Each frame runs ``iterations_per_frame`` select → predict → measure cycles (CONDENSATION; Ong &
Gong ran several per frame). Selection is skipped where the effective sample size is still at
least ``ess_threshold × N`` (adaptive resampling; ``ess_threshold = 1`` always resamples,
``0`` never). The first frame is measured directly on particles drawn from ``model.init``.
A model may propose instead (``StateSpaceModel``'s ``propose`` and ``init_propose``): its
particles then come from a proposal that may look at the frame's observation, and their
weights carry the proposal's log-weight corrections.

A frame where every weight is zero (all log-likelihoods −∞ or NaN) is *degenerate*: the info
reports it, the particles are re-drawn from ``model.init`` (or ``model.init_propose``, given
the frame's observation) and re-weighted by the same frame,
and the filter goes on instead of producing NaN. Its log-evidence increment is −∞, which is the
estimate (the frame is impossible under every particle), not a numerical failure, and its ESS
is reported as 0 (no particle carried any weight into the frame), not the ESS of the re-seeded
set, which would read as a healthy N.
"""

from __future__ import annotations

import math
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, Bool, Float, Int, PRNGKeyArray, PyTree

from jaxtrack.smc._cond import cond_any
from jaxtrack.smc._model import StateSpaceModel, check_observation_shape, defines
from jaxtrack.smc._random import particle_keys, split
from jaxtrack.smc._resampling import Resampler, Systematic, effective_sample_size


class FilterState(eqx.Module):
    """What the filter carries from frame to frame."""

    particles: PyTree[Any]  # each leaf (particles, ...)
    log_weights: Float[Array, " particles"]  # normalised
    time: Int[Array, ""]  # frame index the particles belong to
    log_evidence: Float[Array, ""]  # log p(y_0..y_time), running


class StepInfo(eqx.Module):
    """What one frame reports."""

    log_evidence_increment: Float[Array, ""]  # log p(y_t | y_0..y_{t-1})
    ess: Float[Array, ""]  # effective sample size after measuring; 0 on a degenerate frame
    resampled: Bool[Array, ""]  # any cycle of the frame resampled
    degenerate: Bool[Array, ""]  # every weight was zero; particles re-seeded from init
    num_invalid: Int[Array, ""]  # particles whose log-likelihood was NaN (treated as −∞)
    ancestors: Int[Array, " particles"]  # parent of each particle in the previous frame


class FilterResult(eqx.Module):
    """The outputs of ``run`` for one sequence (leading axis ``time`` on every per-frame field)."""

    log_evidence: Float[Array, ""]
    log_evidence_increments: Float[Array, " time"]
    ess: Float[Array, " time"]
    resampled: Bool[Array, " time"]
    degenerate: Bool[Array, " time"]
    num_invalid: Int[Array, " time"]
    mean: PyTree[Any]  # weighted mean of float leaves; best particle's value for integer leaves
    best: PyTree[Any]  # the particle of largest weight
    particles: PyTree[Any] | None = None  # with keep_history: (time, particles, ...)
    log_weights: Float[Array, "time particles"] | None = None
    ancestors: Int[Array, "time particles"] | None = None


def _gather(particles: PyTree[Any], indices: Int[Array, " particles"]) -> PyTree[Any]:
    return jax.tree.map(lambda leaf: leaf[indices], particles)


def weighted_mean(particles: PyTree[Any], log_weights: Float[Array, " particles"]) -> PyTree[Any]:
    """Weighted mean of each floating leaf; integer/bool leaves take the best particle's value."""
    weights = jax.nn.softmax(log_weights)
    best = jnp.argmax(log_weights)

    def mean(leaf):
        if jnp.issubdtype(leaf.dtype, jnp.inexact):
            return jnp.tensordot(weights.astype(leaf.dtype), leaf, axes=1)
        return leaf[best]

    return jax.tree.map(mean, particles)


def best_particle(particles: PyTree[Any], log_weights: Float[Array, " particles"]) -> PyTree[Any]:
    """The particle of largest weight."""
    return _gather(particles, jnp.argmax(log_weights))


def _log_likelihoods(model, particles, observation):
    values = jax.vmap(model.log_likelihood, in_axes=(0, None))(particles, observation)
    invalid = jnp.isnan(values)
    return jnp.where(invalid, -jnp.inf, values), jnp.sum(invalid, dtype=jnp.int32)


def _corrections(values):
    """A proposal's log-weight corrections, NaN as −∞ (weight zero), and how many were NaN."""
    invalid = jnp.isnan(values)
    return jnp.where(invalid, -jnp.inf, values), jnp.sum(invalid, dtype=jnp.int32)


def _init_particles(key, model, num_particles, observation):
    """Frame 0's particles from ``init``, or from ``init_propose`` with their log-weight
    corrections and count of NaN corrections (``None`` and 0 without the hook)."""
    keys = particle_keys(key, num_particles)
    if defines(model, "init_propose"):
        particles, corrections = jax.vmap(model.init_propose, in_axes=(0, None))(keys,
                                                                                observation)
        return particles, *_corrections(corrections)
    return jax.vmap(model.init)(keys), None, 0


def _measure(key, model, particles, prior_log_weights, observation, axis_name):
    """Weight particles by one observation; re-seed from ``init`` (or ``init_propose``) if
    every weight is zero. ``prior_log_weights`` already hold any proposal's corrections."""
    log_likelihoods, num_invalid = _log_likelihoods(model, particles, observation)
    unnormalised = prior_log_weights + log_likelihoods
    increment = jax.nn.logsumexp(unnormalised)
    degenerate = ~jnp.isfinite(increment)
    num = prior_log_weights.shape[0]

    def reseed(operands):
        key, model, particles, observation, unnormalised, increment, degenerate = operands
        fresh, corrections, _ = _init_particles(key, model, num, observation)
        fresh_log_likelihoods, _ = _log_likelihoods(model, fresh, observation)
        if corrections is not None:
            fresh_log_likelihoods = fresh_log_likelihoods + corrections
        fresh_log_weights = fresh_log_likelihoods - jax.nn.logsumexp(fresh_log_likelihoods)
        uniform = jnp.full_like(unnormalised, -math.log(num))
        fresh_log_weights = jnp.where(
            jnp.isfinite(jax.nn.logsumexp(fresh_log_likelihoods)), fresh_log_weights, uniform
        )
        keep = lambda new, old: jnp.where(  # noqa: E731
            jnp.reshape(degenerate, (1,) * new.ndim), new, old
        )
        normalised = jnp.where(degenerate, 0.0, unnormalised - increment)
        return jax.tree.map(keep, fresh, particles), keep(fresh_log_weights, normalised)

    def keep_going(operands):
        _, _, particles, _, unnormalised, increment, _ = operands
        return particles, unnormalised - increment

    # Under vmap over sequences the re-seeding runs only on frames where some sequence needs
    # it (cond_any; a plain lax.cond would become a select and re-seed on every frame). The
    # branches take everything as operands: cond_any's batching rule must see what is batched.
    if axis_name is not None:
        degenerate_somewhere = lax.psum(degenerate.astype(jnp.int32), axis_name) > 0
    else:
        degenerate_somewhere = degenerate
    operands = (key, model, particles, observation, unnormalised, increment, degenerate)
    particles, log_weights = cond_any(degenerate_somewhere, reseed, keep_going, operands)
    return particles, log_weights, increment, degenerate, num_invalid


def _reported_ess(log_weights: Float[Array, " particles"], degenerate: Bool[Array, ""]
                  ) -> Float[Array, ""]:
    """The frame's ESS, 0 where the frame was degenerate (its particles were re-seeded)."""
    ess = effective_sample_size(log_weights)
    return jnp.where(degenerate, jnp.zeros_like(ess), ess)


def initialize(
    key: PRNGKeyArray,
    model: StateSpaceModel,
    observation: PyTree[Any],
    num_particles: int,
    *,
    axis_name: str | None = None,
) -> tuple[FilterState, StepInfo]:
    """Draw ``num_particles`` from ``model.init`` (or ``model.init_propose``, given the first
    observation, with its log-weight corrections) and weight them by the first observation."""
    if not isinstance(num_particles, int) or num_particles < 1:
        raise ValueError(f"num_particles must be a positive int, got {num_particles!r}")
    check_observation_shape(model, observation, time_axis=False)
    key_init, key_reseed = split(key)
    particles, corrections, invalid_corrections = _init_particles(key_init, model,
                                                                  num_particles, observation)
    prior = jnp.full((num_particles,), -math.log(num_particles))
    if corrections is not None:
        prior = prior + corrections
    particles, log_weights, increment, degenerate, num_invalid = _measure(
        key_reseed, model, particles, prior, observation, axis_name
    )
    if corrections is not None:
        num_invalid = num_invalid + invalid_corrections
    state = FilterState(particles, log_weights, jnp.asarray(0, jnp.int32), increment)
    info = StepInfo(
        increment, _reported_ess(log_weights, degenerate), jnp.asarray(False), degenerate,
        num_invalid, jnp.arange(num_particles, dtype=jnp.int32),
    )
    return state, info


def _check_threshold(ess_threshold: float) -> None:
    if not 0.0 <= ess_threshold <= 1.0:
        raise ValueError(f"ess_threshold must lie in [0, 1], got {ess_threshold}")


def step(
    key: PRNGKeyArray,
    state: FilterState,
    observation: PyTree[Any],
    model: StateSpaceModel,
    *,
    resampler: Resampler = Systematic(),
    ess_threshold: float = 1.0,
    iterations_per_frame: int = 1,
    axis_name: str | None = None,
) -> tuple[FilterState, StepInfo]:
    """Advance the filter by one frame: ``iterations_per_frame`` select/predict/measure cycles.

    Predict draws from ``model.propose`` with its log-weight corrections where the model
    defines it (``StateSpaceModel``'s docstring), from ``model.propagate`` otherwise.

    Args:
        key: PRNG key for this frame.
        state: the filter state at frame ``state.time``.
        observation: the observation of frame ``state.time + 1`` (a pytree, no time axis).
        model: the state-space model.
        resampler: selection scheme and gradient estimator (see ``jaxtrack.smc.Resampler``).
        ess_threshold: resample when ESS < ess_threshold × N (1: always, 0: never).
        iterations_per_frame: cycles per frame; > 1 refines on the same frame (Ong & Gong used
            5) and the log evidence then reports the first cycle's increment only.
        axis_name: name of an enclosing ``vmap`` axis over sequences (set by ``run_batch``).

    Returns:
        The state at frame ``state.time + 1`` and the frame's ``StepInfo``.
    """
    _check_threshold(ess_threshold)
    if iterations_per_frame < 1:
        raise ValueError(f"iterations_per_frame must be >= 1, got {iterations_per_frame}")
    check_observation_shape(model, observation, time_axis=False)
    num = state.log_weights.shape[0]
    time = state.time + 1
    identity = jnp.arange(num, dtype=jnp.int32)
    proposes = defines(model, "propose")

    def select(key, log_weights):
        """(ancestors, carried log weights, resampled?) for the three threshold regimes."""
        if ess_threshold <= 0.0:
            return identity, log_weights, jnp.asarray(False)
        ancestors, carried = resampler(key, log_weights)
        if ess_threshold >= 1.0:
            return ancestors, carried, jnp.asarray(True)
        resample = effective_sample_size(log_weights) < ess_threshold * num
        return (jnp.where(resample, ancestors, identity), jnp.where(resample, carried, log_weights),
                resample)

    def cycle(carry, key):
        particles, log_weights, ancestors_so_far, resampled_so_far = carry
        key_select, key_propagate, key_reseed = split(key, 3)
        ancestors, carried, resample = select(key_select, log_weights)
        parents = _gather(particles, ancestors)
        keys = particle_keys(key_propagate, num)
        if proposes:
            children, corrections = jax.vmap(model.propose, in_axes=(0, 0, None, None))(
                keys, parents, time, observation
            )
            corrections, invalid_corrections = _corrections(corrections)
            carried = carried + corrections
        else:
            children = jax.vmap(model.propagate, in_axes=(0, 0, None))(keys, parents, time)
        children, log_weights, increment, degenerate, num_invalid = _measure(
            key_reseed, model, children, carried, observation, axis_name
        )
        if proposes:
            num_invalid = num_invalid + invalid_corrections
        carry = (children, log_weights, ancestors_so_far[ancestors], resampled_so_far | resample)
        return carry, (increment, degenerate, num_invalid)

    keys = split(key, iterations_per_frame)
    carry = (state.particles, state.log_weights, identity, jnp.asarray(False))
    if iterations_per_frame == 1:
        carry, outputs = cycle(carry, keys[0])
        outputs = jax.tree.map(lambda x: x[None], outputs)
    else:
        carry, outputs = lax.scan(cycle, carry, keys)
    particles, log_weights, ancestors, resampled = carry
    increments, degenerate, num_invalid = outputs
    increment = increments[0]
    degenerate = jnp.any(degenerate)
    info = StepInfo(
        increment, _reported_ess(log_weights, degenerate), resampled, degenerate,
        jnp.sum(num_invalid, dtype=jnp.int32), ancestors,
    )
    new_state = FilterState(particles, log_weights, time, state.log_evidence + increment)
    return new_state, info


def _num_frames(observations: PyTree[Any]) -> int:
    leaves = jax.tree.leaves(observations)
    if not leaves:
        raise ValueError("observations is empty: expected arrays with a leading time axis")
    lengths = {jnp.shape(leaf)[0] if jnp.ndim(leaf) else None for leaf in leaves}
    if len(lengths) != 1 or None in lengths:
        raise ValueError(
            "every observation leaf needs the same leading time axis; got leading sizes "
            f"{sorted(str(n) for n in lengths)}"
        )
    (length,) = lengths
    if length < 1:
        raise ValueError("observations have zero frames")
    return length


def filter_sequence(
    key: PRNGKeyArray,
    model: StateSpaceModel,
    observations: PyTree[Any],
    num_particles: int,
    *,
    resampler: Resampler = Systematic(),
    ess_threshold: float = 1.0,
    iterations_per_frame: int = 1,
    keep_history: bool = False,
    axis_name: str | None = None,
) -> FilterResult:
    """``run`` without ``jit``: the traceable body, for use inside a caller's own transformation."""
    num_frames = _num_frames(observations)
    check_observation_shape(model, observations, time_axis=True)
    key_init, key_frames = split(key)
    first = jax.tree.map(lambda leaf: leaf[0], observations)
    rest = jax.tree.map(lambda leaf: leaf[1:], observations)
    state, info = initialize(key_init, model, first, num_particles, axis_name=axis_name)

    def record(state, info):
        summary = (
            info.log_evidence_increment, info.ess, info.resampled, info.degenerate,
            info.num_invalid, weighted_mean(state.particles, state.log_weights),
            best_particle(state.particles, state.log_weights),
        )
        if keep_history:
            summary += (state.particles, state.log_weights, info.ancestors)
        return summary

    def body(state, inputs):
        key, observation = inputs
        state, info = step(
            key, state, observation, model, resampler=resampler, ess_threshold=ess_threshold,
            iterations_per_frame=iterations_per_frame, axis_name=axis_name,
        )
        return state, record(state, info)

    first_record = record(state, info)
    state, records = lax.scan(body, state, (split(key_frames, num_frames - 1), rest))
    records = jax.tree.map(
        lambda head, tail: jnp.concatenate([head[None], tail]), first_record, records
    )
    return FilterResult(state.log_evidence, *records)


@eqx.filter_jit
def _run_jit(key, model, observations, num_particles, **options):
    return filter_sequence(key, model, observations, num_particles, **options)


def run(
    key: PRNGKeyArray,
    model: StateSpaceModel,
    observations: PyTree[Any],
    num_particles: int,
    *,
    resampler: Resampler = Systematic(),
    ess_threshold: float = 1.0,
    iterations_per_frame: int = 1,
    keep_history: bool = False,
    mesh: jax.sharding.Mesh | None = None,
) -> FilterResult:
    """Run the particle filter over a whole sequence as one compiled ``lax.scan``.

    Args:
        key: PRNG key (with ``mesh``: a batch of keys, one per sequence).
        model: a ``StateSpaceModel``.
        observations: pytree of arrays with a leading ``time`` axis (with ``mesh``: leading
            ``(sequences, time)`` axes).
        num_particles: N, a Python int (static).
        resampler: selection scheme and gradient estimator; default ``Systematic()``.
        ess_threshold: resample when ESS < ess_threshold × N (1: every frame, CONDENSATION).
        iterations_per_frame: select/predict/measure cycles per frame.
        keep_history: also return particles, log weights and ancestors of every frame
            (memory: time × N × state size).
        mesh: a ``jax.sharding.Mesh``; the batch of sequences is split over its first axis
            (see ``run_batch``).

    Returns:
        ``FilterResult`` (with ``mesh``: every field gains a leading ``sequences`` axis).
    """
    options = dict(
        resampler=resampler, ess_threshold=ess_threshold,
        iterations_per_frame=iterations_per_frame, keep_history=keep_history,
    )
    if mesh is not None:
        from jaxtrack.smc._batch import run_batch

        return run_batch(key, model, observations, num_particles, mesh=mesh, **options)
    _check_threshold(ess_threshold)
    _num_frames(observations)
    check_observation_shape(model, observations, time_axis=True)
    return _run_jit(key, model, observations, num_particles, **options)
