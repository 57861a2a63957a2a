"""Gradient estimators of d log p(y) / d(noise parameters) vs the exact Kalman gradient."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc

NUM_SEEDS = 8


def _model(theta, base):
    """theta = (log transition-noise std, log observation-noise std)."""
    dim = base.state_dim
    return smc.LinearGaussian(
        base.transition_matrix, jnp.exp(2 * theta[0]) * jnp.eye(dim), base.observation_matrix,
        jnp.exp(2 * theta[1]) * jnp.eye(base.observation_matrix.shape[0]), base.initial_mean,
        base.initial_covariance,
    )


@pytest.fixture(scope="module")
def problem():
    base = smc.random_linear_gaussian(jr.key(0), state_dim=2, observation_dim=1)
    theta = jnp.array([jnp.log(0.4), jnp.log(0.5)])
    _, observations = _model(theta, base).sample(jr.key(7), 20)
    exact = jax.grad(lambda t: smc.kalman_filter(_model(t, base), observations).log_evidence)(theta)
    return base, theta, observations, np.asarray(exact)


def _median_gradient(problem, resampler):
    base, theta, observations, _ = problem

    def log_evidence(theta, key):
        return smc.filter_sequence(key, _model(theta, base), observations, 10_000,
                                   resampler=resampler).log_evidence

    gradients = jax.jit(jax.vmap(jax.grad(log_evidence), in_axes=(None, 0)))(
        theta, jr.split(jr.key(11), NUM_SEEDS))
    assert np.all(np.isfinite(gradients))
    return np.median(np.asarray(gradients), axis=0)


@pytest.fixture(scope="module")
def plain(problem):
    return _median_gradient(problem, smc.Systematic())


def test_stop_gradient_matches_kalman_and_plain_is_biased(problem, plain):
    exact = problem[-1]
    stop_gradient = _median_gradient(problem, smc.StopGradient())
    relative = np.abs(stop_gradient / exact - 1)
    assert np.all(relative < 0.10), (stop_gradient, exact)
    plain_relative = np.abs(plain / exact - 1)
    # Plain resampling drops the selection's score: the observation-noise gradient is far off.
    assert plain_relative.max() > 0.3, (plain, exact)
    assert plain_relative.max() > 3 * relative.max()


def test_soft_resampling_gradient_is_finite_and_between(problem, plain):
    exact = problem[-1]
    soft = _median_gradient(problem, smc.SoftResampling(0.5))
    # Partial gradient through the selection: closer to the truth than plain on the noise term.
    assert abs(soft[1] - exact[1]) < abs(plain[1] - exact[1])
