"""The baselines on detections, each against an answer known without it: Butterworth's
coefficients and its gain at the cutoff, the 1€ filter's exponential smoothing, the Kalman
smoother's exactness on a noiseless straight line and its filling of gaps."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.vision.smoothing import (
    butterworth_coefficients,
    butterworth_filter,
    filtfilt,
    fit_kalman_noise,
    kalman_smoother,
    one_euro_filter,
)


def test_butterworth_coefficients_are_the_textbook_ones():
    # scipy.signal.butter(2, 0.2) (cutoff 0.2 of Nyquist): fs = 2, fc = 0.2
    b, a = butterworth_coefficients(2, 0.2, 2.0)
    np.testing.assert_allclose(b, [0.06745527, 0.13491055, 0.06745527], rtol=1e-6)
    np.testing.assert_allclose(a, [1.0, -1.1429805, 0.4128016], rtol=1e-6)
    # first order at a quarter of the sampling rate: the bilinear transform gives b = [.5, .5]
    b, a = butterworth_coefficients(1, 0.25, 1.0)
    np.testing.assert_allclose(b, [0.5, 0.5], atol=1e-12)
    np.testing.assert_allclose(a, [1.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("frequency", [0.0, 2.0, 6.0, 9.0, 18.0])
def test_forward_backward_butterworth_halves_a_sinusoid_at_its_cutoff(frequency):
    # Pose2Sim's order 4 is 2 per pass: each pass has |H|² = 1 / (1 + (tan(πf/fs) /
    # tan(πf_c/fs))^4), −3 dB at the cutoff, and both passes together square it: 1/2 there
    fps, t = 60.0, np.arange(600) / 60.0
    gain = 1 / (1 + (np.tan(np.pi * frequency / fps) / np.tan(np.pi * 6.0 / fps)) ** 4)
    signal = np.cos(2 * np.pi * frequency * t) + 3.0
    filtered = butterworth_filter(signal[:, None], fps)[:, 0]
    middle = filtered[200:400] - 3.0
    amplitude = 0.5 * (middle.max() - middle.min()) if frequency else middle.mean()
    assert amplitude == pytest.approx(gain, abs=0.003)
    if frequency == 6.0:
        assert gain == pytest.approx(0.5)


def test_filtfilt_is_zero_phase_and_the_filter_leaves_gaps_and_short_runs():
    # a digital Butterworth's gain is 1 / sqrt(1 + (tan(ω/2) / tan(ω_c/2))^2n); forward and
    # backward square it and leave no phase shift: 2 Hz comes out as G cos, not shifted
    b, a = butterworth_coefficients(2, 6.0, 60.0)
    t = np.arange(300) / 60.0
    gain = 1 / (1 + (np.tan(np.pi * 2 / 60) / np.tan(np.pi * 6 / 60)) ** 4)
    out = filtfilt(b, a, np.cos(2 * np.pi * 2.0 * t))
    np.testing.assert_allclose(out[50:250], gain * np.cos(2 * np.pi * 2.0 * t[50:250]),
                               atol=1e-4)
    np.testing.assert_allclose(filtfilt(b, a, np.full(30, 7.0)), 7.0, atol=1e-12)
    series = np.cos(np.arange(40) / 3.0)
    series[20] = np.nan
    series[25:] = np.nan
    out = butterworth_filter(series[:, None], 60.0)[:, 0]
    assert np.isnan(out[20]) and np.isnan(out[25:]).all()
    assert np.array_equal(out[21:25], series[21:25])  # 4 frames: shorter than the padding
    assert not np.allclose(out[:20], series[:20])


def test_the_one_euro_filter_is_an_exponential_smoother_at_its_minimum_cutoff():
    fps = 30.0
    steps = np.r_[0.0, np.ones(9)][:, None]
    out = one_euro_filter(steps, fps, min_cutoff=2.0, beta=0.0)[:, 0]
    alpha = 1 / (1 + fps / (2 * np.pi * 2.0))
    np.testing.assert_allclose(out[1:], 1 - (1 - alpha) ** np.arange(1, 10), rtol=1e-12)
    # with β the cutoff rises with the speed: it lags less behind a ramp
    ramp = np.arange(30.0)[:, None] * 5.0
    slow = one_euro_filter(ramp, fps)[-1, 0]
    fast = one_euro_filter(ramp, fps, beta=0.1)[-1, 0]
    assert ramp[-1, 0] - fast < 0.5 * (ramp[-1, 0] - slow)
    gap = ramp.copy()
    gap[10] = np.nan
    assert np.isnan(one_euro_filter(gap, fps)[10, 0])


def test_the_kalman_smoother_recovers_a_line_through_gaps_and_ignores_low_confidence():
    fps = 30.0
    t = np.arange(40) / fps
    truth = np.stack([100 + 60 * t, 50 - 30 * t], -1)[:, None]  # (time, 1, 2)
    points = truth.copy()
    points[10:15] = np.nan                                  # a gap
    points[20] += 80.0                                     # a wild detection ...
    confidence = np.ones(points.shape[:2])
    confidence[20] = 0.1                                   # ... of low confidence
    smoothed, stds, noise = kalman_smoother(points, fps, confidence=confidence,
                                            min_confidence=0.3, measurement_std=1.0,
                                            acceleration_std=200.0)
    np.testing.assert_allclose(smoothed, truth, atol=0.05)
    assert stds[12].min() > 1.5 * stds[30].max()           # less sure inside the gap
    # without the confidence the wild frame pulls the estimate
    pulled, _, _ = kalman_smoother(points, fps, measurement_std=1.0, acceleration_std=200.0)
    assert np.abs(pulled[20] - truth[20]).max() > 5.0


def test_the_fitted_noise_follows_the_measurement_noise():
    rng = np.random.default_rng(0)
    fps, t = 60.0, np.arange(200) / 60.0
    truth = 200 + 40 * np.sin(2 * np.pi * 0.5 * t)
    noisy = truth[:, None, None] + rng.normal(0.0, 3.0, (200, 2, 1))
    noise = fit_kalman_noise(noisy, fps)
    assert 1.5 < noise["measurement_std"] < 6.0 and not noise["grid_edge"]
    smoothed, _, _ = kalman_smoother(noisy, fps)
    assert np.abs(smoothed[20:-20, :, 0] - truth[20:-20, None]).mean() < 1.5  # below σ = 3


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="cutoff must lie"):
        butterworth_filter(np.zeros((20, 2)), 10.0, cutoff=6.0)
    with pytest.raises(ValueError, match="even integer"):
        butterworth_filter(np.zeros((20, 2)), 60.0, order=3)
    with pytest.raises(ValueError, match="confidence must have shape"):
        kalman_smoother(np.zeros((5, 3, 2)), 30.0, confidence=np.ones((5, 2)))
