"""The MediaPipe detector jaxtrack runs in its own venv: the worker's files and pipe, full frames
and regions, its time reported apart, and one-line errors naming ``make detector``. MediaPipe
itself is stood in for by ``_fake_mediapipe_worker.py`` (the real worker's code around a
bright-pixel "detector" with a known answer); with ``make detector`` done, the last test runs
the real one on a frame of the Pose2Sim video."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from jaxtrack.vision.mediapipe import (
    DetectorUnavailableError,
    MediaPipeDetector,
    detect_pose,
    detected_keypoints,
    mediapipe_python,
    region_around,
    run_mediapipe,
)

FAKE = Path(__file__).with_name("_fake_mediapipe_worker.py")
PYTHON = Path(sys.executable)


def frames_with_blobs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Three 60x80 frames: a bright 4x6 blob (the "person") at known places, a second bright
    blob at the far right in frames 0 and 1 (a distractor outside the region), nothing in frame
    2. Returns frames, the person's centroids (x, y), the region around the person."""
    frames = np.zeros((3, 60, 80, 3), np.uint8)
    centres = []
    for t, (x, y) in enumerate([(10, 20), (14, 24)]):
        frames[t, y:y + 4, x:x + 6] = 255
        frames[t, 50:54, 70:76] = 255
        centres.append((x + 2.5, y + 1.5))
    return frames, np.array(centres), np.array([0.0, 5.0, 40.0, 45.0])


def test_a_whole_video_runs_through_the_worker_files_on_full_frames_and_on_a_region():
    frames, centres, region = frames_with_blobs()
    full = detect_pose(frames, python=PYTHON, worker=FAKE)
    assert full["found"].tolist() == [True, True, False]
    # full frame: the centroid of both blobs; frame 2: no one, NaN
    both = (centres + np.array([72.5, 51.5])) / 2
    np.testing.assert_allclose(full["landmarks"][:2, 11], both, atol=1e-9)
    assert np.isnan(full["landmarks"][2]).all() and full["version"] == "fake-1.0"
    cropped = detect_pose(frames, regions=region, python=PYTHON, worker=FAKE)
    np.testing.assert_allclose(cropped["landmarks"][:2, 11], centres, atol=1e-9)
    assert cropped["seconds"].shape == (2,) and cropped["wall_seconds"] > cropped["first_seconds"]
    points, confidence = detected_keypoints(cropped)
    np.testing.assert_allclose(points[0, 0], centres[0], atol=1e-9)
    assert confidence[:2].min() == pytest.approx(0.9) and (confidence[2] == 0).all()


def test_frame_by_frame_through_the_pipe_follows_the_region_it_is_given():
    frames, centres, region = frames_with_blobs()
    with MediaPipeDetector(python=PYTHON, worker=FAKE, segmentation=True) as detector:
        whole = detector.detect(frames[0])
        first = detector.detect(frames[0], region)
        moved = detector.detect(frames[1], region + [4, 4, 4, 4])
        outside = detector.detect(frames[1], [60.0, 0.0, 68.0, 40.0])
        assert detector.version == "fake-1.0"
    np.testing.assert_allclose(whole["landmarks"][0], (centres[0] + [72.5, 51.5]) / 2)
    np.testing.assert_allclose(first["landmarks"][0], centres[0], atol=1e-9)
    np.testing.assert_allclose(moved["landmarks"][0], centres[1], atol=1e-9)
    assert not outside["found"] and np.isnan(outside["landmarks"]).all()
    # the mask comes back in the frame's pixels, the person's blob only (the region's crop)
    assert first["mask"].shape == (60, 80) and first["mask"].sum() == 24
    assert first["seconds"] >= 0 and first["wall_seconds"] >= first["seconds"]


def test_no_detector_python_is_one_line_naming_make_detector(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", str(tmp_path / "no-python"))
    frames = np.zeros((1, 8, 8, 3), np.uint8)
    for call in (lambda: detect_pose(frames), lambda: MediaPipeDetector()):
        with pytest.raises(DetectorUnavailableError, match="make detector") as error:
            call()
        assert "\n" not in str(error.value)
    assert "no MediaPipe python" in run_mediapipe(frames)["skipped"]


def test_a_failing_worker_is_one_line_naming_make_detector():
    # the real worker with jaxtrack's python, which has no mediapipe: it fails on import
    frames = np.zeros((1, 8, 8, 3), np.uint8)
    with pytest.raises(DetectorUnavailableError, match=r"failed \(1\).*make detector"):
        detect_pose(frames, python=PYTHON)
    detector = MediaPipeDetector(python=PYTHON)
    with pytest.raises(DetectorUnavailableError, match="stopped.*make detector") as error:
        detector.detect(frames[0])
    assert "\n" not in str(error.value)


def test_a_region_around_predicted_markers_is_a_grown_square_inside_the_frame():
    markers = np.array([[100.0, 200.0], [140.0, 260.0], [np.nan, np.nan]])
    box = region_around(markers, (1000, 1000), margin=0.5)
    # the box 40 x 60 centred at (120, 230): side 60 grown by 30 each side, plus a pixel
    np.testing.assert_allclose(box, [120 - 61, 230 - 61, 120 + 61, 230 + 61])
    np.testing.assert_allclose(region_around(markers, (150, 1000)), [59, 169, 150, 291])
    np.testing.assert_allclose(region_around(np.full((3, 2), np.nan), (64, 48)), [0, 0, 64, 48])


def test_bad_regions_are_refused():
    frames = np.zeros((2, 8, 8, 3), np.uint8)
    with pytest.raises(ValueError, match="regions must be"):
        detect_pose(frames, regions=np.zeros((3, 4)), python=PYTHON, worker=FAKE)
    with pytest.raises(ValueError, match="x1 > x0"):
        detect_pose(frames, regions=[5, 0, 2, 4], python=PYTHON, worker=FAKE)


@pytest.mark.skipif(not mediapipe_python().exists(), reason="make detector has not been run")
def test_the_real_detector_finds_the_man_on_the_beam_in_a_region_as_in_the_frame():
    from jaxtrack.evaluation.reference import default_folder
    from jaxtrack.vision import read_video

    try:
        video = default_folder() / "videos" / "cam01.mp4"
    except FileNotFoundError as error:
        pytest.skip(str(error))
    frame = read_video(video, max_frames=1).frames[0]
    with MediaPipeDetector(static=True) as detector:
        whole = detector.detect(frame)
        shoulders = whole["landmarks"][[11, 12]]
        box = np.r_[whole["landmarks"].min(0) - 150, whole["landmarks"].max(0) + 150]
        region = detector.detect(frame, box)
    # SOURCE.txt of the test data: the right shoulder at about (370, 492), the left (516, 513)
    np.testing.assert_allclose(shoulders, [[516, 513], [370, 492]], atol=25)
    assert region["found"] and np.abs(region["landmarks"][[11, 12]] - shoulders).max() < 25
