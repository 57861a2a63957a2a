"""The engine's proposal hooks (``propose``, ``init_propose``) against brute-force enumeration
of a three-state hidden Markov model with Gaussian observations.

The proposal is the "optimal" one, p(x_t | x_{t-1}, y_t), with importance weight
p(y_t | x_{t-1}); the weight is put either all in the correction (log-likelihood zero) or split
between the correction, log p(y_t | x_{t-1}) − log p(y_t | x_t), and the model's
log-likelihood. Frame 0's evidence estimate is then exact for any N, and so is every frame's
when the transition's rows are equal (p(y_t | x_{t-1}) is then the same for every parent);
otherwise the evidence estimate is unbiased and the filtered marginals are the exact ones
within Monte Carlo error. Without the hooks' corrections none of this holds (checked)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy import stats

from jaxtrack import smc

NUM_STATES = 3
MEANS = np.array([-1.0, 0.2, 1.5])
STD = 0.7


class HiddenMarkov(smc.StateSpaceModel):
    """x_t ∈ {0, 1, 2} with π and T; y_t ~ N(MEANS[x_t], STD²); bootstrap proposal."""

    log_initial: jax.Array
    log_transition: jax.Array

    def log_likelihoods(self, observation):
        """log p(y | x) for every state x."""
        return jnp.asarray(stats.norm.logpdf(0.0) - np.log(STD)) - 0.5 * (
            (observation - MEANS) / STD) ** 2

    def init(self, key):
        return jr.categorical(key, self.log_initial).astype(jnp.int32)

    def propagate(self, key, particle, time):
        return jr.categorical(key, self.log_transition[particle]).astype(jnp.int32)

    def log_likelihood(self, particle, observation):
        return self.log_likelihoods(observation)[particle]

    def log_transition_density(self, previous, particle, time):
        return self.log_transition[previous, particle]


def _draw(key, logits):
    """One state from p ∝ exp(logits), and log Σ exp(logits)."""
    normaliser = jax.nn.logsumexp(logits)
    return jr.categorical(key, logits).astype(jnp.int32), normaliser


class OptimalProposal(HiddenMarkov):
    """Proposes from p(x_t | x_{t-1}, y_t); its whole weight p(y_t | x_{t-1}) is the correction
    (times ``scale``: 0 drops it, and the filter is wrong). A particle proposed into state
    ``invalid_state`` gets a NaN correction (−1: none does)."""

    scale: jax.Array = eqx.field(default_factory=lambda: jnp.ones(()))
    invalid_state: jax.Array = eqx.field(default_factory=lambda: jnp.asarray(-1))

    def init_propose(self, key, observation):
        state, normaliser = _draw(key, self.log_initial + self.log_likelihoods(observation))
        return state, self.scale * normaliser

    def propose(self, key, particle, time, observation):
        logits = self.log_transition[particle] + self.log_likelihoods(observation)
        state, normaliser = _draw(key, logits)
        return state, jnp.where(state == self.invalid_state, jnp.nan, self.scale * normaliser)

    def log_likelihood(self, particle, observation):
        return jnp.zeros((), jnp.result_type(float))


class SplitWeight(HiddenMarkov):
    """The same proposal; correction log p(y_t | x_{t-1}) − log p(y_t | x_t), the model's
    log-likelihood the rest."""

    def init_propose(self, key, observation):
        state, normaliser = _draw(key, self.log_initial + self.log_likelihoods(observation))
        return state, normaliser - self.log_likelihood(state, observation)

    def propose(self, key, particle, time, observation):
        logits = self.log_transition[particle] + self.log_likelihoods(observation)
        state, normaliser = _draw(key, logits)
        return state, normaliser - self.log_likelihood(state, observation)


def _model(cls, rng, rows="random"):
    """π random; T random, or with equal rows, or sticky (0.8 on the diagonal)."""
    transition = rng.dirichlet(np.ones(NUM_STATES) * 2, size=NUM_STATES)
    if rows == "equal":
        transition[:] = transition[0]
    elif rows == "sticky":
        transition = np.full((NUM_STATES, NUM_STATES), 0.1) + 0.7 * np.eye(NUM_STATES)
    initial = rng.dirichlet(np.ones(NUM_STATES) * 2)
    return cls(jnp.log(jnp.asarray(initial)), jnp.log(jnp.asarray(transition)))


def _forward(model, observations):
    """Exact filtered marginals (time, states) and log evidence by the forward algorithm."""
    log_h = np.stack([np.asarray(model.log_likelihoods(y)) for y in observations])
    transition = np.exp(np.asarray(model.log_transition))
    alpha = np.exp(np.asarray(model.log_initial) + log_h[0])
    log_evidence, filtered = np.log(alpha.sum()), [alpha / alpha.sum()]
    for t in range(1, len(observations)):
        alpha = (filtered[-1] @ transition) * np.exp(log_h[t])
        log_evidence += np.log(alpha.sum())
        filtered.append(alpha / alpha.sum())
    return np.array(filtered), log_evidence


def _filtered_marginals(result):
    weights = jax.nn.softmax(result.log_weights, axis=-1)
    return np.asarray(jnp.einsum("tp,tpk->tk", weights,
                                 jax.nn.one_hot(result.particles, NUM_STATES)))


OBSERVATIONS = jnp.asarray([0.1, 1.4, -0.8, -1.2, 0.6])


@eqx.filter_jit
def _increments(model, keys):
    """The log-evidence increments of one filter (3 particles) per key: (keys, time)."""
    return jax.vmap(lambda key: smc.filter_sequence(key, model, OBSERVATIONS, 3)
                    .log_evidence_increments)(keys)


@pytest.mark.parametrize("cls", [OptimalProposal, SplitWeight])
def test_evidence_is_exact_where_the_optimal_proposal_makes_it_so_and_unbiased(cls):
    rng = np.random.default_rng(0)
    keys = jr.split(jr.key(cls is SplitWeight), 400)
    for rows in ("equal", "random"):
        model = _model(cls, rng, rows)
        _, exact = _forward(model, OBSERVATIONS)
        increments = np.asarray(_increments(model, keys))
        first = float(jax.nn.logsumexp(model.log_initial
                                       + model.log_likelihoods(OBSERVATIONS[0])))
        np.testing.assert_allclose(increments[:, 0], first, rtol=0, atol=1e-12)
        evidence = increments.sum(axis=1)
        if rows == "equal":  # p(y_t | x_{t-1}) is the same for every parent: exact for any N
            np.testing.assert_allclose(evidence, exact, rtol=0, atol=1e-12)
        else:  # the parents' p(y_t | x_{t-1}) differ: an estimate, unbiased in Z
            assert np.ptp(evidence) > 1e-3
            ratio = np.exp(evidence - exact)
            assert abs(ratio.mean() - 1.0) < 4 * ratio.std() / np.sqrt(len(ratio)), ratio.mean()


def test_filtered_marginals_match_enumeration_and_nan_corrections_are_invalid():
    model = _model(OptimalProposal, np.random.default_rng(1), "sticky")
    filtered, _ = _forward(model, OBSERVATIONS)
    result = smc.run(jr.key(4), model, OBSERVATIONS, 20_000, keep_history=True)
    np.testing.assert_allclose(_filtered_marginals(result), filtered, atol=0.015)
    # dropping the corrections gives another filter, off by up to 0.125 here
    wrong = smc.run(jr.key(4), eqx.tree_at(lambda m: m.scale, model, jnp.zeros(())),
                    OBSERVATIONS, 20_000, keep_history=True)
    assert np.abs(_filtered_marginals(wrong) - filtered).max() > 0.08
    result = smc.run(jr.key(7), eqx.tree_at(lambda m: m.invalid_state, model, jnp.asarray(2)),
                     OBSERVATIONS, 20_000, keep_history=True)
    in_two = np.asarray(result.particles[1:] == 2)
    np.testing.assert_array_equal(result.num_invalid[1:], in_two.sum(axis=1))
    assert np.all(np.asarray(result.log_weights[1:])[in_two] == -np.inf)
    assert np.all(np.isfinite(np.asarray(result.log_evidence_increments)))


class ZeroCorrection(HiddenMarkov):
    """``propose`` is ``propagate`` with correction 0: the bootstrap filter."""

    def propose(self, key, particle, time, observation):
        return self.propagate(key, particle, time), jnp.zeros(())


def test_a_zero_correction_is_the_bootstrap_filter():
    base = _model(HiddenMarkov, np.random.default_rng(2))
    plain = smc.run(jr.key(6), base, OBSERVATIONS, 50, keep_history=True)
    hooked = smc.run(jr.key(6), ZeroCorrection(base.log_initial, base.log_transition),
                     OBSERVATIONS, 50, keep_history=True)
    np.testing.assert_array_equal(plain.particles, hooked.particles)
    np.testing.assert_array_equal(plain.log_weights, hooked.log_weights)
    np.testing.assert_array_equal(plain.log_evidence, hooked.log_evidence)
