"""The log-evidence gradient that fitting ascends: against central finite differences with
common random numbers, against Kalman's exact gradient, and a fit that finds Kalman's maximum;
then through the detection density in a tracker's filter; and the fixed-lag smoother that
reads a fitted filter's history."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc


def _model(theta, base):
    """theta = (log transition-noise std, log observation-noise std)."""
    dim = base.state_dim
    return smc.LinearGaussian(
        base.transition_matrix, jnp.exp(2 * theta[0]) * jnp.eye(dim), base.observation_matrix,
        jnp.exp(2 * theta[1]) * jnp.eye(base.observation_matrix.shape[0]), base.initial_mean,
        base.initial_covariance)


@pytest.fixture(scope="module")
def problem():
    base = smc.random_linear_gaussian(jr.key(0), state_dim=2, observation_dim=1)
    truth = jnp.array([jnp.log(0.4), jnp.log(0.5)])
    _, observations = _model(truth, base).sample(jr.key(7), 30)
    return base, truth, observations


def test_gradient_matches_central_differences_with_common_random_numbers(problem):
    """Without resampling the estimate is a smooth function of θ for a fixed key, and
    ``log_evidence_and_gradient`` is its exact derivative: central differences with the same
    key agree to 1e-4 (float64)."""
    base, truth, observations = problem
    with jax.enable_x64(True):
        base64 = jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64), base)
        theta = jnp.asarray(truth, jnp.float64) + 0.1
        obs = jnp.asarray(observations, jnp.float64)
        build = lambda t: _model(t, base64)  # noqa: E731
        key = jr.key(3)
        evaluate = jax.jit(lambda t: smc.log_evidence_and_gradient(key, build, t, obs, 64,
                                                                   ess_threshold=0.0))
        value, gradient = evaluate(theta)
        step = 1e-5
        differences = []
        for i in range(2):
            shift = jnp.zeros(2, jnp.float64).at[i].set(step)
            differences.append((evaluate(theta + shift)[0] - evaluate(theta - shift)[0])
                               / (2 * step))
        assert np.isfinite(float(value))
        np.testing.assert_allclose(np.asarray(gradient), np.asarray(differences), rtol=1e-4,
                                   atol=1e-4)


@pytest.mark.slow
def test_gradient_with_resampling_matches_kalmans_exact_gradient(problem):
    """With resampling every frame, the StopGradient estimate averaged over 4 keys at N = 4 000
    is within 15 % (of the gradient's norm) of ∇ log p(y | θ) by Kalman."""
    base, truth, observations = problem
    theta = truth + jnp.array([0.3, -0.2])  # away from the maximum: a gradient to match
    exact = jax.grad(lambda t: smc.kalman_filter(_model(t, base), observations).log_evidence)(
        theta)
    build = lambda t: _model(t, base)  # noqa: E731
    estimate = jax.jit(jax.vmap(lambda key: smc.log_evidence_and_gradient(
        key, build, theta, observations, 4000)[1]))(jr.split(jr.key(11), 4))
    mean = np.mean(np.asarray(estimate), 0)
    assert np.linalg.norm(mean - np.asarray(exact)) < 0.15 * np.linalg.norm(np.asarray(exact))


@pytest.mark.slow
def test_adam_on_the_filter_finds_kalmans_maximum(problem):
    """``fit_log_evidence`` from 0.5 away in each log-std climbs Kalman's exact log-likelihood
    to within 0.5 nats of its maximum (found by Kalman's own gradient ascent), most of the way
    up, with the well-determined observation noise within 0.1 of the maximum's (the
    transition noise lies on a flat ridge over 30 frames)."""
    base, truth, observations = problem

    def exact(theta):
        return smc.kalman_filter(_model(theta, base), observations).log_evidence

    # the exact maximum, by plain gradient ascent on Kalman (one compiled loop)
    best = jax.jit(lambda start: jax.lax.fori_loop(
        0, 400, lambda _, theta: theta + 0.01 * jax.grad(exact)(theta), start))(truth)
    assert np.max(np.abs(np.asarray(jax.grad(exact)(best)))) < 0.5  # a maximum
    start = truth + jnp.array([0.5, -0.5])
    fit = smc.fit_log_evidence(jr.key(5), lambda t: _model(t, base), start, observations, 500,
                               iterations=150, learning_rate=0.03)
    reached, top, low = (float(exact(theta)) for theta in (fit.params, best, start))
    assert reached > top - 0.5
    assert reached - low > 0.8 * (top - low)
    assert abs(float(fit.params[1]) - float(best[1])) < 0.1
    assert float(np.mean(fit.log_evidence[-10:])) > float(fit.log_evidence[0])
    assert fit.log_evidence.shape == (150,)


@pytest.mark.slow
def test_gradient_through_the_detection_density_matches_central_differences():
    """The fitted parameters' gradient through a tracker's filter on detections (no
    resampling, one key, float64) is the derivative of its estimate: central differences
    agree to 1e-3."""
    from jaxtrack.experiments.detection_tracking import detection_tracker
    from jaxtrack.likelihoods.detections import DetectionsFrame
    from jaxtrack.trackers._particles import detection_observations, device_observation

    with jax.enable_x64(True):
        shape = np.array([[0, -8], [0, 0], [0, 9], [0, 22], [-9, 1], [-12, 11], [-13, 20],
                          [-5, 22], [9, 1], [12, 11], [13, 20], [5, 22]], float) * 4
        frames = 5
        truth = shape[None] + np.stack([100 + 2.0 * np.arange(frames), 90 + 0.0 * np.arange(
            frames)], -1)[:, None]
        rng = np.random.default_rng(0)
        points = truth[:, None] + 4 * rng.standard_normal((frames, 1, 12, 2))
        confidence = np.full((frames, 1, 12), 0.8)
        observations = detection_observations(DetectionsFrame(
            points, confidence, np.ones(frames, np.int32), np.full((frames, 2), [320., 240.])),
            dtype=np.float64)
        tracker = detection_tracker(truth[0], num_particles=32, dtype=jnp.float64)
        state = tracker.start(jr.key(0), jax.tree.map(lambda a: a[0], observations), truth[0])
        model = state.model
        params = model.templates.params

        def build(theta):
            density = eqx.tree_at(lambda d: (d.joint_scales, d.pixel_noise, d.outlier_rate),
                                  params, (jnp.exp(theta[:12]), jnp.exp(theta[12]),
                                           jax.nn.sigmoid(theta[13])))
            built = eqx.tree_at(lambda m: m.templates.params, model, density)
            return eqx.tree_at(lambda m: m.dynamics.noise_std, built,
                               model.dynamics.noise_std * jnp.exp(theta[14]))

        theta = jnp.concatenate([jnp.log(params.joint_scales) + 0.2,
                                 jnp.array([jnp.log(3.0), -2.0, 0.1])])
        obs = device_observation(observations, jnp.float64)
        key = jr.key(4)
        evaluate = jax.jit(lambda t: smc.log_evidence_and_gradient(key, build, t, obs, 32,
                                                                   ess_threshold=0.0))
        _, gradient = evaluate(theta)
        step = 1e-6
        for i in (0, 6, 12, 13, 14):  # a head, a wrist scale, σ₀, ε, the noise factor
            shift = jnp.zeros_like(theta).at[i].set(step)
            difference = float((evaluate(theta + shift)[0] - evaluate(theta - shift)[0])
                               / (2 * step))
            assert abs(float(gradient[i]) - difference) < 1e-3 * max(1.0, abs(difference)), i


def test_fixed_lag_smoother_runs_from_the_filter_to_the_whole_sequence(problem):
    """``fixed_lag_ancestry`` with lag 0 is the filter's particles and weights; with a lag of
    the whole sequence it is ``trace_ancestry``; between, frame t's particles descend to frame
    t + lag's."""
    base, truth, observations = problem
    result = smc.run(jr.key(2), _model(truth, base), observations[:8], 50, keep_history=True)
    none = smc.fixed_lag_ancestry(result, 0)
    np.testing.assert_array_equal(np.asarray(none.particles), np.asarray(result.particles))
    np.testing.assert_array_equal(np.asarray(none.log_weights), np.asarray(result.log_weights))
    whole = smc.fixed_lag_ancestry(result, 20)
    traced = smc.trace_ancestry(result)
    np.testing.assert_array_equal(np.asarray(whole.particles), np.asarray(traced.paths))
    np.testing.assert_allclose(np.asarray(whole.mean), np.asarray(traced.mean), rtol=1e-12)
    lagged = smc.fixed_lag_ancestry(result, 2)
    parents = np.asarray(result.ancestors)
    index = parents[5][parents[6]]  # frame 4's ancestors of frame 6's particles
    np.testing.assert_array_equal(np.asarray(lagged.particles[4]),
                                  np.asarray(result.particles[4])[index])
