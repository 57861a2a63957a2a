"""Baselines on a detector's keypoints: what smoothing them over time gives without a body model.

Each takes ``points`` ``(time, ..., 2)`` pixels (or any trailing coordinates: ``(time, ..., 3)``
metres), NaN where the detector found nothing, and smooths every coordinate of every keypoint
as its own series:

- :func:`butterworth_filter`: Pose2Sim's filter (``filtering.butterworth``: order 4, 6 Hz): a
  Butterworth low-pass of half the order, run forward and backward (zero phase, the order
  doubled), on each run of frames without a gap longer than its padding; NaN stays NaN. The
  filter design (:func:`butterworth_coefficients`: the bilinear transform of the analog
  prototype, prewarped) and the forward-backward filtering (:func:`filtfilt`: odd-extension
  padding and steady-state initial conditions, as ``scipy.signal.filtfilt``) are here, in NumPy.
- :func:`one_euro_filter`: Casiez, Roussel & Vogel, "1€ Filter" (CHI 2012): an exponential
  smoother whose cutoff rises with the speed, ``f_c = f_c,min + β |ẋ|`` (their filter as they
  give it), with the paper's defaults ``f_c,min = 1 Hz``, ``β = 0``, ``f_c,d = 1 Hz``.
  Causal; a missing frame is skipped (its output NaN), the next one's period spans the gap.
- :func:`kalman_smoother`: a constant-velocity Kalman filter and Rauch–Tung–Striebel smoother
  (JAX, ``lax.scan``, every series at once), frames that are NaN or of low confidence treated as
  missing (predicted through, so gaps are filled); its two noise levels by default the ones that
  maximise the log-evidence of the observed frames over a grid (:func:`fit_kalman_noise`).

Tests with known answers: ``tests/vision/test_smoothing.py``.
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = [
    "BUTTERWORTH_CUTOFF", "BUTTERWORTH_ORDER", "ONE_EURO_BETA", "ONE_EURO_DERIVATIVE_CUTOFF",
    "ONE_EURO_MIN_CUTOFF", "butterworth_coefficients", "butterworth_filter", "filtfilt",
    "fit_kalman_noise", "kalman_smoother", "lfilter", "one_euro_filter",
]

BUTTERWORTH_ORDER = 4
"""Pose2Sim's ``[filtering.butterworth] order``: the order after the forward-backward pass (each
pass is of half of it, ``signal.butter(order / 2, ...)`` in Pose2Sim's ``filtering.py``)."""
BUTTERWORTH_CUTOFF = 6.0
"""Pose2Sim's ``[filtering.butterworth] cut_off_frequency``, Hz (its ``Config.toml``)."""
ONE_EURO_MIN_CUTOFF = 1.0
"""Casiez et al. 2012's minimum cutoff ``f_c,min``, Hz (their recommended starting point)."""
ONE_EURO_BETA = 0.0
"""Casiez et al. 2012's speed coefficient ``β`` (their starting point: 0, then raised)."""
ONE_EURO_DERIVATIVE_CUTOFF = 1.0
"""Casiez et al. 2012's cutoff of the speed's own low-pass ``f_c,d``, Hz."""


def butterworth_coefficients(order: int, cutoff: float, fps: float
                             ) -> tuple[np.ndarray, np.ndarray]:
    """A digital Butterworth low-pass: ``(b, a)``, ``a[0] = 1``, gain 1 at 0 Hz.

    The analog prototype's poles ``ω_a exp(iπ(2k + n − 1)/2n)``, k = 1..n, at the prewarped
    cutoff ``ω_a = 2 fs tan(π f_c / fs)``, mapped by the bilinear transform ``z = (2 fs + s) /
    (2 fs − s)``; its n zeros go to ``z = −1``.

    Args:
        order: n ≥ 1, of one pass.
        cutoff: f_c in Hz, below the Nyquist frequency ``fps / 2``.
        fps: the sampling rate fs, Hz.
    """
    if int(order) != order or order < 1:
        raise ValueError(f"order must be a positive integer, got {order}")
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    if not (0 < cutoff < fps / 2):
        raise ValueError(f"cutoff must lie in (0, fps / 2 = {fps / 2:g}) Hz, got {cutoff}")
    order = int(order)
    warped = 2.0 * fps * math.tan(math.pi * cutoff / fps)
    k = np.arange(1, order + 1)
    poles = warped * np.exp(1j * np.pi * (2 * k + order - 1) / (2 * order))
    z_poles = (2.0 * fps + poles) / (2.0 * fps - poles)
    a = np.real(np.poly(z_poles))
    b = np.real(np.poly(-np.ones(order)))
    return b * (a.sum() / b.sum()), a


