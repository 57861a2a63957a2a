"""Smoothers vs the RTS smoother and vs brute-force enumeration of a 2-state HMM."""

import itertools

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc


def test_smoothers_match_rts():
    model = smc.random_linear_gaussian(jr.key(0), state_dim=2, observation_dim=1)
    _, observations = model.sample(jr.key(1), 10)
    smoothed, covariances = smc.rts_smoother(model, observations)
    std = np.sqrt(np.diagonal(np.asarray(covariances), axis1=1, axis2=2))
    result = smc.run(jr.key(2), model, observations, 2_000, keep_history=True)
    backward = smc.ffbsi(jr.key(3), model, result, 500)
    traced = smc.trace_ancestry(result)
    for estimate in (backward.mean, traced.mean):
        error = np.abs(np.asarray(estimate) - np.asarray(smoothed))
        # Standard error of a mean of ~500 (correlated) draws, with margin for the filter's error.
        assert np.all(error < 6 * std / np.sqrt(500) + 1e-3)
    # The last frame of a smoother is the filter.
    np.testing.assert_allclose(traced.mean[-1], result.mean[-1], rtol=1e-10)


def test_rts_smoother_differs_from_filter_and_matches_at_the_end():
    model = smc.random_linear_gaussian(jr.key(4), 2, 1)
    _, observations = model.sample(jr.key(5), 8)
    filtered = smc.kalman_filter(model, observations)
    smoothed, _ = smc.rts_smoother(model, observations)
    np.testing.assert_allclose(smoothed[-1], filtered.filtered_means[-1])
    assert np.abs(np.asarray(smoothed[0] - filtered.filtered_means[0])).max() > 1e-3


class TwoStateHMM(smc.StateSpaceModel):
    """x in {0, 1}; y ~ N(means[x], 1)."""

    initial: jax.Array
    transition: jax.Array
    means: jax.Array

    def init(self, key):
        return jr.bernoulli(key, self.initial[1]).astype(jnp.int32)

    def propagate(self, key, particle, time):
        return jr.bernoulli(key, self.transition[particle, 1]).astype(jnp.int32)

    def log_likelihood(self, particle, observation):
        return -0.5 * (observation - self.means[particle]) ** 2

    def log_transition_density(self, previous, particle, time):
        return jnp.log(self.transition[previous, particle])


@pytest.fixture(scope="module")
def hmm():
    model = TwoStateHMM(jnp.array([0.6, 0.4]), jnp.array([[0.8, 0.2], [0.3, 0.7]]),
                        jnp.array([-1.0, 1.0]))
    observations = jnp.array([0.3, -0.8, 1.4, 0.9, -0.2, 1.1])
    return model, observations


def _enumerate(model, observations):
    """Exact filtering and smoothing marginals of state 1 and the log evidence, over 2^T paths."""
    num = len(observations)
    initial, transition, means = (np.asarray(a) for a in (model.initial, model.transition,
                                                          model.means))
    obs = np.asarray(observations)
    paths = np.array(list(itertools.product([0, 1], repeat=num)))
    log_prior = np.log(initial[paths[:, 0]]) + np.log(
        transition[paths[:, :-1], paths[:, 1:]]).sum(axis=1)
    log_lik = -0.5 * (obs[None] - means[paths]) ** 2
    filtering, log_evidence = [], None
    for t in range(num):
        joint = np.exp(log_prior_prefix(paths, initial, transition, t) + log_lik[:, :t + 1].sum(1))
        # Paths agree on the prefix 0..t in 2^(T-t-1) copies: divide that out via unique prefixes.
        prefixes, index = np.unique(paths[:, :t + 1], axis=0, return_index=True)
        weights = joint[index]
        filtering.append(weights[prefixes[:, t] == 1].sum() / weights.sum())
        if t == num - 1:
            log_evidence = np.log(weights.sum())
    posterior = np.exp(log_prior + log_lik.sum(1))
    posterior /= posterior.sum()
    smoothing = (posterior[:, None] * paths).sum(0)
    return np.array(filtering), smoothing, log_evidence


def log_prior_prefix(paths, initial, transition, t):
    steps = np.log(transition[paths[:, :t], paths[:, 1:t + 1]]).sum(axis=1) if t else 0.0
    return np.log(initial[paths[:, 0]]) + steps


def test_hmm_filter_and_smoothers_match_enumeration(hmm):
    model, observations = hmm
    filtering, smoothing, log_evidence = _enumerate(model, observations)
    result = smc.run(jr.key(0), model, observations, 10_000, keep_history=True)
    weights = jax.nn.softmax(result.log_weights, axis=-1)
    pf_filtering = np.asarray(jnp.sum(weights * result.particles, axis=-1))
    np.testing.assert_allclose(pf_filtering, filtering, atol=0.02)
    # Both drop the same Gaussian constant -1/2 log(2 pi) per frame. One run's log evidence
    # has a standard deviation of about 0.02 nats here (200 seeds): the mean of 8 is within 0.02
    evidences = jax.vmap(lambda key: smc.filter_sequence(key, model, observations, 10_000)
                         .log_evidence)(jr.split(jr.key(0), 8))
    assert float(jnp.mean(evidences)) == pytest.approx(log_evidence, abs=0.02)

    traced = smc.trace_ancestry(result)
    traced_marginals = smc.discrete_marginals(traced.paths, traced.log_weights, 2)[:, 1]
    np.testing.assert_allclose(traced_marginals, smoothing, atol=0.03)

    backward = smc.ffbsi(jr.key(1), model, result, 2_000)
    backward_marginals = smc.discrete_marginals(backward.paths, backward.log_weights, 2)[:, 1]
    # 3 standard errors of a proportion from 2000 paths, plus the forward filter's error.
    np.testing.assert_allclose(backward_marginals, smoothing, atol=3 * 0.5 / np.sqrt(2_000) + 0.01)


def test_smoothers_need_history(hmm):
    model, observations = hmm
    result = smc.run(jr.key(0), model, observations, 100)
    with pytest.raises(ValueError, match="keep_history"):
        smc.trace_ancestry(result)


def test_ffbsi_needs_transition_density(hmm):
    model, observations = hmm

    class NoDensity(TwoStateHMM):
        log_transition_density = smc.StateSpaceModel.log_transition_density

    model = NoDensity(model.initial, model.transition, model.means)
    result = smc.run(jr.key(0), model, observations, 100, keep_history=True)
    with pytest.raises(NotImplementedError, match="ancestry"):
        smc.ffbsi(jr.key(1), model, result, 10)
