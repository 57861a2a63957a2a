"""fast_normal: distribution, independence across keys, extreme bit patterns, float64 fallback."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy import stats

from jaxtrack import smc
from jaxtrack.smc._random import bits_to_normal


def test_extreme_bits_give_finite_symmetric_draws():
    bits = jnp.array([0, 0xFF, 0x7FFFFF00, 0x80000000, 0xFFFFFF00, 0xFFFFFFFF], jnp.uint32)
    draws = np.asarray(bits_to_normal(bits))
    assert np.all(np.isfinite(draws))
    assert draws[0] == -draws[-1] and 5.0 < draws[-1] < 5.6
    assert abs(draws[2]) < 1e-6 and abs(draws[3]) < 1e-6


def test_erf_inv_is_float32_accurate_over_every_input_bits_to_normal_makes():
    from scipy.special import erfinv

    from jaxtrack.smc._random import erf_inv

    # Every 64th of the 2^24 inputs, the extremes and the switch between the two polynomials.
    top = np.concatenate([np.arange(0, 2**24, 64), [1, 2**24 - 2, 2**24 - 1]]).astype(np.float32)
    x = (top - np.float32(8388607.5)) * np.float32(1.0 / 8388608.0)
    x = np.concatenate([x, np.float32([0.99662, 0.99663, -0.99663])])
    approx = np.asarray(jax.jit(erf_inv)(jnp.asarray(x)), np.float64)
    exact = erfinv(x.astype(np.float64))
    assert np.max(np.abs(approx - exact) / np.abs(exact)) < 1e-6


@pytest.mark.parametrize("make_keys", ["split", "particle_keys"])
def test_per_particle_draws_are_standard_normal_and_independent(make_keys):
    from jaxtrack.smc._random import particle_keys

    keys = jr.split(jr.key(0), 40_000) if make_keys == "split" else particle_keys(jr.key(0),
                                                                                   40_000)
    draws = np.asarray(jax.vmap(lambda key: smc.fast_normal(key, (25,)))(keys))
    assert draws.dtype == np.float32 and np.all(np.isfinite(draws))
    flat = draws.ravel()
    assert stats.kstest(flat, "norm").pvalue > 1e-3
    assert abs(flat.mean()) < 5 / np.sqrt(flat.size)
    assert abs(flat.var() - 1) < 5 * np.sqrt(2 / flat.size)
    # Neither across coordinates of one key nor across neighbouring keys correlated.
    assert abs(np.corrcoef(draws[:, 0], draws[:, 1])[0, 1]) < 0.03
    assert abs(np.corrcoef(draws[:-1, 0], draws[1:, 0])[0, 1]) < 0.03
    # No two particles share a stream.
    assert len(np.unique(draws[:, 0])) > 0.99 * len(keys)


def test_float64_falls_back_to_threefry():
    key = jr.key(3)
    np.testing.assert_array_equal(smc.fast_normal(key, (5,), jnp.float64),
                                  jr.normal(key, (5,), jnp.float64))


@pytest.mark.parametrize("num", [1, 2, 7, 200])
def test_split_and_uniform_match_jax_random_bit_for_bit(num):
    from jaxtrack.smc._random import split, uniform

    for key in (jax.random.PRNGKey(3), jax.random.key(11)):
        assert np.array_equal(jax.random.key_data(split(key, num)),
                              jax.random.key_data(jax.random.split(key, num)))
        for shape in [(), (num,), (3, num)]:
            ours = uniform(key, shape, jnp.float32)
            reference = jax.random.uniform(key, shape, jnp.float32)
            assert ours.dtype == reference.dtype and np.array_equal(ours, reference)
    # other dtypes fall back to jax.random itself
    key = jax.random.PRNGKey(5)
    assert np.array_equal(uniform(key, (4,), jnp.float64),
                          jax.random.uniform(key, (4,), jnp.float64))


def test_particle_keys_are_distinct_keys_of_the_input_kind():
    from jaxtrack.smc._random import particle_keys

    for key in (jax.random.PRNGKey(3), jax.random.key(11)):
        keys = particle_keys(key, 5000)
        assert keys.shape[0] == 5000 and keys.dtype == key.dtype
        data = np.asarray(jax.random.key_data(keys) if keys.dtype != jnp.uint32 else keys)
        assert len({tuple(row) for row in data}) == 5000
        # threefry draws from them are standard normal too
        draws = np.asarray(jax.vmap(lambda k: jr.normal(k, ()))(keys))
        assert stats.kstest(draws, "norm").pvalue > 1e-3
    assert not np.array_equal(jax.random.key_data(particle_keys(jr.key(0), 8)),
                              jax.random.key_data(particle_keys(jr.key(1), 8)))
