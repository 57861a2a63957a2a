"""Observations of the wrong shape are refused at trace time, naming both shapes."""

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc


@pytest.fixture(scope="module")
def model():
    return smc.random_linear_gaussian(jr.key(0), state_dim=2, observation_dim=2)


def test_linear_gaussian_declares_its_observation_shape(model):
    assert model.observation_shape == (2,)


@pytest.mark.parametrize("shape", [(12, 1), (12, 3), (12,), (12, 2, 1)])
def test_run_and_kalman_refuse_observations_of_the_wrong_shape(model, shape):
    # (12, 1) against a 2-d observation broadcast silently before and gave a finite, wrong
    # log evidence from both the particle filter and the Kalman filter
    observations = jnp.zeros(shape)
    expected = (r"expects observations of shape \(time, 2\).*"
                rf"got observations of shape \({shape[0]},")
    with pytest.raises(ValueError, match=expected):
        smc.run(jr.key(1), model, observations, 8)
    with pytest.raises(ValueError, match=expected):
        smc.kalman_filter(model, observations)
    with pytest.raises(ValueError, match=expected):
        smc.rts_smoother(model, observations)
    with pytest.raises(ValueError, match=expected):
        smc.filter_sequence(jr.key(1), model, observations, 8)


def test_step_and_initialize_refuse_one_frame_of_the_wrong_shape(model):
    with pytest.raises(ValueError, match=r"expects observation of shape \(2,\).*got .*\(1,\)"):
        smc.initialize(jr.key(0), model, jnp.zeros(1), 8)
    state, _ = smc.initialize(jr.key(0), model, jnp.zeros(2), 8)
    with pytest.raises(ValueError, match=r"expects observation of shape \(2,\).*got .*\(3,\)"):
        smc.step(jr.key(1), state, jnp.zeros(3), model)


def test_batches_are_checked_per_sequence(model):
    with pytest.raises(ValueError, match=r"shape \(time, 2\).*got observations of shape \(5, 1\)"):
        smc.run_batch(jr.split(jr.key(0), 2), model, jnp.zeros((2, 5, 1)), 8)


class Tagged(smc.StateSpaceModel):
    """A generic model with a pytree observation that declares its shape."""

    observation_shape = {"position": (2,), "posture": ()}

    def init(self, key):
        return jr.normal(key, (2,))

    def propagate(self, key, particle, time):
        return particle + 0.1 * jr.normal(key, (2,))

    def log_likelihood(self, particle, observation):
        return -jnp.sum((observation["position"] - particle) ** 2) + 0.0 * observation["posture"]


class Undeclared(Tagged):
    observation_shape = None


def test_a_generic_model_may_declare_a_pytree_observation_shape():
    good = {"position": jnp.zeros((4, 2)), "posture": jnp.zeros(4)}
    assert np.isfinite(float(smc.run(jr.key(0), Tagged(), good, 16).log_evidence))
    bad = {"position": jnp.zeros((4, 3)), "posture": jnp.zeros(4)}
    with pytest.raises(ValueError, match=r"Tagged expects observations of shape \(time, 2\)"):
        smc.run(jr.key(0), Tagged(), bad, 16)
    with pytest.raises(ValueError, match="structured as"):
        smc.run(jr.key(0), Tagged(), {"position": jnp.zeros((4, 2))}, 16)
    # without a declaration the engine cannot tell: a broadcasting shape runs
    broadcasting = {"position": jnp.zeros((4, 1)), "posture": jnp.zeros(4)}
    with pytest.raises(ValueError, match=r"got observations of shape \(4, 1\)"):
        smc.run(jr.key(0), Tagged(), broadcasting, 16)
    assert np.isfinite(float(smc.run(jr.key(0), Undeclared(), broadcasting, 16).log_evidence))


def test_valid_observations_give_the_same_result_as_before(model):
    _, observations = model.sample(jr.key(2), 6)
    result = smc.run(jr.key(3), model, observations, 64)
    exact = smc.kalman_filter(model, observations)
    assert np.isfinite(float(result.log_evidence)) and np.isfinite(float(exact.log_evidence))
