"""The parts' posterior proposal (``MixedStateModel(part_proposal="posterior")``): its draws,
weighted by its correction and the capped part likelihood (eq. 7), are the target's, checked
against quadrature on a grid, near a hypothesis and beyond the cutoff."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.likelihoods.part_distances import PartDistances, part_distance_terms
from jaxtrack.priors.postures import NUM_POSTURES, PostureModel
from jaxtrack.trackers.mixed_state import MixedStateModel

POSTURES = PostureModel(jnp.zeros((NUM_POSTURES, 1)), jnp.ones((NUM_POSTURES, 1, 1)),
                        jnp.zeros(NUM_POSTURES), jnp.full((NUM_POSTURES,) * 2, -np.log(5.0)),
                        jnp.full(NUM_POSTURES, -np.log(5.0)), jnp.asarray(1e9))
"""Postures play no part here: the parts are drawn given one."""


@eqx.filter_jit
def _draw(model, keys, mean, variance, hypotheses):
    return jax.vmap(lambda key: model._posterior_parts(key, mean, variance, hypotheses))(keys)


@eqx.filter_jit
def _terms(parts, hypotheses, likelihood):
    """f(i) of eq. 7 for every row of ``parts`` (rows, 1, 2)."""
    return jax.vmap(lambda x: part_distance_terms(x, hypotheses, likelihood.inverse_covariances,
                                                  likelihood.cutoff))(parts)


@pytest.mark.parametrize("hypothesis, skew", [((6.0, -4.0), False), ((60.0, 10.0), False),
                                              ((5.0, 3.0), True)])
def test_weighted_draws_are_the_prediction_times_the_capped_likelihood(hypothesis, skew):
    likelihood = PartDistances((8.0,), cutoff=9.0)
    if skew:  # a full R⁻¹
        likelihood = eqx.tree_at(lambda m: m.inverse_covariances, likelihood, jnp.asarray(
            [[[1 / 40.0, 1 / 150.0], [1 / 150.0, 1 / 90.0]]]))
    model = MixedStateModel(POSTURES, likelihood, part_proposal="posterior")
    mean, variance = jnp.zeros((1, 2)), jnp.asarray(15.0 ** 2)
    z = jnp.asarray([hypothesis])
    keys = jr.split(jr.PRNGKey(0), 50000)
    drawn, correction = _draw(model, keys, mean, variance, z)
    terms = _terms(drawn, z, likelihood)
    log_w = np.asarray(correction - terms[:, 0], np.float64)
    weights = np.exp(log_w)
    # the target N(x; 0, 15² I) exp(−min(δ, d(x))) on a grid: its mass and its mean
    axis = np.linspace(-90, 150, 481)
    grid = np.stack(np.meshgrid(axis, axis, indexing="ij"), -1).reshape(-1, 2)
    prior = np.exp(-0.5 * np.sum(grid ** 2, -1) / 225.0) / (2 * np.pi * 225.0)
    capped = np.asarray(_terms(jnp.asarray(grid)[:, None], z, likelihood))[:, 0]
    target = prior * np.exp(-capped) * (axis[1] - axis[0]) ** 2
    assert weights.mean() == pytest.approx(target.sum(), rel=0.01)
    estimate = (weights[:, None] * np.asarray(drawn)[:, 0]).sum(0) / weights.sum()
    np.testing.assert_allclose(estimate, (target[:, None] * grid).sum(0) / target.sum(),
                               atol=0.3)
    # the weights are bounded: at most Z, at least Z / 2 (no weight collapses)
    assert np.ptp(log_w) <= np.log(2) + 1e-4


def test_unknown_part_proposal_is_refused():
    with pytest.raises(ValueError, match="part_proposal must be one of dynamics, posterior"):
        MixedStateModel(POSTURES, part_proposal="optimal")
