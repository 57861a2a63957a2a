"""Statistical tests of the engine's generator (``jaxtrack.smc._random``).

The engine's noise is a counter hash (Wellons' lowbias32, two rounds) keyed per particle and
frame, mapped from 24 bits to normals through Giles' erf⁻¹ polynomials. These tests check what
a Monte-Carlo user relies on: the 24-bit uniforms are uniform (chi-square over bins,
Kolmogorov–Smirnov, every bit balanced), consecutive draws are not serially dependent
(serial-pair chi-square, Wald–Wolfowitz runs), the normals are N(0, 1) (KS, first four
moments), draws of neighbouring particles and of one particle at consecutive frames of a real
``smc.run`` are uncorrelated, and the bootstrap filter's evidence estimate is unbiased against
the Kalman filter's exact evidence (E[Ẑ] = Z, Del Moral 2004, Thm 7.4.2). Seeds are fixed, so
each test is deterministic; thresholds are p > 1e-3 (|z| < 3.3) or the equivalent.
"""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy import stats

from jaxtrack import smc
from jaxtrack.smc._random import bits_to_normal, fast_uniform_bits, particle_keys

P_MIN = 1e-3
Z_MAX = float(stats.norm.isf(P_MIN / 2))  # 3.29: a two-sided p-value above 1e-3
NUM_DRAWS = 1 << 19


@pytest.fixture(scope="module")
def bits():
    """2¹⁹ consecutive uint32 words of one key's stream."""
    return np.asarray(jax.jit(fast_uniform_bits, static_argnums=1)(jr.key(7), (NUM_DRAWS,)))


def _uniforms(words):
    """The 24-bit uniforms the engine's normals are made from: (b + ½) / 2²⁴ for the top bits."""
    return ((words >> 8).astype(np.float64) + 0.5) / 2.0**24


def test_uniforms_fill_bins_evenly_and_pass_kolmogorov_smirnov(bits):
    uniforms = _uniforms(bits)
    counts = np.bincount((uniforms * 1024).astype(np.int64), minlength=1024)
    assert stats.chisquare(counts).pvalue > P_MIN
    assert stats.kstest(uniforms, "uniform").pvalue > P_MIN
    # the bottom 8 bits are dropped by the normals but are still the hash's: every bit of the
    # word is 1 half the time
    ones = np.array([np.count_nonzero(bits & np.uint32(1 << bit)) for bit in range(32)])
    z = (ones - NUM_DRAWS / 2) / np.sqrt(NUM_DRAWS / 4)
    assert np.max(np.abs(z)) < stats.norm.isf(P_MIN / 2 / 32)  # Bonferroni over 32 bits


def test_consecutive_uniforms_are_serially_independent(bits):
    uniforms = _uniforms(bits)
    # serial pairs (u_2k, u_2k+1) in a 32 × 32 grid: non-overlapping pairs, so the cell counts
    # are multinomial and the chi-square statistic has 1023 degrees of freedom
    cells = (uniforms[0::2] * 32).astype(np.int64) * 32 + (uniforms[1::2] * 32).astype(np.int64)
    assert stats.chisquare(np.bincount(cells, minlength=1024)).pvalue > P_MIN
    # Wald–Wolfowitz runs above / below ½
    above = uniforms > 0.5
    runs = 1 + np.count_nonzero(above[1:] != above[:-1])
    n1, n2 = np.count_nonzero(above), np.count_nonzero(~above)
    mean = 2 * n1 * n2 / (n1 + n2) + 1
    variance = (mean - 1) * (mean - 2) / (n1 + n2 - 1)
    assert abs(runs - mean) / np.sqrt(variance) < Z_MAX
    # lag-1 to lag-4 autocorrelations
    centred = uniforms - uniforms.mean()
    for lag in (1, 2, 3, 4):
        correlation = np.dot(centred[:-lag], centred[lag:]) / np.dot(centred, centred)
        assert abs(correlation) * np.sqrt(NUM_DRAWS) < Z_MAX


def test_normals_pass_kolmogorov_smirnov_and_have_standard_moments(bits):
    normals = np.asarray(bits_to_normal(jnp.asarray(bits)), np.float64)
    n = normals.size
    assert stats.kstest(normals, "norm").pvalue > P_MIN
    assert abs(normals.mean()) * np.sqrt(n) < Z_MAX
    assert abs(normals.var() - 1) / np.sqrt(2 / n) < Z_MAX
    assert abs(stats.skew(normals)) / np.sqrt(6 / n) < Z_MAX
    assert abs(stats.kurtosis(normals)) / np.sqrt(24 / n) < Z_MAX
    # tails: the frequency beyond ±3 is that of N(0, 1) (binomial z-score)
    beyond = np.count_nonzero(np.abs(normals) > 3)
    expected = n * 2 * stats.norm.sf(3)
    assert abs(beyond - expected) / np.sqrt(expected) < Z_MAX


class _FreshNoise(smc.StateSpaceModel):
    """Every particle's state is a fresh ``fast_normal`` draw each frame and every weight is
    equal, so the history of a run is the engine's raw noise, particle by particle."""

    def init(self, key):
        return smc.fast_normal(key, (4,), jnp.float32)

    def propagate(self, key, particle, time):
        return smc.fast_normal(key, particle.shape, particle.dtype)

    def log_likelihood(self, particle, observation):
        return jnp.zeros((), jnp.float32)


