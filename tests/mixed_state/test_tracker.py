"""The mixed-state tracker is the engine's filter frame by frame: ``start`` and ``update`` give
the particles :func:`filter_sequence` keeps, and a frame without a silhouette carries no
evidence (weights unchanged, parts moved by their velocity alone)."""

import equinox as eqx
import jax
import jax.random as jr
import numpy as np

from jaxtrack.trackers._tracker import Tracker
from jaxtrack.trackers.mixed_state import MixedStateModel, MixedStateTracker, filter_sequence

from .test_filter import _flat_frames, _toy_postures


def test_the_tracker_steps_through_what_filter_sequence_keeps():
    rng = np.random.default_rng(5)
    model = MixedStateModel(_toy_postures(rng), initial_std=1.0, position_std=0.5,
                            velocity_std=0.5)
    frames = _flat_frames(rng.normal(size=4))
    frames = type(frames)(frames.features, frames.hypotheses, frames.nearest,
                          frames.status.at[2].set(1))  # frame 2: no silhouette
    num = 64
    result = filter_sequence(jr.PRNGKey(7), model, frames, num)
    tracker = MixedStateTracker(model, num)
    assert isinstance(tracker, Tracker) and tracker.num_particles == num
    # the engine's keys: one for frame 0, one per later frame
    key_init, key_frames = jr.split(jr.PRNGKey(7))
    frame_keys = jr.split(key_frames, 3)
    frame = lambda t: jax.tree.map(lambda leaf: leaf[t], frames)  # noqa: E731
    state = tracker.start(key_init, frame(0))
    first = tracker.first_estimate(state)
    np.testing.assert_allclose(first.log_likelihood, result.log_evidence_increments[0])
    update = eqx.filter_jit(lambda key, state, frame: tracker.update(key, state, frame))
    for t in range(4):
        if t:
            state, estimate = update(frame_keys[t - 1], state, frame(t))
            np.testing.assert_allclose(estimate.log_likelihood,
                                       result.log_evidence_increments[t], atol=1e-12)
            np.testing.assert_allclose(estimate.markers, result.filtered_parts[t], atol=1e-9)
        np.testing.assert_array_equal(state.postures, result.postures[t])
        np.testing.assert_allclose(state.parts, result.parts[t], atol=1e-9)
        np.testing.assert_allclose(state.log_weights, result.log_weights[t], atol=1e-12)
    # frame 2, without evidence: the weights stay equal (resampled every frame) and the parts
    # move by their new velocity alone (no projection, no re-draw)
    np.testing.assert_allclose(result.log_weights[2], -np.log(num), atol=1e-12)
    assert float(result.log_evidence_increments[2]) == 0.0
    parents = np.asarray(result.parts[1])[np.asarray(result.ancestors[2])]
    np.testing.assert_allclose(result.parts[2] - parents, result.velocities[2], atol=1e-9)
