"""Statistical tests of the engine's generator (``jaxtrack.smc._random``).

The engine's noise is a counter hash (Wellons' lowbias32, two rounds) keyed per particle and
frame, mapped from 24 bits to normals through Giles' erf⁻¹ polynomials. These tests check what
a Monte-Carlo user relies on: the 24-bit uniforms are uniform (chi-square over bins,
Kolmogorov–Smirnov, every bit balanced), consecutive draws are not serially dependent
(serial-pair chi-square, Wald–Wolfowitz runs, autocorrelations), the normals are N(0, 1) (KS,
first four moments, tails), draws of neighbouring particles and of one particle at consecutive
frames of a real ``smc.run`` are uncorrelated, and the bootstrap filter's evidence estimate is
unbiased against the Kalman filter's exact evidence (E[Ẑ] = Z, Del Moral 2004, Thm 7.4.2).

Seeds are fixed, so each test is deterministic; a p-value must exceed 1e-3 and a z-score stay
within ±3.29 (the same two-sided level), Bonferroni-corrected where one test checks a family
of z-scores (the family's chance of a false alarm stays 1e-3).
``python tests/smc/test_generator_statistics.py`` prints every statistic the tests check.
"""

import functools

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
NUM_SEEDS = 256


def stream_bits():
    """2¹⁹ consecutive uint32 words of one key's stream."""
    return np.asarray(jax.jit(fast_uniform_bits, static_argnums=1)(jr.key(7), (NUM_DRAWS,)))


def _uniforms(words):
    """The 24-bit uniforms the engine's normals are made from: (b + ½) / 2²⁴ for the top bits."""
    return ((words >> 8).astype(np.float64) + 0.5) / 2.0**24


def _z_limit(count):
    """The |z| a family of ``count`` two-sided z-scores must stay within (Bonferroni)."""
    return float(stats.norm.isf(P_MIN / 2 / count))


def _all_z_within_limit(statistics):
    scores = [abs(value) for name, value in statistics.items() if name.endswith(" z")]
    return max(scores) < _z_limit(len(scores))


def _correlation_z(first, second):
    """z-score of the Pearson correlation of two flat samples (√n r ~ N(0, 1) if independent)."""
    return float(np.corrcoef(first.ravel(), second.ravel())[0, 1] * np.sqrt(first.size))


def uniform_statistics(bits):
    """Chi-square over 1 024 bins and KS p-values of the uniforms; largest |z| of a bit's count
    of ones (every bit of the word, the 8 the normals drop too)."""
    uniforms = _uniforms(bits)
    counts = np.bincount((uniforms * 1024).astype(np.int64), minlength=1024)
    ones = np.array([np.count_nonzero(bits & np.uint32(1 << bit)) for bit in range(32)])
    return {"chi-square p (1024 bins)": float(stats.chisquare(counts).pvalue),
            "KS p": float(stats.kstest(uniforms, "uniform").pvalue),
            "largest |z| of a bit's ones": float(np.max(
                np.abs(ones - bits.size / 2) / np.sqrt(bits.size / 4)))}


def serial_statistics(bits):
    """Serial-pair chi-square p (non-overlapping pairs on a 32 × 32 grid, 1 023 degrees of
    freedom), Wald–Wolfowitz runs z above/below ½, and lag-1 to lag-4 autocorrelation z's."""
    uniforms = _uniforms(bits)
    cells = (uniforms[0::2] * 32).astype(np.int64) * 32 + (uniforms[1::2] * 32).astype(np.int64)
    above = uniforms > 0.5
    runs = 1 + np.count_nonzero(above[1:] != above[:-1])
    n1, n2 = np.count_nonzero(above), np.count_nonzero(~above)
    mean = 2 * n1 * n2 / (n1 + n2) + 1
    variance = (mean - 1) * (mean - 2) / (n1 + n2 - 1)
    centred = uniforms - uniforms.mean()
    lags = {f"lag-{lag} autocorrelation z": float(
        np.dot(centred[:-lag], centred[lag:]) / np.dot(centred, centred) * np.sqrt(bits.size))
        for lag in (1, 2, 3, 4)}
    return {"serial-pair chi-square p": float(
                stats.chisquare(np.bincount(cells, minlength=1024)).pvalue),
            "runs z": float((runs - mean) / np.sqrt(variance)), **lags}


