"""``papers.kwatra2002.diagnosis``: the autocorrelation and the averaged error of hypotheses'
errors, against processes whose answer is known (white noise, AR(1), a constant offset)."""

import numpy as np
import pytest

from papers.kwatra2002.diagnosis import (
    averaged_mse,
    error_autocorrelation,
    part_errors,
    summarise,
)


def _ar1(rng, phi, length, parts=5):
    """``(length, parts, 2)`` stationary AR(1) errors e_t = φ e_t−1 + √(1 − φ²) ε_t."""
    errors = np.zeros((length, parts, 2))
    errors[0] = rng.normal(size=(parts, 2))
    for t in range(1, length):
        errors[t] = phi * errors[t - 1] + np.sqrt(1 - phi ** 2) * rng.normal(size=(parts, 2))
    return errors


def test_autocorrelation_of_ar1_is_phi_to_the_lag():
    rng = np.random.default_rng(0)
    sequences = [_ar1(rng, 0.8, 400) for _ in range(10)]
    rho = error_autocorrelation(sequences, lags=(1, 2, 5))
    np.testing.assert_allclose(rho.mean(axis=1), [0.8, 0.64, 0.8 ** 5], atol=0.03)
    white = error_autocorrelation([rng.normal(size=(400, 5, 2)) for _ in range(10)], lags=(1,))
    assert np.all(np.abs(white) < 0.05)
    constant = error_autocorrelation([np.ones((30, 5, 2)) * 7.0], lags=(1, 10))
    np.testing.assert_allclose(constant, 1.0)


def test_averaging_white_noise_divides_its_error_by_the_width_but_not_an_offset():
    rng = np.random.default_rng(1)
    noise = [rng.normal(size=(2000, 5, 2)) for _ in range(2)]
    raw = averaged_mse(noise, 1)
    np.testing.assert_allclose(raw, 2.0, rtol=0.05)  # two coordinates of unit variance
    np.testing.assert_allclose(averaged_mse(noise, 9) / raw, 1 / 9, rtol=0.1)
    offset = [np.full((50, 5, 2), 3.0)]
    np.testing.assert_allclose(averaged_mse(offset, 15), averaged_mse(offset, 1))
    with pytest.raises(ValueError, match="positive odd"):
        averaged_mse(noise, 4)


def test_summary_reports_the_known_process():
    rng = np.random.default_rng(2)
    summary = summarise([_ar1(rng, 0.9, 600) for _ in range(4)])
    assert summary["hands"]["autocorrelation"]["1"] == pytest.approx(0.9, abs=0.03)
    assert summary["all"]["mse"] == pytest.approx(2.0, rel=0.15)
    # AR(1) at φ = 0.9: averaging 31 frames leaves (1 + φ)/(1 − φ)/31 ≈ 0.6 of it, less the
    # window's edge effects; far more than white noise's 1/31
    left = summary["all"]["fraction_left_after_averaging"]["31"]
    assert 0.3 < left < 0.7


def test_part_errors_take_the_better_left_right_assignment():
    truth = np.zeros((1, 5, 2))
    truth[0, 1], truth[0, 2] = (0, 0), (10, 0)
    estimate = truth.copy()
    estimate[0, 1], estimate[0, 2] = (11, 0), (1, 0)  # the hands swapped, each 1 px off
    errors = part_errors(estimate, truth)
    np.testing.assert_allclose(errors[0, 1:3], [[1, 0], [1, 0]])
    with pytest.raises(ValueError, match=r"\(time, 5, 2\)"):
        part_errors(np.zeros((2, 4, 2)), np.zeros((2, 4, 2)))
