"""Learning a model's parameters by gradient ascent of the particle filter's log-evidence.

``log p̂(y_{1:T} | θ)`` is the filter's estimate of the log-evidence (``run(...).log_evidence``);
with a :class:`~jaxtrack.smc.StopGradient` resampler its gradient is the Fisher-identity
estimate of ∇ log p(y | θ) (Ścibior & Wood 2021; consistent in N, ``docs/engine.md``).
:func:`fit_log_evidence` ascends it with Adam (Kingma & Ba 2015, Algorithm 1), a fresh key per
iteration (stochastic gradient ascent), over any pytree of unconstrained parameters that
``build`` turns into a model. Only a normalised density may be learned so: an unnormalised
energy's log-evidence grows without bound as its sharpness does.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray, PyTree

from jaxtrack.smc._filter import filter_sequence
from jaxtrack.smc._model import StateSpaceModel
from jaxtrack.smc._resampling import Resampler, StopGradient, Systematic

__all__ = ["FitResult", "adam_update", "fit_log_evidence", "log_evidence_and_gradient"]


class FitResult(eqx.Module):
    """What :func:`fit_log_evidence` found.

    Attributes:
        params: the parameters after the last iteration (unconstrained, as given).
        log_evidence: ``(iterations,)`` the estimate at each iteration's parameters (before
            its step).
        gradient_norm: ``(iterations,)`` the norm of each iteration's gradient.
        seconds: wall time of the iterations (compilation excluded).
        compile_seconds: time to compile one iteration.
    """

    params: PyTree[Array]
    log_evidence: Float[Array, " iterations"]
    gradient_norm: Float[Array, " iterations"]
    seconds: float = eqx.field(static=True)
    compile_seconds: float = eqx.field(static=True)


def log_evidence_and_gradient(key: PRNGKeyArray, build: Callable[[PyTree], StateSpaceModel],
                              params: PyTree[Array], observations: PyTree[Any],
                              num_particles: int, *,
                              resampler: Resampler = StopGradient(Systematic()),
                              ess_threshold: float = 1.0) -> tuple[Array, PyTree[Array]]:
    """``(log p̂(y | θ), ∇_θ log p̂(y | θ))`` of the model ``build(params)`` by one filter run
    with ``key`` (the same key: common random numbers)."""
    def log_evidence(theta):
        return filter_sequence(key, build(theta), observations, num_particles,
                               resampler=resampler, ess_threshold=ess_threshold).log_evidence

    return jax.value_and_grad(log_evidence)(params)


def adam_update(gradient: PyTree[Array], moments: tuple, step: Array, learning_rate: float,
                b1: float = 0.9, b2: float = 0.999, eps: float = 1e-8
                ) -> tuple[PyTree[Array], tuple]:
    """One Adam step for *ascent* (Kingma & Ba 2015, Algorithm 1): ``(update, moments)``,
    ``step`` counting from 1, ``moments`` the running ``(m, v)`` (zeros at first)."""
    first, second = moments
    first = jax.tree.map(lambda m, g: b1 * m + (1 - b1) * g, first, gradient)
    second = jax.tree.map(lambda v, g: b2 * v + (1 - b2) * g * g, second, gradient)
    update = jax.tree.map(
        lambda m, v: learning_rate * (m / (1 - b1**step)) / (jnp.sqrt(v / (1 - b2**step)) + eps),
        first, second)
    return update, (first, second)


def fit_log_evidence(key: PRNGKeyArray, build: Callable[[PyTree], StateSpaceModel],
                     params: PyTree[Array], observations: PyTree[Any], num_particles: int, *,
                     iterations: int = 100, learning_rate: float = 0.05,
                     resampler: Resampler = StopGradient(Systematic()),
                     ess_threshold: float = 1.0, common_random_numbers: bool = False
                     ) -> FitResult:
    """Maximise the log-evidence of ``build(params)`` over ``params`` by Adam on the filter's
    gradient estimate.

    Args:
        key: PRNG key; iteration i runs the filter with ``fold_in(key, i)`` (or ``key`` itself
            every time with ``common_random_numbers``: a deterministic, biased objective).
        build: unconstrained parameters → a :class:`StateSpaceModel` (exp for scales, logistic
            for rates, …), traceable.
        params: the starting parameters (a pytree of float arrays).
        observations: a pytree with a leading ``time`` axis.
        num_particles: N per filter run.
        iterations: Adam steps.
        learning_rate: Adam's step size in the unconstrained parameters.
        resampler: the gradient estimator (default the consistent ``StopGradient``).
        ess_threshold: as :func:`~jaxtrack.smc.run`.

    Returns:
        A :class:`FitResult`.
    """
    if not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
    if not (np.isfinite(learning_rate) and learning_rate > 0):
        raise ValueError(f"learning_rate must be a positive number, got {learning_rate!r}")
    params = jax.tree.map(jnp.asarray, params)

    @eqx.filter_jit
    def iterate(params, moments, step, key):
        value, gradient = log_evidence_and_gradient(
            key, build, params, observations, num_particles, resampler=resampler,
            ess_threshold=ess_threshold)
        # a degenerate run (−inf evidence) gives no direction: skip its step
        finite = jnp.isfinite(value) & jnp.all(jnp.asarray(
            [jnp.all(jnp.isfinite(leaf)) for leaf in jax.tree.leaves(gradient)]))
        gradient = jax.tree.map(lambda g: jnp.where(finite, g, 0.0), gradient)
        update, moments = adam_update(gradient, moments, step, learning_rate)
        params = jax.tree.map(lambda p, u: p + u, params, update)
        norm = jnp.sqrt(sum(jnp.sum(g * g) for g in jax.tree.leaves(gradient)))
        return params, moments, value, norm

    zeros = jax.tree.map(jnp.zeros_like, params)
    moments = (zeros, zeros)
    tick = time.perf_counter()
    compiled = iterate.lower(params, moments, jnp.asarray(1.0), key).compile()
    compile_seconds = time.perf_counter() - tick
    values, norms = [], []
    tick = time.perf_counter()
    for index in range(iterations):
        run_key = key if common_random_numbers else jr.fold_in(key, index)
        params, moments, value, norm = compiled(params, moments, jnp.asarray(index + 1.0),
                                                run_key)
        values.append(value)
        norms.append(norm)
    values = jnp.stack(values)
    values.block_until_ready()
    return FitResult(params, values, jnp.stack(norms), time.perf_counter() - tick,
                     compile_seconds)