def normal_statistics(bits):
    """KS p against N(0, 1) and z-scores of the mean, variance, skewness, excess kurtosis and
    the count beyond ±3 (normal-theory standard errors)."""
    normals = np.asarray(bits_to_normal(jnp.asarray(bits)), np.float64)
    n = normals.size
    beyond = np.count_nonzero(np.abs(normals) > 3)
    expected = n * 2 * stats.norm.sf(3)
    return {"KS p": float(stats.kstest(normals, "norm").pvalue),
            "mean z": float(normals.mean() * np.sqrt(n)),
            "variance z": float((normals.var() - 1) / np.sqrt(2 / n)),
            "skewness z": float(stats.skew(normals) / np.sqrt(6 / n)),
            "excess kurtosis z": float(stats.kurtosis(normals) / np.sqrt(24 / n)),
            "beyond ±3 z": float((beyond - expected) / np.sqrt(expected))}


def engine_statistics(noise):
    """For the engine's draws ``(runs, time, particles, coordinates)``: KS p against N(0, 1),
    correlation z's between neighbouring particles, consecutive frames, neighbouring
    coordinates and neighbouring runs' keys (and of the squares: dependence in magnitude), and
    the chi-square p of consecutive frames' sign pairs."""
    squares = noise**2
    signs = (noise[:, :-1, :, 0] > 0).astype(np.int64) * 2 + (noise[:, 1:, :, 0] > 0)
    return {"KS p": float(stats.kstest(noise.ravel(), "norm").pvalue),
            "neighbouring particles z": _correlation_z(noise[:, :, :-1], noise[:, :, 1:]),
            "consecutive frames z": _correlation_z(noise[:, :-1], noise[:, 1:]),
            "neighbouring coordinates z": _correlation_z(noise[..., :-1], noise[..., 1:]),
            "neighbouring runs z": _correlation_z(noise[:-1], noise[1:]),
            "squares, neighbouring particles z": _correlation_z(squares[:, :, :-1],
                                                                squares[:, :, 1:]),
            "squares, consecutive frames z": _correlation_z(squares[:, :-1], squares[:, 1:]),
            "sign pairs over frames chi-square p": float(
                stats.chisquare(np.bincount(signs.ravel(), minlength=4)).pvalue)}


def particle_key_statistics():
    """Streams of ``particle_keys`` for neighbouring indices: correlation z, and chi-square p of
    the first position of every stream."""
    keys = particle_keys(jr.key(3), 1 << 15)
    uniforms = _uniforms(np.asarray(jax.vmap(lambda key: fast_uniform_bits(key, (8,)))(keys)))
    counts = np.bincount((uniforms[:, 0] * 256).astype(np.int64), minlength=256)
    return {"neighbouring indices z": _correlation_z(uniforms[:-1] - 0.5, uniforms[1:] - 0.5),
            "first draws chi-square p": float(stats.chisquare(counts).pvalue)}


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


@functools.cache
def filter_runs(noise_scale):
    """``NUM_SEEDS`` runs of the float32 bootstrap filter (64 particles, ``fast_normal`` noise)
    on one small linear-Gaussian model (2 states, 1 observation, 10 frames), its transition
    noise's scale multiplied by ``noise_scale``.

    Returns:
        exp(log Ẑ − log Z) per seed ``(seeds,)``, and the standard normals the engine drew for
        the transitions ``(seeds, 9 frames, 64 particles, 2)``, recovered from the kept history
        as ε = L⁻¹ (x_t − A x_parent) (particle i's draw comes from its own key, whoever its
        parent).
    """
    # jitted whole: one compile each instead of one per operation outside their scans
    model64 = jax.jit(smc.random_linear_gaussian, static_argnums=(1, 2, 3))(
        jr.key(5), 2, 1, jnp.float64)
    observations = jnp.asarray(_sample_observations(model64, 10, np.random.default_rng(6)))
    exact = float(jax.jit(smc.kalman_filter)(model64, observations).log_evidence)
    model32 = jax.tree.map(lambda leaf: leaf.astype(jnp.float32), model64)
    model32 = type(model32)(
        model32.transition_matrix, noise_scale**2 * model32.transition_covariance,
        model32.observation_matrix, model32.observation_covariance, model32.initial_mean,
        model32.initial_covariance)
    keys = jr.split(jr.key(2026), NUM_SEEDS)
    batch = jnp.broadcast_to(observations.astype(jnp.float32), (NUM_SEEDS, *observations.shape))
    result = smc.run_batch(keys, model32, batch, 64, chunk_size=None, keep_history=True)
    ratios = np.exp(np.asarray(result.log_evidence, np.float64) - exact)
    particles = np.asarray(result.particles, np.float64)  # (seeds, time, particles, 2)
    ancestors = np.asarray(result.ancestors)  # (seeds, time, particles): parents in t − 1
    parents = np.take_along_axis(particles[:, :-1], ancestors[:, 1:, :, None], axis=2)
    transition = np.asarray(model32.transition_matrix, np.float64)
    cholesky = np.linalg.cholesky(np.asarray(model32.transition_covariance, np.float64))
    residuals = particles[:, 1:] - parents @ transition.T
    noise = np.linalg.solve(cholesky, residuals[..., None])[..., 0]
    return ratios, noise


