"""Linear-Gaussian state-space model and its exact Kalman filter / RTS smoother (the reference).

x_0 ~ N(m_0, P_0),  x_t = F x_{t-1} + w_t, w_t ~ N(0, Q),  y_t = H x_t + v_t, v_t ~ N(0, R).

The first observation is of x_0 (no transition before it), matching the particle filter.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr
import jax.scipy.linalg as jsl
from jax import lax
from jaxtyping import Array, Float, PRNGKeyArray

from jaxtrack.smc._model import StateSpaceModel, check_observation_shape
from jaxtrack.smc._random import fast_normal


def _mvn_log_density(residual, cholesky):
    """log N(residual; 0, L Lᵀ) for one vector.

    L⁻¹ is formed explicitly: it depends only on the model, so under the engine's vmap over
    particles it is computed once per frame and each particle costs one matvec; a batched
    triangular solve per particle was 3x slower on CPU.
    """
    identity = jnp.eye(cholesky.shape[0], dtype=cholesky.dtype)
    # residual @ L⁻ᵀ == L⁻¹ residual, written vector-times-matrix so that, vmapped over
    # particles, the particle axis stays the leading axis of the product (docs/engine.md,
    # "Speed")
    solved = residual @ jsl.solve_triangular(cholesky, identity, lower=True).T
    log_det = 2.0 * jnp.sum(jnp.log(jnp.diagonal(cholesky)))
    dim = residual.shape[-1]
    return -0.5 * (jnp.dot(solved, solved) + log_det + dim * math.log(2.0 * math.pi))


class LinearGaussian(StateSpaceModel):
    """Linear-Gaussian model with dense matrices; all fields are differentiable arrays.

    Noise comes from ``fast_normal`` (threefry ``jax.random.normal`` for float64).
    """

    transition_matrix: Float[Array, "state state"]
    transition_covariance: Float[Array, "state state"]
    observation_matrix: Float[Array, "observation state"]
    observation_covariance: Float[Array, "observation observation"]
    initial_mean: Float[Array, " state"]
    initial_covariance: Float[Array, "state state"]

    def __check_init__(self):
        dim = self.transition_matrix.shape[0]
        shapes = {
            "transition_matrix": (self.transition_matrix.shape, (dim, dim)),
            "transition_covariance": (self.transition_covariance.shape, (dim, dim)),
            "initial_mean": (self.initial_mean.shape, (dim,)),
            "initial_covariance": (self.initial_covariance.shape, (dim, dim)),
            "observation_matrix": (
                self.observation_matrix.shape, (self.observation_matrix.shape[0], dim)
            ),
            "observation_covariance": (
                self.observation_covariance.shape, (self.observation_matrix.shape[0],) * 2
            ),
        }
        for name, (got, want) in shapes.items():
            if tuple(got) != want:
                raise ValueError(f"LinearGaussian.{name} has shape {tuple(got)}, expected {want}")

    @property
    def state_dim(self) -> int:
        return self.transition_matrix.shape[0]

    @property
    def observation_shape(self) -> tuple[int]:
        """One frame's observation is a vector of this shape (checked by the engine)."""
        return (self.observation_matrix.shape[0],)

    # Products are written vector @ matrix.T: vmapped over particles, (particles, state) @
    # (state, state) keeps the particle axis leading; matrix @ vector makes XLA lay the
    # particles out as (state, particles) and transpose every gather and noise draw into it
    # (docs/engine.md, "Speed").

    def init(self, key):
        noise = fast_normal(key, (self.state_dim,), self.initial_mean.dtype)
        return self.initial_mean + noise @ jnp.linalg.cholesky(self.initial_covariance).T

    def propagate(self, key, particle, time):
        noise = fast_normal(key, particle.shape, particle.dtype)
        cholesky = jnp.linalg.cholesky(self.transition_covariance)
        # A x + L ε as one product [x, ε] @ [A, L]ᵀ: vmapped, one (particles, 2·state) @
        # (2·state, state) matmul instead of two and an add
        stacked = jnp.concatenate([self.transition_matrix, cholesky], axis=1)
        return jnp.concatenate([particle, noise]) @ stacked.T

    def log_likelihood(self, particle, observation):
        residual = observation - particle @ self.observation_matrix.T
        return _mvn_log_density(residual, jnp.linalg.cholesky(self.observation_covariance))

    def log_transition_density(self, previous, particle, time):
        residual = particle - previous @ self.transition_matrix.T
        return _mvn_log_density(residual, jnp.linalg.cholesky(self.transition_covariance))

    def sample(self, key: PRNGKeyArray, num_frames: int):
        """Draw (states (time, state), observations (time, observation)) from the model."""
        key_init, key_frames = jr.split(key)
        obs_dim = self.observation_matrix.shape[0]
        obs_cholesky = jnp.linalg.cholesky(self.observation_covariance)

        def observe(key, state):
            noise = fast_normal(key, (obs_dim,), state.dtype)
            return self.observation_matrix @ state + obs_cholesky @ noise

        def body(state, key):
            key_move, key_observe = jr.split(key)
            state = self.propagate(key_move, state, 0)
            return state, (state, observe(key_observe, state))

        key_first, key_observe_first = jr.split(key_init)
        first = self.init(key_first)
        _, (states, observations) = lax.scan(body, first, jr.split(key_frames, num_frames - 1))
        states = jnp.concatenate([first[None], states])
        observations = jnp.concatenate([observe(key_observe_first, first)[None], observations])
        return states, observations


