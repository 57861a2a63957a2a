"""A detector's keypoints as part hypotheses beside the silhouette's
(:func:`jaxtrack.vision.parts.detection_hypotheses`): each posture keeps its slot convention, an
unconfident or missing keypoint leaves the silhouette's hypothesis, NaN never leaks; and the
mixed-state tracker that reads them follows the detector where the silhouette's heuristics are
wrong."""

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.priors.postures import NUM_POSTURES, POSTURE_NAMES, PostureModel
from jaxtrack.trackers import track
from jaxtrack.trackers._tracker import VideoChunk
from jaxtrack.trackers.mixed_state import (
    MixedStateModel,
    MixedStateTracker,
    observations_from_silhouettes,
    with_detections,
)
from jaxtrack.vision.detections import DETECTION_MARKERS
from jaxtrack.vision.parts import detection_hypotheses

MARKERS = ("head", "right_wrist", "left_wrist", "right_ankle", "left_ankle")


def _silhouette_hypotheses():
    """Two frames; posture 0 puts hand_1 at x = 0 and hand_2 at x = 100, posture 1 the other
    way round (two slot conventions); feet at y = 200."""
    hypotheses = np.zeros((2, NUM_POSTURES, 5, 2))
    hypotheses[:, :, 0] = [50, 0]
    hypotheses[:, 0, 1:3] = [[0, 50], [100, 50]]
    hypotheses[:, 1:, 1:3] = [[100, 50], [0, 50]]
    hypotheses[:, :, 3:5] = [[40, 200], [60, 200]]
    return hypotheses


def test_keypoints_replace_confident_parts_in_each_postures_own_slots():
    hypotheses = _silhouette_hypotheses()
    # frame 0: right wrist at x 95 (image right), left wrist at x 5; head and feet confident
    # frame 1: the left wrist unconfident, the right ankle NaN, the head below threshold
    points = np.array([[[52, 10], [95, 55], [5, 45], [38, 190], [62, 195]],
                       [[52, 10], [10, 52], [7, 7], [np.nan, np.nan], [59, 210]]], float)
    confidence = np.array([[0.9, 0.9, 0.9, 0.9, 0.9], [0.4, 0.9, 0.1, 0.9, 0.8]])
    out = detection_hypotheses(hypotheses, points, confidence, MARKERS, min_confidence=0.5)
    assert out.shape == hypotheses.shape and np.all(np.isfinite(out))
    # frame 0, posture 0 (hand_1 image-left): the left wrist goes to hand_1, the right to hand_2
    np.testing.assert_array_equal(out[0, 0, 1:3], [[5, 45], [95, 55]])
    # posture 1 (hand_1 image-right): the other way round, each slot keeps its convention
    np.testing.assert_array_equal(out[0, 1, 1:3], [[95, 55], [5, 45]])
    np.testing.assert_array_equal(out[0, :, 0], np.broadcast_to([52, 10], (NUM_POSTURES, 2)))
    np.testing.assert_array_equal(out[0, :, 3:5], np.broadcast_to([[38, 190], [62, 195]],
                                                                  (NUM_POSTURES, 2, 2)))
    # frame 1: the head below threshold and the unconfident wrist keep the silhouette's; the
    # lone confident wrist takes the nearer slot (hand_1 of posture 0, hand_2 of posture 1)
    np.testing.assert_array_equal(out[1, :, 0], hypotheses[1, :, 0])
    np.testing.assert_array_equal(out[1, 0, 1:3], [[10, 52], [100, 50]])
    np.testing.assert_array_equal(out[1, 1, 1:3], [[100, 50], [10, 52]])
    # the NaN ankle keeps the silhouette's; the confident one its nearer slot (foot_2)
    np.testing.assert_array_equal(out[1, :, 3:5], np.broadcast_to([[40, 200], [59, 210]],
                                                                  (NUM_POSTURES, 2, 2)))
    # markers the detections lack (no ankles) leave the feet as they were
    out = detection_hypotheses(hypotheses, points[:, :3], confidence[:, :3], MARKERS[:3],
                               min_confidence=0.5)
    np.testing.assert_array_equal(out[..., 3:5, :], hypotheses[..., 3:5, :])
    with pytest.raises(ValueError, match="points must be"):
        detection_hypotheses(hypotheses, points[:1], confidence, MARKERS, min_confidence=0.5)