def _companion_zi(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The direct-form-II-transposed state of a step's steady state (``scipy.signal.lfilter_zi``):
    ``(I − Aᵀ) zi = b[1:] − a[1:] b[0]``, A the companion matrix of ``a``."""
    n = len(a) - 1
    companion = np.zeros((n, n))
    companion[0] = -a[1:]
    companion[1:, :-1] = np.eye(n - 1)
    return np.linalg.solve(np.eye(n) - companion.T, b[1:] - a[1:] * b[0])


def lfilter(b, a, x: np.ndarray, zi: np.ndarray | None = None) -> np.ndarray:
    """IIR filtering along axis 0 (direct form II transposed), every other axis at once.

    Args:
        b, a: the coefficients, ``a[0] = 1``, of equal length.
        x: ``(time, ...)``.
        zi: the initial state ``(len(a) − 1, ...)``, or zeros.
    """
    b, a = np.asarray(b, np.float64), np.asarray(a, np.float64)
    x = np.asarray(x, np.float64)
    state = np.zeros((len(a) - 1, *x.shape[1:])) if zi is None else np.array(zi, np.float64)
    out = np.empty_like(x)
    for t in range(len(x)):
        y = b[0] * x[t] + state[0]
        for i in range(len(state) - 1):
            state[i] = b[i + 1] * x[t] + state[i + 1] - a[i + 1] * y
        state[-1] = b[-1] * x[t] - a[-1] * y
        out[t] = y
    return out


def filtfilt(b, a, x: np.ndarray, padlen: int | None = None) -> np.ndarray:
    """Zero-phase filtering along axis 0: forward, then backward, each pass started at its
    steady state for the first sample, on the signal extended by ``padlen`` samples of its odd
    reflection at each end (``scipy.signal.filtfilt``'s default, ``padlen = 3 max(len(a),
    len(b))`` when None). ``x`` needs more than ``padlen`` samples."""
    b, a = np.asarray(b, np.float64), np.asarray(a, np.float64)
    x = np.asarray(x, np.float64)
    padlen = 3 * max(len(a), len(b)) if padlen is None else int(padlen)
    if len(x) <= padlen:
        raise ValueError(f"filtfilt needs more than padlen = {padlen} samples, got {len(x)}")
    if padlen:
        head = 2 * x[0] - x[padlen:0:-1]
        tail = 2 * x[-1] - x[-2:-padlen - 2:-1]
        x = np.concatenate([head, x, tail])
    zi = _companion_zi(b, a).reshape(-1, *([1] * (x.ndim - 1)))
    forward = lfilter(b, a, x, zi * x[0])
    backward = lfilter(b, a, forward[::-1], zi * forward[-1])[::-1]
    return backward[padlen:len(backward) - padlen] if padlen else backward


def _runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` of each run of True."""
    edges = np.diff(np.concatenate([[0], valid.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _series(points) -> tuple[np.ndarray, tuple[int, ...]]:
    points = np.asarray(points, np.float64)
    if points.ndim < 2 or points.shape[0] == 0:
        raise ValueError(f"points must be (time, ..., coordinates), got shape {points.shape}")
    return points.reshape(points.shape[0], -1), points.shape


def butterworth_filter(points, fps: float, *, cutoff: float = BUTTERWORTH_CUTOFF,
                       order: int = BUTTERWORTH_ORDER) -> np.ndarray:
    """Pose2Sim's Butterworth filter (its ``filtering.butterworth_filter_1d``): a low-pass of
    ``order / 2`` at ``cutoff`` Hz run forward and backward, on each series' runs of frames
    without NaN that are longer than the padding (``3 max(len(a), len(b))``, 9 frames for order
    4); shorter runs are left as detected, NaN as NaN.

    Args:
        points: ``(time, ...)`` keypoints, NaN where missing.
        fps: the video's frame rate.
        cutoff, order: Hz, and the even order after both passes.

    Returns:
        ``(time, ...)`` like ``points``.
    """
    if int(order) != order or order < 2 or order % 2:
        raise ValueError(f"order must be an even integer >= 2 (both passes), got {order}")
    b, a = butterworth_coefficients(order // 2, cutoff, fps)
    padlen = 3 * max(len(a), len(b))
    series, shape = _series(points)
    out = series.copy()
    for column in range(series.shape[1]):
        for start, stop in _runs(np.isfinite(series[:, column])):
            if stop - start > padlen:
                out[start:stop, column] = filtfilt(b, a, series[start:stop, column], padlen)
    return out.reshape(shape)


def one_euro_filter(points, fps: float, *, min_cutoff: float = ONE_EURO_MIN_CUTOFF,
                    beta: float = ONE_EURO_BETA,
                    derivative_cutoff: float = ONE_EURO_DERIVATIVE_CUTOFF) -> np.ndarray:
    """The 1€ filter (Casiez, Roussel & Vogel 2012) on every series.

    Per frame, with period ``T_e`` (frames since the last detected one over ``fps``) and
    ``α(f_c) = 1 / (1 + τ / T_e)``, ``τ = 1 / (2π f_c)``: the speed ``ẋ = (x − x̂_prev) / T_e``
    is smoothed at ``derivative_cutoff``, the cutoff is ``f_c = min_cutoff + β |ẋ̂|``, and
    ``x̂ = α(f_c) x + (1 − α(f_c)) x̂_prev``. The first detected frame is taken as it is.

    Args:
        points: ``(time, ...)`` keypoints, NaN where missing (left NaN).
        fps: the video's frame rate.
        min_cutoff, beta, derivative_cutoff: f_c,min (Hz), β (per unit of speed), f_c,d (Hz).

    Returns:
        ``(time, ...)`` like ``points``.
    """
    if not (min_cutoff > 0 and derivative_cutoff > 0 and beta >= 0 and fps > 0):
        raise ValueError(f"one-euro needs min_cutoff > 0, derivative_cutoff > 0, beta >= 0, "
                         f"fps > 0; got {min_cutoff}, {derivative_cutoff}, {beta}, {fps}")
    series, shape = _series(points)
    out = np.full_like(series, np.nan)
    estimate = np.full(series.shape[1], np.nan)
    speed = np.zeros(series.shape[1])
    last = np.full(series.shape[1], -1)

    def alpha(cutoff, period):
        return 1.0 / (1.0 + 1.0 / (2.0 * np.pi * cutoff * period))

    for t, x in enumerate(series):
        seen = np.isfinite(x)
        first = seen & (last < 0)
        later = seen & (last >= 0)
        period = (t - last) / fps
        raw_speed = np.where(later, (x - estimate) / np.where(later, period, 1.0), 0.0)
        speed = np.where(later, speed + alpha(derivative_cutoff, period) * (raw_speed - speed),
                         speed)
        weight = alpha(min_cutoff + beta * np.abs(speed), period)
        estimate = np.where(first, x, np.where(later, estimate + weight * (x - estimate),
                                               estimate))
        last = np.where(seen, t, last)
        out[t] = np.where(seen, estimate, np.nan)
    return out.reshape(shape)


def _kalman(observations, observed, fps, measurement_std, acceleration_std, *, smooth=True):
    """Constant-velocity Kalman filter (+ RTS smoother) of scalar series in JAX.

    Args:
        observations: ``(time, series)``, centred, zeros where unobserved.
        observed: ``(time, series)`` bool.
        measurement_std, acceleration_std: ``(...)`` broadcast against each other (a grid).

    Returns:
        ``(positions (..., time, series), stds (..., time, series), log_evidence (..., series))``.
    """
    import jax.numpy as jnp

    r, a = jnp.broadcast_arrays(jnp.asarray(measurement_std, float),
                                jnp.asarray(acceleration_std, float))
    positions, stds, logs = _kalman_function(float(fps), bool(smooth))(
        jnp.asarray(observations, float), jnp.asarray(observed), r.reshape(-1), a.reshape(-1))
    return (positions.reshape(*r.shape, *positions.shape[1:]),
            stds.reshape(*r.shape, *stds.shape[1:]), logs.reshape(*r.shape, logs.shape[-1]))


@functools.lru_cache(maxsize=8)
def _kalman_function(fps: float, smooth: bool):
    """The jitted Kalman filter/smoother over a grid of noise levels and every series at once
    (one compilation per frame rate and mode). The 2x2 algebra is written out on ``(grid,
    series)`` arrays: a small graph that compiles in a fraction of the time a vmapped matrix
    version takes."""
    import jax
    import jax.numpy as jnp
    from jax import lax

    dt = 1.0 / fps

    def run(y, seen, r, a):
        r2 = (r ** 2)[:, None]
        # white-noise acceleration of spectral density q = σ_a²: the discrete Q of a constant-
        # velocity model (Bar-Shalom, Li & Kirubarajan 2001, §6.2.2)
        q = (a ** 2)[:, None]
        q00, q01, q11 = q * dt ** 3 / 3, q * dt ** 2 / 2, q * dt
        shape = (r.shape[0], y.shape[1])
        # start: the first observed value, unknown speed (±10 σ_r per frame)
        first = y[jnp.argmax(seen, axis=0), jnp.arange(y.shape[1])]
        start = (jnp.broadcast_to(first, shape), jnp.zeros(shape), jnp.broadcast_to(r2, shape),
                 jnp.zeros(shape), jnp.broadcast_to((10.0 * fps) ** 2 * r2, shape))

        def step(carry, inputs):
            m0, m1, p00, p01, p11 = carry
            value, present, index = inputs
            moved = index > 0
            m0 = jnp.where(moved, m0 + dt * m1, m0)
            p00, p01, p11 = (jnp.where(moved, p00 + 2 * dt * p01 + dt ** 2 * p11 + q00, p00),
                             jnp.where(moved, p01 + dt * p11 + q01, p01),
                             jnp.where(moved, p11 + q11, p11))
            predicted = (m0, m1, p00, p01, p11)
            variance = p00 + r2
            residual = value - m0
            k0, k1 = p00 / variance, p01 / variance
            updated = (m0 + k0 * residual, m1 + k1 * residual, p00 - k0 * p00, p01 - k0 * p01,
                       p11 - k1 * p01)
            log_lik = -0.5 * (residual ** 2 / variance + jnp.log(2 * jnp.pi * variance))
            filtered = tuple(jnp.where(present, u, v) for u, v in zip(updated, predicted,
                                                                       strict=True))
            return filtered, (filtered, predicted, jnp.where(present, log_lik, 0.0))

        times = jnp.arange(y.shape[0])
        _, (filtered, predicted, logs) = lax.scan(step, start, (y, seen, times))
        if not smooth:
            return filtered[0], jnp.sqrt(filtered[2]), logs.sum(0)

        def back(carry, inputs):
            s0, s1, s00, s01, s11 = carry
            (m0, m1, p00, p01, p11), (n0, n1, n00, n01, n11) = inputs
            # G = P Fᵀ P_pred⁻¹ (Rauch, Tung & Striebel 1965), the 2x2 inverse written out
            a00, a01, a10, a11 = p00 + dt * p01, p01, p01 + dt * p11, p11
            det = n00 * n11 - n01 ** 2
            g00 = (a00 * n11 - a01 * n01) / det
            g01 = (a01 * n00 - a00 * n01) / det
            g10 = (a10 * n11 - a11 * n01) / det
            g11 = (a11 * n00 - a10 * n01) / det
            d0, d1 = s0 - n0, s1 - n1
            e00, e01, e11 = s00 - n00, s01 - n01, s11 - n11
            # P + G E Gᵀ, E symmetric
            h00, h01 = g00 * e00 + g01 * e01, g00 * e01 + g01 * e11
            h10, h11 = g10 * e00 + g11 * e01, g10 * e01 + g11 * e11
            smoothed = (m0 + g00 * d0 + g01 * d1, m1 + g10 * d0 + g11 * d1,
                        p00 + h00 * g00 + h01 * g01, p01 + h00 * g10 + h01 * g11,
                        p11 + h10 * g10 + h11 * g11)
            return smoothed, smoothed

        last = tuple(part[-1] for part in filtered)
        inputs = (tuple(part[:-1] for part in filtered), tuple(part[1:] for part in predicted))
        _, smoothed = lax.scan(back, last, inputs, reverse=True)
        position = jnp.concatenate([smoothed[0], last[0][None]])
        variance = jnp.concatenate([smoothed[2], last[2][None]])
        return position, jnp.sqrt(jnp.maximum(variance, 0.0)), logs.sum(0)

    def grid_first(y, seen, r, a):
        position, std, logs = run(y, seen, r, a)  # (time, grid, series), (grid, series)
        return jnp.moveaxis(position, 1, 0), jnp.moveaxis(std, 1, 0), logs

    return jax.jit(grid_first)


def _observed_series(points, confidence, min_confidence):
    series, shape = _series(points)
    seen = np.isfinite(series)
    if confidence is not None:
        confidence = np.asarray(confidence, np.float64)
        if confidence.shape != shape[:-1]:
            raise ValueError(f"confidence must have shape {shape[:-1]} (points without its last "
                             f"axis), got {confidence.shape}")
        keep = np.nan_to_num(confidence) >= min_confidence
        seen &= np.repeat(keep.reshape(shape[0], -1), shape[-1], axis=1)
    centre = np.array([series[seen[:, i], i].mean() if seen[:, i].any() else 0.0
                       for i in range(series.shape[1])])
    return np.where(seen, series - centre, 0.0), seen, centre, shape


def fit_kalman_noise(points, fps: float, *, confidence=None, min_confidence: float = 0.0,
                     measurement_grid=None, acceleration_grid=None) -> dict:
    """The constant-velocity model's noise levels that maximise the summed log-evidence of the
    observed frames of every series (one pair for all), over a grid.

    Args:
        points, fps, confidence, min_confidence: as :func:`kalman_smoother`.
        measurement_grid: σ_r candidates (units of ``points``); default 15 values from 0.3 to
            100 times the median frame-to-frame change of the detections.
        acceleration_grid: σ_a candidates (units/s² per √Hz); default 21 values from 0.001 to
            1000 times that change times ``fps^1.5``.

    Returns:
        ``measurement_std``, ``acceleration_std``, ``log_evidence`` (the best), ``grid_edge``
        (True where the best lies on the grid's border).
    """
    observations, seen, _, _ = _observed_series(points, confidence, min_confidence)
    both = seen[1:] & seen[:-1]
    steps = np.abs(np.diff(observations, axis=0))[both]
    scale = float(np.median(steps)) if steps.size else 1.0
    scale = scale if scale > 0 else 1.0
    r_grid = (np.geomspace(0.3, 100, 15) * scale if measurement_grid is None
              else np.asarray(measurement_grid, np.float64))
    a_grid = (np.geomspace(1e-3, 1e3, 21) * scale * fps ** 1.5 if acceleration_grid is None
              else np.asarray(acceleration_grid, np.float64))
    r, a = np.meshgrid(r_grid, a_grid, indexing="ij")
    _, _, logs = _kalman(observations, seen, fps, r, a, smooth=False)
    total = np.asarray(logs).sum(-1)
    i, j = np.unravel_index(int(np.nanargmax(total)), total.shape)
    return {"measurement_std": float(r_grid[i]), "acceleration_std": float(a_grid[j]),
            "log_evidence": float(total[i, j]),
            "grid_edge": bool(i in (0, len(r_grid) - 1) or j in (0, len(a_grid) - 1))}


def kalman_smoother(points, fps: float, *, confidence=None, min_confidence: float = 0.0,
                    measurement_std: float | None = None,
                    acceleration_std: float | None = None, smooth: bool = True
                    ) -> tuple[np.ndarray, np.ndarray, dict]:
    """A constant-velocity Kalman filter and RTS smoother on every series (JAX).

    State ``(x, ẋ)`` per coordinate, ``x_t = x_{t−1} + ẋ_{t−1}/fps``, the speed driven by
    white acceleration noise of density σ_a²; ``y_t = x_t + N(0, σ_r²)``. Frames that are NaN
    or whose ``confidence`` is below ``min_confidence`` are missing: the filter predicts
    through them and the smoother fills them. A series with no observed frame stays NaN.

    Args:
        points: ``(time, ..., coordinates)``, NaN where missing.
        fps: frames per second.
        confidence: optional ``(time, ...)`` (``points`` without its last axis).
        min_confidence: confidences below it are missing.
        measurement_std, acceleration_std: σ_r and σ_a; None: :func:`fit_kalman_noise`'s.
        smooth: the RTS smoother (True) or the filter alone (causal).

    Returns:
        ``(positions, stds, noise)``: the estimates and their standard deviations, both shaped
        like ``points``, and the noise levels used (with the fit's log-evidence when fitted).
    """
    observations, seen, centre, shape = _observed_series(points, confidence, min_confidence)
    noise = {"measurement_std": measurement_std, "acceleration_std": acceleration_std}
    if measurement_std is None or acceleration_std is None:
        fitted = fit_kalman_noise(points, fps, confidence=confidence,
                                  min_confidence=min_confidence)
        noise = {key: value if value is not None else fitted[key]
                 for key, value in noise.items()}
        noise.update({key: fitted[key] for key in ("log_evidence", "grid_edge")})
    if not (noise["measurement_std"] > 0 and noise["acceleration_std"] > 0):
        raise ValueError(f"measurement_std and acceleration_std must be positive, got {noise}")
    positions, stds, _ = _kalman(observations, seen, fps, noise["measurement_std"],
                                 noise["acceleration_std"], smooth=smooth)
    empty = ~seen.any(axis=0)
    positions = np.where(empty, np.nan, np.asarray(positions, np.float64) + centre)
    stds = np.where(empty, np.nan, np.asarray(stds, np.float64))
    return positions.reshape(shape), stds.reshape(shape), noise
