"""``python -m papers.tian2005.real_video``: its MediaPipe landmark map, the frames it tracks
and its refusals (the study itself is a script: its ``--quick`` run compiles two trackers
and takes minutes on 2 cores, so it is not a test)."""

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data import shared_folder
from jaxtrack.vision.mediapipe import LANDMARKS, to_upper_body
from papers.tian2005 import real_video

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


@needs_data
def test_a_track_file_is_scored_against_the_reference(tmp_path, capsys):
    """``--score``: a ``jaxtrack track`` run's track.json, its markers in the video's pixels;
    the reference itself scores 0, a copy 30 px off scores that, and a video that is not one of
    the demo's is refused in one line."""
    import json

    from jaxtrack.evaluation.reference import load_reference

    reference = load_reference(FOLDER, num_video_frames=100)["cam03"]
    indices = [int(index) for index in reference.frame_indices[:6]]
    truth = reference.select(indices).markers

    def write(markers, video="videos/cam03.mp4"):
        path = tmp_path / "track.json"
        path.write_text(json.dumps({
            "video": video, "tracker": {"likelihood": {"keypoint_weight": 1.5}},
            "frames": [{"frame": index, "markers": {name: list(map(float, point))
                                                    for name, point in zip(UPPER_BODY_12, pose,
                                                                           strict=True)}}
                       for index, pose in zip(indices, markers, strict=True)]}))
        return path

    exact = real_video.score_track_file(write(truth), FOLDER)
    assert exact["view"] == "cam03" and exact["frames_scored"] == 5
    assert exact["mean_error_torso"] < 1e-9 and exact["fraction_within_15"] == 1.0
    shifted = real_video.score_track_file(write(truth + [30.0, 0.0]), FOLDER)
    assert shifted["mean_error_px"] == pytest.approx(30.0)
    assert real_video.main(["--score", str(write(truth)), "--data", str(FOLDER)]) == 0
    assert "cam03, 5 frames: 0.0 % of the torso, 100 % of frames within 15 %" in (
        capsys.readouterr().out)
    with pytest.raises(SystemExit, match="none of the Pose2Sim demo's"):
        real_video.score_track_file(write(truth, "my_clip.mp4"), FOLDER)


def test_a_detectors_left_right_swaps_are_counted():
    """``swapped_frames``: the scored frames (after the first) whose markers lie nearer the
    reference with left and right exchanged, and their errors once swapped back."""
    from types import SimpleNamespace

    from jaxtrack.likelihoods.edges import MIRRORED_MARKERS

    truth = np.array([[80, 20], [80, 35], [80, 60], [80, 95], [65, 38], [55, 55], [50, 70],
                      [70, 95], [95, 38], [105, 55], [110, 70], [90, 95]], float)
    truth = np.repeat(truth[None], 5, axis=0)
    markers = truth + 1.5
    markers[2:4] = markers[2:4][:, list(MIRRORED_MARKERS)]
    counted = real_video.swapped_frames(markers, SimpleNamespace(truth=truth))
    assert counted["frames_swapped"] == 2
    torso = np.linalg.norm(truth[0, 1] - truth[0, 3])
    np.testing.assert_allclose(counted["swapped_back_errors_torso"],
                               [1.5 * np.sqrt(2) / torso] * 2, atol=1e-4)