def test_parts_are_projected_onto_the_silhouette_and_the_confident_keypoints():
    masks = np.zeros((1, 20, 30), bool)
    masks[0, 5:15, 5:10] = True
    observations = observations_from_silhouettes(masks, num_bins=4)
    points = np.array([[[25.0, 10.0], [20.0, 3.0], [np.nan, np.nan], [1.0, 1.0], [28, 18]]])
    confidence = np.array([[0.9, 0.9, 0.9, 0.1, 0.9]])  # the right ankle unconfident
    merged = with_detections(observations, points, confidence, MARKERS, min_confidence=0.5)
    nearest = np.asarray(merged.nearest[0])
    np.testing.assert_array_equal(nearest[10, 24], [25, 10])  # next to the detected head
    np.testing.assert_array_equal(nearest[3, 20], [20, 3])  # the detected wrist is itself
    np.testing.assert_array_equal(nearest[19, 29], [28, 18])  # the confident ankle
    np.testing.assert_array_equal(nearest[10, 12], [9, 10])  # the silhouette still
    np.testing.assert_array_equal(nearest[1, 1], [5, 5])  # not the unconfident ankle
    assert np.asarray(merged.hypotheses)[0, :, 0].tolist() == [[25.0, 10.0]] * NUM_POSTURES


def _flat_postures(features: int, standing: float = 0.96) -> PostureModel:
    """Postures the silhouette's features do not tell apart (a vanishing precision): standing
    a priori and kept, so the parts alone are tested."""
    others = (1 - standing) / (NUM_POSTURES - 1)
    matrix = np.full((NUM_POSTURES, NUM_POSTURES), others)
    np.fill_diagonal(matrix, standing)
    initial = np.full(NUM_POSTURES, others)
    initial[POSTURE_NAMES.index("standing")] = standing
    return PostureModel(jnp.zeros((NUM_POSTURES, features)),
                        jnp.broadcast_to(1e-6 * jnp.eye(features),
                                         (NUM_POSTURES, features, features)),
                        jnp.zeros(NUM_POSTURES), jnp.log(matrix), jnp.log(initial), 1e9)


def test_the_tracker_follows_the_detector_where_the_silhouette_is_wrong():
    # a standing block, 34 wide and 60 high: the silhouette's hands are its left and right
    # edges, but the detector sees the hands in front of the body, moving down by 1 px a frame
    frames, height, width = 8, 80, 70
    masks = np.zeros((frames, height, width), bool)
    masks[:, 10:70, 18:52] = True
    points = np.full((frames, len(DETECTION_MARKERS), 2), np.nan)
    confidence = np.zeros((frames, len(DETECTION_MARKERS)))
    moving = np.arange(frames)
    for name, x in (("right_wrist", 28.0), ("left_wrist", 42.0)):
        index = DETECTION_MARKERS.index(name)
        points[:, index] = np.stack([np.full(frames, x), 50.0 + moving], axis=-1)
        confidence[:, index] = 0.9
    bins = 4
    model = MixedStateModel(_flat_postures(2 * bins + 1), initial_std=2.0, position_std=1.0,
                            velocity_std=0.5)
    chunk = VideoChunk(masks=masks, keypoints=(points, confidence))
    plain = MixedStateTracker(model, 64, bins)
    tracker = MixedStateTracker(model, 64, bins, keypoint_markers=DETECTION_MARKERS)
    assert plain.reads == ("masks",) and tracker.reads == ("masks", "keypoints")
    truth = np.stack([[[28.0, 50.0 + t], [42.0, 50.0 + t]] for t in moving])
    silhouette = np.asarray(plain.observe(chunk).hypotheses)
    observations = tracker.observe(chunk)
    standing = POSTURE_NAMES.index("standing")
    # the silhouette alone puts the hands at the block's edges, far from the detections
    assert np.linalg.norm(silhouette[:, standing, 1:3] - truth, axis=-1).min() > 20.0
    estimates = np.asarray(track(tracker, jr.PRNGKey(0), observations,
                                 progress=False).estimates.markers)
    assert np.all(np.isfinite(estimates))
    # with them, the filtered hands follow the detections within a few pixels
    assert np.linalg.norm(estimates[:, 1:3] - truth, axis=-1).max() < 4.0
    # the undetected head and feet stay the silhouette's
    np.testing.assert_array_equal(np.asarray(observations.hypotheses)[..., [0, 3, 4], :],
                                  silhouette[..., [0, 3, 4], :])
    assert np.linalg.norm(estimates[:, [0, 3, 4]] - silhouette[:, standing, [0, 3, 4]],
                          axis=-1).mean() < 4.0
    with pytest.raises(ValueError, match="keypoints=..."):
        tracker.observe(VideoChunk(masks=masks))