@pytest.fixture(scope="module")
def engine_noise():
    """(time, particles, 4) draws made by ``smc.run`` (never resampling, so particle i stays i)."""
    result = smc.run(jr.key(11), _FreshNoise(), jnp.zeros((32, 1), jnp.float32), 2048,
                     ess_threshold=0.0, keep_history=True)
    assert not np.any(np.asarray(result.resampled))
    return np.asarray(result.particles, np.float64)


def _correlation_z(first, second):
    """z-score of the Pearson correlation of two flat samples (√n r ~ N(0, 1) if independent)."""
    return np.corrcoef(first.ravel(), second.ravel())[0, 1] * np.sqrt(first.size)


def test_engine_draws_are_independent_across_particles_and_frames(engine_noise):
    noise = engine_noise
    assert stats.kstest(noise.ravel(), "norm").pvalue > P_MIN
    # neighbouring particles in one frame, and one particle at consecutive frames
    assert abs(_correlation_z(noise[:, :-1], noise[:, 1:])) < Z_MAX
    assert abs(_correlation_z(noise[:-1], noise[1:])) < Z_MAX
    # neighbouring coordinates of one particle's draw
    assert abs(_correlation_z(noise[..., :-1], noise[..., 1:])) < Z_MAX
    # squares too: a dependence in magnitude that leaves the correlation at zero
    squares = noise**2
    assert abs(_correlation_z(squares[:, :-1], squares[:, 1:])) < Z_MAX
    assert abs(_correlation_z(squares[:-1], squares[1:])) < Z_MAX
    # serial pairs of signs at consecutive frames: the four cells are equally likely
    signs = (noise[:-1, :, 0] > 0).astype(np.int64) * 2 + (noise[1:, :, 0] > 0)
    assert stats.chisquare(np.bincount(signs.ravel(), minlength=4)).pvalue > P_MIN


def test_particle_keys_give_uncorrelated_streams_for_neighbouring_indices():
    keys = particle_keys(jr.key(3), 1 << 15)
    draws = np.asarray(jax.vmap(lambda key: fast_uniform_bits(key, (8,)))(keys))
    uniforms = _uniforms(draws)
    assert abs(_correlation_z(uniforms[:-1] - 0.5, uniforms[1:] - 0.5)) < Z_MAX
    # the same position of every particle's stream is itself uniform
    counts = np.bincount((uniforms[:, 0] * 256).astype(np.int64), minlength=256)
    assert stats.chisquare(counts).pvalue > P_MIN


NUM_SEEDS = 256


def _sample_observations(model, num_frames, rng):
    """Observations drawn from ``model`` with NumPy (E[Ẑ] = Z holds for any fixed observations;
    drawing them from the model keeps Ẑ's variance small, and NumPy compiles nothing)."""
    transition, observation_matrix = np.asarray(model.transition_matrix), np.asarray(
        model.observation_matrix)
    state = rng.multivariate_normal(np.asarray(model.initial_mean),
                                    np.asarray(model.initial_covariance))
    observations = []
    for frame in range(num_frames):
        if frame:
            state = transition @ state + rng.multivariate_normal(
                np.zeros(state.size), np.asarray(model.transition_covariance))
        observations.append(observation_matrix @ state + rng.multivariate_normal(
            np.zeros(observation_matrix.shape[0]), np.asarray(model.observation_covariance)))
    return np.stack(observations)


def _evidence_ratios(noise_scale):
    """exp(log Ẑ − log Z) over ``NUM_SEEDS`` runs of the float32 bootstrap filter (fast_normal
    noise) on one small linear-Gaussian model, the transition noise scaled by ``noise_scale``."""
    model64 = smc.random_linear_gaussian(jr.key(5), 2, 1, dtype=jnp.float64)
    observations = jnp.asarray(_sample_observations(model64, 10, np.random.default_rng(6)))
    exact = float(smc.kalman_filter(model64, observations).log_evidence)
    model32 = jax.tree.map(lambda leaf: leaf.astype(jnp.float32), model64)
    model32 = type(model32)(
        model32.transition_matrix, noise_scale**2 * model32.transition_covariance,
        model32.observation_matrix, model32.observation_covariance, model32.initial_mean,
        model32.initial_covariance)
    keys = jr.split(jr.key(2026), NUM_SEEDS)
    batch = jnp.broadcast_to(observations.astype(jnp.float32), (NUM_SEEDS, *observations.shape))
    result = smc.run_batch(keys, model32, batch, 64, chunk_size=None)
    return np.exp(np.asarray(result.log_evidence, np.float64) - exact)


def test_evidence_estimate_is_unbiased_against_kalman_over_seeds():
    ratios = _evidence_ratios(1.0)
    standard_error = ratios.std(ddof=1) / np.sqrt(ratios.size)
    assert 0 < standard_error < 0.05  # the test has the power to see a few per cent of bias
    assert abs(ratios.mean() - 1) < Z_MAX * standard_error
    # log Ẑ itself is biased low (Jensen): its mean is below log Z by about half its variance
    log_ratios = np.log(ratios)
    assert log_ratios.mean() < 0
    # and the same check sees a wrong model: transition noise 0.6 times too small
    wrong = _evidence_ratios(0.6)
    assert abs(wrong.mean() - 1) > Z_MAX * wrong.std(ddof=1) / np.sqrt(wrong.size)
