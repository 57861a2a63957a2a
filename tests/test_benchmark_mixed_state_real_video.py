"""The mixed-state real-video benchmark's truth: which reference keypoints stand for the five
parts, and how much of them a silhouette covers (the benchmark itself tracks four videos and is
a script, not a test)."""

import numpy as np

from benchmarks.mixed_state_real_video import truth_in_silhouette, truth_parts
from jaxtrack.evaluation.reference import TRC_KEYPOINTS
from jaxtrack.vision.parts import PART_NAMES


def test_the_parts_are_the_head_top_wrists_and_ankles_in_part_order():
    keypoints = np.arange(2 * len(TRC_KEYPOINTS), dtype=float).reshape(1, -1, 2)
    parts = truth_parts(keypoints)
    assert parts.shape == (1, len(PART_NAMES), 2)
    expected = ["Head", "RWrist", "LWrist", "RAnkle", "LAnkle"]
    for part, name in zip(parts[0], expected, strict=True):
        np.testing.assert_array_equal(part, keypoints[0, TRC_KEYPOINTS.index(name)])
    assert PART_NAMES[0] == "head" and "hand" in PART_NAMES[1] and "foot" in PART_NAMES[3]


def test_coverage_counts_parts_on_or_within_five_pixels_of_the_silhouette():
    masks = np.zeros((2, 60, 40), bool)
    masks[:, 10:50, 10:30] = True
    truth = np.array([[[20, 12], [12, 30], [28, 30], [15, 48], [25, 48]],    # all inside
                      [[20, 4], [2, 30], [28, 30], [15, 58], [34, 48]]],     # head 6 px above,
                     dtype=float)                                            # a hand, two feet out
    covered = truth_in_silhouette(masks, truth)
    assert covered["head"] == 0.5
    assert covered["hands"] == 0.75
    assert covered["feet"] == 0.5 + 0.25  # 58 is 9 px below; 34 is 5 px right of the box
    assert covered["all"] == (5 + 2) / 10