class KalmanResult(eqx.Module):
    log_evidence: Float[Array, ""]
    log_evidence_increments: Float[Array, " time"]
    filtered_means: Float[Array, "time state"]
    filtered_covariances: Float[Array, "time state state"]
    predicted_means: Float[Array, "time state"]
    predicted_covariances: Float[Array, "time state state"]


def _symmetric(matrix):
    return 0.5 * (matrix + matrix.T)


def kalman_filter(model: LinearGaussian, observations: Float[Array, "time observation"]):
    """Exact filtering distributions and log evidence of a ``LinearGaussian`` model.

    Raises:
        ValueError: ``observations`` is not of shape ``(time, observation)`` for the model's
            observation dimension, or has no frames.
    """
    check_observation_shape(model, observations, time_axis=True)
    if jnp.shape(observations)[0] < 1:
        raise ValueError("observations have zero frames")
    F, Q = model.transition_matrix, model.transition_covariance
    H, R = model.observation_matrix, model.observation_covariance

    def update(mean, covariance, observation):
        innovation_cov = _symmetric(H @ covariance @ H.T + R)
        cholesky = jnp.linalg.cholesky(innovation_cov)
        residual = observation - H @ mean
        increment = _mvn_log_density(residual, cholesky)
        gain = jsl.cho_solve((cholesky, True), H @ covariance).T
        mean = mean + gain @ residual
        identity = jnp.eye(mean.shape[0], dtype=mean.dtype)
        joseph = identity - gain @ H
        covariance = _symmetric(joseph @ covariance @ joseph.T + gain @ R @ gain.T)
        return mean, covariance, increment

    def body(carry, observation):
        mean, covariance = carry
        predicted_mean = F @ mean
        predicted_cov = _symmetric(F @ covariance @ F.T + Q)
        mean, covariance, increment = update(predicted_mean, predicted_cov, observation)
        return (mean, covariance), (mean, covariance, predicted_mean, predicted_cov, increment)

    first_mean, first_cov, first_increment = update(
        model.initial_mean, model.initial_covariance, observations[0]
    )
    _, (means, covs, pred_means, pred_covs, increments) = lax.scan(
        body, (first_mean, first_cov), observations[1:]
    )

    def stack(head, tail):
        return jnp.concatenate([head[None], tail])

    increments = stack(first_increment, increments)
    return KalmanResult(
        jnp.sum(increments),
        increments,
        stack(first_mean, means),
        stack(first_cov, covs),
        stack(model.initial_mean, pred_means),
        stack(model.initial_covariance, pred_covs),
    )


def rts_smoother(model: LinearGaussian, observations: Float[Array, "time observation"]):
    """Rauch–Tung–Striebel smoother: (smoothed means (time, state), covariances)."""
    filtered = kalman_filter(model, observations)
    F = model.transition_matrix

    def body(carry, inputs):
        next_mean, next_cov = carry
        mean, cov, predicted_mean, predicted_cov = inputs
        gain = jsl.solve(predicted_cov, F @ cov, assume_a="pos").T
        mean = mean + gain @ (next_mean - predicted_mean)
        cov = _symmetric(cov + gain @ (next_cov - predicted_cov) @ gain.T)
        return (mean, cov), (mean, cov)

    last = (filtered.filtered_means[-1], filtered.filtered_covariances[-1])
    inputs = (
        filtered.filtered_means[:-1], filtered.filtered_covariances[:-1],
        filtered.predicted_means[1:], filtered.predicted_covariances[1:],
    )
    _, (means, covs) = lax.scan(body, last, inputs, reverse=True)
    means = jnp.concatenate([means, last[0][None]])
    covs = jnp.concatenate([covs, last[1][None]])
    return means, covs


def random_linear_gaussian(
    key: PRNGKeyArray, state_dim: int, observation_dim: int, dtype=None
) -> LinearGaussian:
    """A random stable linear-Gaussian model (spectral radius < 1), for tests and benchmarks.

    ``dtype`` None: JAX's default float (float64 when ``jax_enable_x64`` is on, else float32,
    without the warning an explicit float64 request gives then)."""
    if dtype is None:
        dtype = jnp.result_type(float)
    keys = jr.split(key, 4)
    raw = jr.normal(keys[0], (state_dim, state_dim), dtype)
    transition = 0.9 * raw / jnp.max(jnp.abs(jnp.linalg.eigvals(raw)))
    factor = jr.normal(keys[1], (state_dim, state_dim), dtype) / math.sqrt(state_dim)
    transition_cov = 0.1 * (factor @ factor.T) + 0.05 * jnp.eye(state_dim, dtype=dtype)
    observation = jr.normal(keys[2], (observation_dim, state_dim), dtype) / math.sqrt(state_dim)
    obs_factor = jr.normal(keys[3], (observation_dim, observation_dim), dtype)
    obs_cov = 0.1 * (obs_factor @ obs_factor.T) / observation_dim + 0.2 * jnp.eye(
        observation_dim, dtype=dtype
    )
    return LinearGaussian(
        transition.real.astype(dtype), transition_cov, observation, obs_cov,
        jnp.zeros(state_dim, dtype), jnp.eye(state_dim, dtype=dtype),
    )