def evidence_statistics(ratios):
    """Mean of Ẑ/Z, its standard error, the z-score of mean − 1, and the mean of log Ẑ − log Z."""
    standard_error = float(ratios.std(ddof=1) / np.sqrt(ratios.size))
    return {"mean of Ẑ/Z": float(ratios.mean()), "standard error": standard_error,
            "z of mean − 1": float((ratios.mean() - 1) / standard_error),
            "mean of log Ẑ − log Z": float(np.log(ratios).mean())}


@pytest.fixture(scope="module")
def bits():
    return stream_bits()


def test_uniforms_fill_bins_evenly_and_pass_kolmogorov_smirnov(bits):
    statistics = uniform_statistics(bits)
    assert statistics["chi-square p (1024 bins)"] > P_MIN
    assert statistics["KS p"] > P_MIN
    assert statistics["largest |z| of a bit's ones"] < _z_limit(32)


def test_consecutive_uniforms_are_serially_independent(bits):
    statistics = serial_statistics(bits)
    assert statistics["serial-pair chi-square p"] > P_MIN
    assert _all_z_within_limit(statistics)


def test_normals_pass_kolmogorov_smirnov_and_have_standard_moments(bits):
    statistics = normal_statistics(bits)
    assert statistics["KS p"] > P_MIN
    assert _all_z_within_limit(statistics)


def test_engine_draws_are_independent_across_particles_and_frames():
    statistics = engine_statistics(filter_runs(1.0)[1])
    assert statistics["KS p"] > P_MIN and statistics["sign pairs over frames chi-square p"] > P_MIN
    assert _all_z_within_limit(statistics)


def test_particle_keys_give_uncorrelated_streams_for_neighbouring_indices():
    statistics = particle_key_statistics()
    assert abs(statistics["neighbouring indices z"]) < Z_MAX
    assert statistics["first draws chi-square p"] > P_MIN


def test_statistics_see_a_bad_generator():
    """The same checks on a generator with a known flaw fail: neighbouring counters' bits
    without the hash (serially dependent), and the hash with its top bit stuck."""
    counter = np.arange(NUM_DRAWS, dtype=np.uint32) * np.uint32(2654435761)  # a Weyl sequence
    assert serial_statistics(counter)["serial-pair chi-square p"] < P_MIN
    stuck = stream_bits() | np.uint32(1 << 31)
    assert uniform_statistics(stuck)["KS p"] < P_MIN
    assert abs(normal_statistics(stuck)["mean z"]) > Z_MAX


def test_evidence_estimate_is_unbiased_against_kalman_over_seeds():
    statistics = evidence_statistics(filter_runs(1.0)[0])
    # the test has the power to see a few per cent of bias
    assert 0 < statistics["standard error"] < 0.05
    assert abs(statistics["z of mean − 1"]) < Z_MAX
    # log Ẑ itself is biased low (Jensen)
    assert statistics["mean of log Ẑ − log Z"] < 0
    # and the same check sees a wrong model: transition noise 0.6 times too small
    assert abs(evidence_statistics(filter_runs(0.6)[0])["z of mean − 1"]) > Z_MAX


if __name__ == "__main__":
    jax.config.update("jax_enable_x64", True)  # as the tests run (tests/conftest.py)
    words = stream_bits()
    for title, values in (
            ("uniforms", uniform_statistics(words)), ("serial", serial_statistics(words)),
            ("normals", normal_statistics(words)),
            ("engine (the transitions' draws of the runs below)", engine_statistics(
                filter_runs(1.0)[1])),
            ("particle_keys", particle_key_statistics()),
            (f"evidence over {NUM_SEEDS} seeds", evidence_statistics(filter_runs(1.0)[0])),
            ("evidence, transition noise × 0.6", evidence_statistics(filter_runs(0.6)[0]))):
        print(f"{title}: " + ", ".join(f"{name} {value:.4g}" for name, value in values.items()))
