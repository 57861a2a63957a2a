"""One person followed through a detector's frames (:func:`follow_person`): the person inside
the box drawn on the first frame, through a crossing, never a passer-by far away."""

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.vision.detections import DetectionFileError, Detections, follow_person

MARKERS = len(UPPER_BODY_12)


def _person(centre_x: float, rng) -> np.ndarray:
    """``(12, 2)`` keypoints of a 100 px tall person standing at ``centre_x``."""
    layout = rng.uniform([-20, -50], [20, 50], size=(MARKERS, 2))
    return layout + [centre_x, 200.0]


def _crossing(frames: int = 20):
    """Two people walking past each other (A from x = 100 to 300, B from 300 to 100), listed in
    a random order each frame; a passer-by at x = 900 from frame 10."""
    rng = np.random.default_rng(0)
    shape_a, shape_b = _person(0, rng), _person(0, rng)
    points = np.full((frames, 3, MARKERS, 2), np.nan)
    people = np.zeros(frames, np.int64)
    truth = []
    for t in range(frames):
        a = shape_a + [100 + 200 * t / (frames - 1), 0]
        b = shape_b + [300 - 200 * t / (frames - 1), 0]
        rows = [a, b] if rng.random() < 0.5 else [b, a]
        if t >= 10:
            rows.append(_person(900, rng))
        points[t, :len(rows)] = rows
        people[t] = len(rows)
        truth.append(a)
    confidence = np.where(np.isfinite(points[..., 0]), 0.9, 0.0)
    return Detections(points, confidence, people, UPPER_BODY_12, "markers"), np.array(truth)


def test_the_person_in_the_box_is_followed_through_a_crossing():
    detections, truth = _crossing()
    points, confidence = follow_person(detections, (60, 130, 140, 270))  # around A at frame 0
    np.testing.assert_allclose(points, truth)
    assert np.all(confidence == 0.9)


def test_without_a_box_the_most_confident_person_and_nobody_far_away():
    detections, truth = _crossing()
    confidence = detections.confidence.copy()
    confidence[0, :, :] = 0.5
    first = int(np.argmin(np.abs(detections.points[0, :2, 0, 0] - truth[0, 0, 0])))
    confidence[0, first] = 0.95  # A the most confident in the first frame
    detections = Detections(detections.points, confidence, detections.people, UPPER_BODY_12,
                            "markers")
    points, _ = follow_person(detections)
    np.testing.assert_allclose(points[1:], truth[1:])
    # A leaves after frame 12: neither B nor the passer-by at x = 900 is taken for A
    gone = detections.points.copy()
    for t in range(13, 20):
        keep = [row for row in gone[t, :3] if np.all(np.isfinite(row))
                and not np.allclose(row, truth[t])]
        gone[t] = np.nan
        gone[t, :len(keep)] = keep
    people = np.where(np.arange(20) >= 13, detections.people - 1, detections.people)
    left = Detections(gone, np.where(np.isfinite(gone[..., 0]), 0.9, 0.0), people,
                      UPPER_BODY_12, "markers")
    points, confidence = follow_person(left, (60, 130, 140, 270))
    assert np.all(np.isnan(points[13:])) and np.all(confidence[13:] == 0)  # nobody near A


def test_a_box_around_nobody_and_a_bad_box_are_refused_in_one_line():
    detections, _ = _crossing()
    with pytest.raises(DetectionFileError, match="nobody detected in frame 0 lies inside"):
        follow_person(detections, (500, 0, 600, 50))
    with pytest.raises(ValueError, match="x0 < x1"):
        follow_person(detections, (100, 0, 50, 50))
    empty = Detections(np.full((3, 1, MARKERS, 2), np.nan), np.zeros((3, 1, MARKERS)),
                       np.zeros(3, np.int64), UPPER_BODY_12, "markers")
    with pytest.raises(DetectionFileError, match="nobody is detected in any frame"):
        follow_person(empty)
