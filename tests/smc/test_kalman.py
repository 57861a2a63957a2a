"""Bootstrap filter vs the exact Kalman filter on random linear-Gaussian models (float64)."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc

NUM_RUNS = 8


@pytest.fixture(scope="module", params=[0, 1], ids=["model0", "model1"])
def problem(request):
    seed = request.param
    model = smc.random_linear_gaussian(jr.key(seed), state_dim=2, observation_dim=1)
    _, observations = model.sample(jr.key(100 + seed), 12)
    return model, observations, smc.kalman_filter(model, observations)


def _runs(model, observations, num_particles, seed=0):
    keys = jr.split(jr.key(seed), NUM_RUNS)
    batch = jnp.broadcast_to(observations, (NUM_RUNS, *observations.shape))
    return smc.run_batch(keys, model, batch, num_particles)


@pytest.fixture(scope="module")
def large_runs(problem):
    model, observations, _ = problem
    return _runs(model, observations, 100_000)


def test_log_evidence_within_three_standard_errors(problem, large_runs):
    _, _, exact = problem
    result = large_runs
    estimates = np.asarray(result.log_evidence)
    standard_error = estimates.std(ddof=1) / np.sqrt(NUM_RUNS)
    assert standard_error > 0
    assert abs(estimates.mean() - float(exact.log_evidence)) < 3 * standard_error + 1e-3


def test_filtered_means_within_five_standard_errors(problem, large_runs):
    _, _, exact = problem
    result = large_runs
    means = np.asarray(result.mean)  # (runs, time, state)
    standard_error = means.std(axis=0, ddof=1) / np.sqrt(NUM_RUNS)
    error = np.abs(means.mean(axis=0) - np.asarray(exact.filtered_means))
    assert np.all(error < 5 * standard_error + 1e-4)


def test_error_shrinks_as_particles_grow(problem):
    model, observations, exact = problem
    errors = []
    for num_particles in (100, 1_000, 10_000):
        result = _runs(model, observations, num_particles, seed=2)
        squared = (np.asarray(result.mean) - np.asarray(exact.filtered_means)) ** 2
        errors.append(np.sqrt(squared.mean()))
    assert errors[0] > errors[1] > errors[2]
    # Monte-Carlo error scales like N^(-1/2): 100x the particles, about 10x smaller.
    assert errors[2] < errors[0] / 4


def test_kalman_filter_matches_dense_gaussian_evidence():
    """The reference itself: log evidence equals the joint Gaussian density of all observations."""
    model = smc.random_linear_gaussian(jr.key(3), state_dim=2, observation_dim=2)
    _, observations = model.sample(jr.key(4), 5)
    F, Q, H, R = (np.asarray(a) for a in (model.transition_matrix, model.transition_covariance,
                                          model.observation_matrix, model.observation_covariance))
    num = observations.shape[0]
    marginal = [np.asarray(model.initial_covariance)]
    for _ in range(1, num):
        marginal.append(F @ marginal[-1] @ F.T + Q)
    joint = np.zeros((2 * num, 2 * num))
    for t in range(num):
        for s in range(t + 1):
            # Cov(x_t, x_s) = F^(t-s) Cov(x_s) for t >= s.
            block = H @ np.linalg.matrix_power(F, t - s) @ marginal[s] @ H.T
            joint[2 * t:2 * t + 2, 2 * s:2 * s + 2] = block
            joint[2 * s:2 * s + 2, 2 * t:2 * t + 2] = block.T
    joint += np.kron(np.eye(num), R)
    flat = np.asarray(observations).reshape(-1)
    sign, log_det = np.linalg.slogdet(joint)
    quadratic = flat @ np.linalg.solve(joint, flat)
    expected = -0.5 * (quadratic + log_det + flat.size * np.log(2 * np.pi))
    assert sign > 0
    np.testing.assert_allclose(float(smc.kalman_filter(model, observations).log_evidence), expected,
                               rtol=1e-9)


def test_shapes_checked_at_construction():
    with pytest.raises(ValueError, match="transition_covariance"):
        smc.LinearGaussian(jnp.eye(2), jnp.eye(3), jnp.ones((1, 2)), jnp.eye(1), jnp.zeros(2),
                           jnp.eye(2))


def test_float32_run_stays_float32():
    model = jax.tree.map(lambda x: x.astype(jnp.float32),
                         smc.random_linear_gaussian(jr.key(5), 2, 1))
    _, observations = model.sample(jr.key(6), 6)
    result = smc.run(jr.key(7), model, observations, 500)
    assert result.mean.dtype == jnp.float32
    assert np.isfinite(float(result.log_evidence))
