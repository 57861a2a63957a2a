"""``python -m papers.tian2005.keypoint_term``: the fit of the keypoint term's scales and the
refusals of the real-video benchmark's keypoint options (the benchmark itself runs MediaPipe in
its own venv and tracks for minutes, so it is not a test)."""

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.likelihoods.edges import MIRRORED_MARKERS
from jaxtrack.vision.mediapipe import LANDMARKS, detected_keypoints, keypoint_confidence
from papers.tian2005 import keypoint_term, real_video


def _truth(frames=40, seed=0):
    rng = np.random.default_rng(seed)
    base = np.array([[80, 20], [80, 35], [80, 60], [80, 95], [65, 38], [55, 55], [50, 70],
                     [70, 95], [95, 38], [105, 55], [110, 70], [90, 95]], float)
    return base + rng.normal(0, 2, (frames, 12, 2))  # spine 60 px


def test_the_fitted_scales_are_the_median_distance_over_root_three_swaps_undone():
    truth = _truth()
    rng = np.random.default_rng(1)
    angles = rng.uniform(0, 2 * np.pi, truth.shape[:2])
    radius = 6.0  # every keypoint 6 px from its marker: a tenth of the 60 px spine
    points = truth + radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    points[5:9] = points[5:9][:, list(MIRRORED_MARKERS)]  # a detector's left/right swap
    confidence = np.ones(truth.shape[:2])
    confidence[0, 3] = 0.0  # not found: left out
    distances = keypoint_term.better_assignment_distances(points, confidence, truth)
    assert np.isnan(distances[0, 3]) and np.isfinite(np.delete(distances.ravel(), 3)).all()
    spine = np.linalg.norm(truth[:, 1] - truth[:, 3], axis=-1)
    np.testing.assert_allclose(np.nan_to_num(distances), np.where(
        confidence > 0, radius / spine[:, None], 0.0), rtol=1e-9)
    scales = keypoint_term.fit_scales(distances)
    np.testing.assert_allclose(scales, np.nanmedian(distances, 0) / np.sqrt(3), rtol=1e-12)
    assert scales.shape == (12,)


def test_mediapipe_keypoints_carry_their_landmarks_least_visibility():
    visibility = np.full(33, 0.9)
    visibility[LANDMARKS["left_ear"]] = 0.4
    visibility[LANDMARKS["right_wrist"]] = 0.2
    confidence = dict(zip(UPPER_BODY_12, keypoint_confidence(visibility), strict=True))
    assert confidence["head"] == confidence["neck"] == confidence["thorax"] == 0.4
    assert confidence["right_wrist"] == 0.2 and confidence["pelvis"] == 0.9
    landmarks = np.random.default_rng(0).uniform(0, 100, (2, 33, 2))
    landmarks[1] = np.nan
    points, sure = detected_keypoints({"found": np.array([True, False]), "landmarks": landmarks,
                                       "visibility": np.stack([visibility, visibility])})
    assert np.isfinite(points[0]).all() and np.isnan(points[1]).all()
    np.testing.assert_array_equal(sure[1], 0.0)
    np.testing.assert_allclose(sure[0], keypoint_confidence(visibility))


def test_bad_keypoint_options_are_refused_in_one_line(capsys):
    for argv, message in ((["--keypoint-weight", "2"],
                           "--keypoint-weight: the keypoint term reads a detector's keypoints"),
                          (["--keypoints", "mediapipe", "--keypoint-weight", "0"],
                           "--keypoint-weight must be a positive number"),
                          (["--inits", "detector", "--no-mediapipe"],
                           "--inits detector starts from MediaPipe's keypoints")):
        with pytest.raises(SystemExit):
            real_video.main(argv)
        assert message in capsys.readouterr().err
    with pytest.raises(SystemExit):
        keypoint_term.main(["--frames", "1"])
    assert "--frames must be at least 2" in capsys.readouterr().err
