"""Frames where every weight is zero are reported and recovered from, never NaN."""

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc

from .helpers import rebuild


class GatedModel(smc.LinearGaussian):
    """Observations above 100 are impossible under every state; NaN observations give NaN."""

    def log_likelihood(self, particle, observation):
        value = super().log_likelihood(particle, observation)
        return jnp.where(observation[0] > 100.0, -jnp.inf, value)


@pytest.fixture(scope="module")
def model():
    base = smc.random_linear_gaussian(jr.key(0), 2, 1)
    return rebuild(GatedModel, base)


@pytest.mark.parametrize("impossible_frame", [0, 3])
def test_all_zero_weights_reported_and_reseeded(model, impossible_frame):
    _, observations = model.sample(jr.key(1), 8)
    observations = observations.at[impossible_frame, 0].set(1e3)
    result = smc.run(jr.key(2), model, observations, 200, keep_history=True)
    expected = np.zeros(8, bool)
    expected[impossible_frame] = True
    np.testing.assert_array_equal(result.degenerate, expected)
    assert np.all(np.isfinite(result.mean)) and np.all(np.isfinite(result.log_weights))
    assert result.log_evidence_increments[impossible_frame] == -np.inf
    # the degenerate frame's ESS says so (it used to read as the re-seeded set's healthy ESS)
    assert result.ess[impossible_frame] == 0.0
    assert np.all(np.isfinite(np.delete(np.asarray(result.log_evidence_increments),
                                        impossible_frame)))
    # The filter goes on: later frames have a healthy particle set.
    assert np.all(result.ess[impossible_frame + 1:] > 1.0)


def test_online_step_reports_zero_ess_on_a_degenerate_frame(model):
    _, observations = model.sample(jr.key(8), 3)
    state, info = smc.initialize(jr.key(9), model, observations[0], 50)
    assert not info.degenerate and info.ess > 1.0
    for iterations in (1, 3):
        _, info = smc.step(jr.key(10), state, observations[1].at[0].set(1e3), model,
                           iterations_per_frame=iterations)
        assert info.degenerate and info.ess == 0.0
    _, info = smc.initialize(jr.key(9), model, observations[0].at[0].set(1e3), 50)
    assert info.degenerate and info.ess == 0.0


def test_nan_likelihoods_are_counted_and_dropped(model):
    _, observations = model.sample(jr.key(3), 5)

    class HalfNaN(GatedModel):
        def log_likelihood(self, particle, observation):
            value = super().log_likelihood(particle, observation)
            return jnp.where(particle[0] > 0, jnp.nan, value)

    nan_model = rebuild(HalfNaN, model)
    result = smc.run(jr.key(4), nan_model, observations, 100)
    assert np.all(result.num_invalid > 0)
    assert np.all(np.isfinite(result.mean)) and np.isfinite(float(result.log_evidence))


def test_degenerate_batch_under_vmap(model):
    """Recovery is decided per sequence inside a batch (vmap with an axis name)."""
    _, observations = model.sample(jr.key(5), 6)
    bad = observations.at[2, 0].set(1e3)
    result = smc.run_batch(jr.split(jr.key(6), 2), model, jnp.stack([observations, bad]), 100)
    assert not np.any(result.degenerate[0])
    np.testing.assert_array_equal(result.degenerate[1], [False, False, True, False, False, False])
    np.testing.assert_array_equal(result.ess[1] == 0.0, result.degenerate[1])
    assert np.all(np.isfinite(result.mean))


def test_bad_arguments_raise_clear_errors(model):
    _, observations = model.sample(jr.key(7), 4)
    with pytest.raises(ValueError, match="num_particles"):
        smc.run(jr.key(0), model, observations, 0)
    with pytest.raises(ValueError, match="ess_threshold"):
        smc.run(jr.key(0), model, observations, 10, ess_threshold=2.0)
    with pytest.raises(ValueError, match="iterations_per_frame"):
        smc.run(jr.key(0), model, observations, 10, iterations_per_frame=0)
    with pytest.raises(ValueError, match="zero frames"):
        smc.run(jr.key(0), model, observations[:0], 10)
    with pytest.raises(ValueError, match="leading time axis"):
        smc.run(jr.key(0), model, {"a": observations, "b": observations[:2]}, 10)
