"""Smoothers over a stored particle history (``run(..., keep_history=True)``).

- ``trace_ancestry``: the sequence-based smoother of Isard & Blake used by Kwatra et al.: each
  final particle carries its whole history (followed back through the ancestors), and estimates
  at every frame use the *final* weights. Cheap (O(T N)); degenerates far back in long
  sequences because few distinct ancestors survive.
- ``ffbsi``: forward-filtering backward-simulation (Godsill, Doucet & West 2004) for models with
  ``log_transition_density``: each trajectory is drawn backwards with weights
  w_t^i f(x_{t+1} | x_t^i).
  O(T N M) for M trajectories; no path degeneracy.

Both assume ``iterations_per_frame = 1`` (several cycles per frame are not a Markov transition
between frames).
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
from jax import lax
from jaxtyping import Array, Float, Int, PRNGKeyArray, PyTree

from jaxtrack.smc._filter import FilterResult, weighted_mean
from jaxtrack.smc._model import StateSpaceModel
from jaxtrack.smc._resampling import draw_indices


class SmoothedPaths(eqx.Module):
    """Whole trajectories and the weights to use at every frame."""

    paths: PyTree[Any]  # each leaf (time, paths, ...)
    log_weights: Float[Array, " paths"]  # normalised
    mean: PyTree[Any]  # (time, ...) weighted mean of float leaves / best path for integer leaves


def _require_history(result: FilterResult) -> None:
    if result.particles is None or result.ancestors is None:
        raise ValueError(
            "smoothing needs the particle history: run the filter with keep_history=True"
        )


@eqx.filter_jit
def trace_ancestry(result: FilterResult) -> SmoothedPaths:
    """Follow every final particle back through its ancestors (Isard & Blake's smoother)."""
    _require_history(result)
    num = result.log_weights.shape[-1]

    def back(indices, frame):
        particles_t, ancestors_t = frame
        path_t = jax.tree.map(lambda leaf: leaf[indices], particles_t)
        return ancestors_t[indices], path_t

    frames = (result.particles, result.ancestors)
    _, paths = lax.scan(back, jnp.arange(num, dtype=jnp.int32), frames, reverse=True)
    final = result.log_weights[-1]
    mean = jax.vmap(weighted_mean, in_axes=(0, None))(paths, final)
    return SmoothedPaths(paths, final, mean)


@eqx.filter_jit
def ffbsi(
    key: PRNGKeyArray, model: StateSpaceModel, result: FilterResult, num_paths: int
) -> SmoothedPaths:
    """Forward-filtering backward-simulation of ``num_paths`` trajectories (equal weights)."""
    _require_history(result)
    key_last, key_back = jr.split(key)
    num_frames = result.log_weights.shape[0]
    last = draw_indices(key_last, result.log_weights[-1], num_paths)

    def pick(particles, indices):
        return jax.tree.map(lambda leaf: leaf[indices], particles)

    def back(following, inputs):
        key, particles_t, log_weights_t, time = inputs

        def one_path(key, following_particle):
            transition = jax.vmap(model.log_transition_density, in_axes=(0, None, None))(
                particles_t, following_particle, time + 1
            )
            return jr.categorical(key, log_weights_t + transition)

        indices = jax.vmap(one_path)(jr.split(key, num_paths), following)
        chosen = pick(particles_t, indices)
        return chosen, chosen

    final_particles = jax.tree.map(lambda leaf: leaf[-1], result.particles)
    following = pick(final_particles, last)
    inputs = (
        jr.split(key_back, num_frames - 1),
        jax.tree.map(lambda leaf: leaf[:-1], result.particles),
        result.log_weights[:-1],
        jnp.arange(num_frames - 1),
    )
    _, earlier = lax.scan(back, following, inputs, reverse=True)
    paths = jax.tree.map(lambda head, tail: jnp.concatenate([head, tail[None]]), earlier, following)
    log_weights = jnp.full((num_paths,), -jnp.log(num_paths), dtype=result.log_weights.dtype)
    mean = jax.vmap(weighted_mean, in_axes=(0, None))(paths, log_weights)
    return SmoothedPaths(paths, log_weights, mean)


def discrete_marginals(
    labels: Int[Array, "time paths"], log_weights: Float[Array, " paths"], num_categories: int
) -> Float[Array, "time categories"]:
    """Per-frame probability of each category of an integer leaf of ``SmoothedPaths.paths``.

    Kwatra et al.'s MAP posture is ``argmax`` of this along the last axis.
    """
    weights = jax.nn.softmax(log_weights)
    one_hot = jax.nn.one_hot(labels, num_categories, dtype=weights.dtype)
    return jnp.einsum("p,tpk->tk", weights, one_hot)


class LaggedParticles(eqx.Module):
    """Fixed-lag smoothed particles: at every frame t, the particles of frame t + L followed
    back to t, with frame t + L's weights (the sequence's last frame's near its end)."""

    particles: PyTree[Any]  # each leaf (time, particles, ...)
    log_weights: Float[Array, "time particles"]  # normalised, frame min(t + L, T − 1)'s
    mean: PyTree[Any]  # (time, ...) weighted mean of float leaves


@eqx.filter_jit
def fixed_lag_ancestry(result: FilterResult, lag: int) -> LaggedParticles:
    """The fixed-lag smoother by ancestry (Kitagawa 1996, §4.2): frame t's estimate is read
    from the particles of frame t + ``lag`` followed back ``lag`` frames through their
    ancestors, weighted by frame t + ``lag``'s weights. A streaming tracker can report frame t
    once frame t + ``lag`` is filtered, holding the last ``lag`` frames' particles and
    ancestors (O(lag N) memory); ``lag`` 0 is the filter, ``lag`` ≥ T − 1 the whole-sequence
    smoother :func:`trace_ancestry`. Cost O(T lag N)."""
    _require_history(result)
    if not isinstance(lag, int) or lag < 0:
        raise ValueError(f"lag must be a non-negative integer, got {lag!r}")
    frames, num = result.log_weights.shape
    lag = min(lag, frames - 1)

    def at(time):
        source = jnp.minimum(time + lag, frames - 1)

        def back(step, indices):
            frame = source - step
            return jnp.where(frame > time, result.ancestors[frame][indices], indices)

        indices = lax.fori_loop(0, lag, back, jnp.arange(num, dtype=jnp.int32))
        particles = jax.tree.map(lambda leaf: leaf[time][indices], result.particles)
        return particles, result.log_weights[source]

    particles, log_weights = jax.vmap(at)(jnp.arange(frames))
    mean = jax.vmap(weighted_mean)(particles, log_weights)
    return LaggedParticles(particles, log_weights, mean)
