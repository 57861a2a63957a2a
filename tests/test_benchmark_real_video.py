"""``python -m benchmarks.real_video``: its MediaPipe landmark map, the frames it tracks and its
refusals (the benchmark itself is a script: its ``--quick`` run compiles two trackers and takes
minutes on 2 cores, so it is not a test)."""

import numpy as np
import pytest

from benchmarks import real_video
from benchmarks._mediapipe import LANDMARKS, to_upper_body
from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data import shared_folder

SHARED = shared_folder()
FOLDER = None if SHARED is None else SHARED / "pose2sim_demo_singleperson"
needs_data = pytest.mark.skipif(
    FOLDER is None or not (FOLDER / "reference" / "pose-3d").is_dir(),
    reason="the shared/data collection (pose2sim_demo_singleperson) is not beside this checkout")


@needs_data
def test_a_stride_tracks_every_other_frame_at_the_rate_it_tracks():
    every = real_video.View(FOLDER, "cam02", 9, 120)
    second = real_video.View(FOLDER, "cam02", 9, 120, stride=2)
    assert list(second.frame_indices) == list(every.frame_indices[::2])
    assert second.fps == pytest.approx(every.fps / 2)
    np.testing.assert_array_equal(second.truth, every.truth[::2])
    assert second.frames.shape[0] == 5 and second.images.shape[0] == 5


def test_bad_arguments_are_refused_in_one_line(capsys):
    for argv, message in ((["--stride", "0"], "--stride must be at least 1"),
                          (["--frames", "1"], "--frames must be at least 2"),
                          (["--foreground-weight", "nan"],
                           "--foreground-weight must be a non-negative number"),
                          (["--coverage-weight", "-2"],
                           "--coverage-weight must be a non-negative number"),
                          (["--coverage-weight", "10"],
                           "--coverage-weight: the coverage term reads the person's masks")):
        with pytest.raises(SystemExit):
            real_video.main(argv)
        assert message in capsys.readouterr().err


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
