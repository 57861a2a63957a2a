"""The mixed-state tracker run by ``track()`` with ``keep_history`` smooths as the sequence
functions do: its ``smooth`` of the collected reports is :func:`smooth` of
:func:`filter_sequence` on the same keys, and its instantaneous estimate is
:func:`instantaneous_estimates`."""

import jax.random as jr
import numpy as np
import pytest

from jaxtrack.trackers import track
from jaxtrack.trackers.mixed_state import (
    MixedStateModel,
    MixedStateTracker,
    filter_sequence,
    instantaneous_estimates,
    smooth,
)

from .test_filter import _flat_frames, _toy_postures


def test_smooth_of_the_tracked_reports_is_the_sequence_smoother():
    rng = np.random.default_rng(5)
    model = MixedStateModel(_toy_postures(rng), initial_std=1.0, position_std=0.5,
                            velocity_std=0.5)
    frames = _flat_frames(rng.normal(size=5))
    num = 32
    expected = smooth(filter_sequence(jr.PRNGKey(3), model, frames, num))
    tracker = MixedStateTracker(model, num, keep_history=True)
    result = track(tracker, jr.PRNGKey(3), frames, progress=False, chunk_size=2)
    smoothed = tracker.smooth(result.estimates)
    np.testing.assert_array_equal(smoothed.posture, expected.posture)
    np.testing.assert_allclose(smoothed.markers, expected.parts, atol=1e-6)
    assert smoothed.history is None and result.estimates.history.ancestors.shape == (5, num)
    np.testing.assert_array_equal(result.estimates.history.ancestors[0], np.arange(num))
    instant_posture, instant_parts = instantaneous_estimates(model, frames)
    np.testing.assert_array_equal(result.estimates.instant_posture, instant_posture)
    np.testing.assert_allclose(result.estimates.instant_parts, instant_parts)
    with pytest.raises(ValueError, match="keep_history=True"):
        MixedStateTracker(model, num).smooth(
            track(MixedStateTracker(model, num), jr.PRNGKey(3), frames, progress=False,
                  chunk_size=2).estimates)
