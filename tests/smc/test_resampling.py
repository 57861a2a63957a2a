"""Resamplers: offspring counts, zero weights, index range, ESS."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy import stats

from jaxtrack import smc
from jaxtrack.smc._resampling import _cumulative_weights, _search

SCHEMES = {
    "multinomial": smc.multinomial_ancestors,
    "stratified": smc.stratified_ancestors,
    "systematic": smc.systematic_ancestors,
    "residual": smc.residual_ancestors,
}


def _weights(num, dtype=jnp.float64):
    raw = jr.exponential(jr.key(0), (num,), dtype) ** 2
    raw = raw.at[jnp.array([0, 5, num - 1])].set(0.0)  # zero weights, including the last particle
    return raw / raw.sum()


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_offspring_counts_match_expected(name):
    num, draws = 40, 2_000
    weights = _weights(num)
    resample = jax.jit(jax.vmap(SCHEMES[name], in_axes=(0, None)))
    ancestors = np.asarray(resample(jr.split(jr.key(1), draws), jnp.log(weights)))
    counts = np.bincount(ancestors.ravel(), minlength=num)
    expected = draws * num * np.asarray(weights)
    positive = expected > 0
    chi_square = np.sum((counts[positive] - expected[positive]) ** 2 / expected[positive])
    # Multinomial is exactly chi-square distributed; the others have smaller variance.
    assert chi_square < stats.chi2.ppf(0.999, positive.sum() - 1)
    assert np.all(counts[~positive] == 0)
    # Per-draw unbiasedness: every scheme keeps N offspring in total.
    assert ancestors.shape == (draws, num)


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_float32_zero_weights_never_selected_and_indices_in_range(name):
    num = 1_000
    weights = _weights(num, jnp.float32)
    # Normalised in float64 then cast: the float32 cumulative sum no longer ends at exactly 1.
    log_weights = jnp.log(weights).astype(jnp.float32)
    ancestors = np.asarray(jax.vmap(SCHEMES[name], in_axes=(0, None))(
        jr.split(jr.key(2), 200), log_weights))
    assert ancestors.min() >= 0 and ancestors.max() < num
    assert not np.isin(ancestors, [0, 5, num - 1]).any()


def test_search_at_the_very_end_returns_last_positive_particle():
    log_weights = jnp.log(jnp.array([0.3, 0.7, 0.0, 0.0], jnp.float32))
    weights, cumulative = _cumulative_weights(log_weights)
    ancestors = _search(weights, cumulative, jnp.array([0.0, cumulative[-1], 2 * cumulative[-1]]))
    np.testing.assert_array_equal(ancestors, [0, 1, 1])


def test_systematic_and_residual_keep_deterministic_counts():
    """Low-variance schemes give each particle floor(N w) or ceil(N w) copies."""
    num = 64
    weights = _weights(num)
    for scheme in (smc.systematic_ancestors, smc.residual_ancestors):
        counts = np.bincount(np.asarray(scheme(jr.key(3), jnp.log(weights))), minlength=num)
        assert np.all(counts >= np.floor(num * np.asarray(weights)) - 1e-9)
    counts = np.bincount(np.asarray(smc.systematic_ancestors(jr.key(3), jnp.log(weights))),
                         minlength=num)
    assert np.all(counts <= np.ceil(num * np.asarray(weights)) + 1e-9)


def test_large_particle_count_resamples_in_linear_memory():
    """10^6 particles resample without building an N x N array (the categorical trap)."""
    num = 1_000_000
    log_weights = jr.normal(jr.key(4), (num,), jnp.float32)
    ancestors = jax.jit(smc.systematic_ancestors)(jr.key(5), log_weights)
    assert ancestors.shape == (num,)
    compiled = jax.jit(smc.systematic_ancestors).lower(jr.key(5), log_weights).compile()
    memory = compiled.memory_analysis()
    if memory is not None:
        assert memory.temp_size_in_bytes < 64 * num


def test_effective_sample_size():
    assert float(smc.effective_sample_size(jnp.zeros(10))) == pytest.approx(10.0)
    assert float(smc.effective_sample_size(jnp.log(jnp.array([1.0, 0.0, 0.0])))) == pytest.approx(1)
    assert float(smc.effective_sample_size(jnp.full(4, -jnp.inf))) == 0.0


@pytest.mark.parametrize("resampler", [smc.StopGradient(), smc.SoftResampling(0.3)],
                         ids=["stop_gradient", "soft"])
def test_wrappers_return_normalised_weights(resampler):
    log_weights = jax.nn.log_softmax(jr.normal(jr.key(6), (50,)))
    ancestors, carried = resampler(jr.key(7), log_weights)
    assert ancestors.shape == (50,)
    assert float(jax.nn.logsumexp(carried)) == pytest.approx(0.0, abs=1e-9)


def test_soft_resampling_rejects_bad_alpha():
    with pytest.raises(ValueError, match="alpha"):
        smc.SoftResampling(1.5)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_systematic_histogram_search_equals_the_binary_search(dtype):
    """The O(N) search (histogram of thresholds) selects what N binary searches select, up to a
    position that lands within rounding of a cumulative weight."""
    from jaxtrack.smc._resampling import _sorted_search

    for seed, num in enumerate((7, 100, 1000, 10_000)):
        weights = jnp.asarray(_weights(num), dtype)
        log_weights = jnp.log(weights)
        raw, cumulative = _cumulative_weights(log_weights)
        offset = jr.uniform(jr.key(seed), (), dtype)
        positions = (jnp.arange(num, dtype=dtype) + offset) / num * cumulative[-1]
        fast = np.asarray(_sorted_search(raw, cumulative, offset))
        slow = np.asarray(_search(raw, cumulative, positions))
        assert np.mean(fast == slow) > 0.999 and np.max(np.abs(fast - slow)) <= 1
        assert np.all(np.diff(fast) >= 0) and fast.min() >= 0 and fast.max() < num
        assert not np.isin(fast, np.flatnonzero(np.asarray(weights) == 0)).any()
