"""The real-video benchmark's MediaPipe landmark map (the benchmark itself is a script: its
``--quick`` run compiles two trackers and takes minutes on 2 cores, so it is not a test)."""

import numpy as np

from benchmarks._mediapipe import LANDMARKS, to_upper_body
from jaxtrack.body import UPPER_BODY_12


def test_mediapipe_landmarks_map_to_the_twelve_markers():
    landmarks = np.full((33, 2), np.nan)
    named = {"left_shoulder": (120, 100), "right_shoulder": (80, 100), "left_ear": (105, 40),
             "right_ear": (95, 40), "left_hip": (110, 250), "right_hip": (90, 250),
             "left_elbow": (130, 160), "right_elbow": (70, 160), "left_wrist": (140, 210),
             "right_wrist": (60, 210)}
    for name, point in named.items():
        landmarks[LANDMARKS[name]] = point
    markers = dict(zip(UPPER_BODY_12, to_upper_body(landmarks[None])[0], strict=True))
    np.testing.assert_allclose(markers["neck"], (100, 80))      # a third of the way to the ears
    np.testing.assert_allclose(markers["head"], (100, 46))      # just below the ears
    np.testing.assert_allclose(markers["pelvis"], (100, 250))
    np.testing.assert_allclose(markers["thorax"], (100, 80 + 0.4 * 170))
    # the person's left is MediaPipe's left (image right when facing the camera)
    np.testing.assert_allclose(markers["left_wrist"], named["left_wrist"])
    np.testing.assert_allclose(markers["right_hip"], named["right_hip"])
    assert np.isfinite(np.stack(list(markers.values()))).all()  # the nose and face are unused
