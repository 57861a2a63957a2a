"""Tracker-guided detection (``jaxtrack.experiments._guided_detection``): the detector runs, inside
the tracking pass, on the region the tracker's own prediction gives, and the detection density
chooses between that detection and the full frame's. Here the detector is the real worker's
code around a stand-in that finds the largest bright rectangle (``tests/vision/
_fake_mediapipe_worker.py``, ``FAKE_DETECTOR=largest``): MediaPipe-like, one person, the
nearest. A second, larger person crosses below the tracked one, so that the full frame shows
only the passer-by while the tracked person walks on."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax.random as jr
import numpy as np
import pytest

from jaxtrack.experiments._guided_detection import (
    GuidedDetections,
    RegionGuide,
    guided_region,
)
from jaxtrack.experiments.detection_tracking import ChunkDetections, detection_tracker
from jaxtrack.experiments.pipeline import track_video
from jaxtrack.trackers import VideoChunk
from jaxtrack.vision import mediapipe
from jaxtrack.vision.mediapipe import MediaPipeDetector, to_upper_body
from jaxtrack.vision.video import write_frames

sys.path.insert(0, str(Path(__file__).parents[1] / "vision"))
from _fake_mediapipe_worker import box_landmarks  # noqa: E402

FAKE = Path(__file__).parents[1] / "vision" / "_fake_mediapipe_worker.py"
WIDTH, HEIGHT, FRAMES = 160, 120, 14
ENTERS = 3  # the passer-by's first frame


def _boxes(t: int) -> tuple[tuple[int, ...], tuple[int, ...] | None]:
    """The tracked person's box (14 x 30, walking right 2 px a frame) and the passer-by's
    (20 x 44, nearer the camera: lower and larger, crossing leftwards from frame ENTERS)."""
    x = 30 + 2 * t
    tracked = (x, 10, x + 14, 40)
    if t < ENTERS:
        return tracked, None
    x = 140 - 11 * (t - ENTERS)
    return tracked, (x, 66, x + 20, 110)


def _crossing_video(path: Path) -> Path:
    frames = np.zeros((FRAMES, HEIGHT, WIDTH, 3), np.uint8)
    for t in range(FRAMES):
        for box in _boxes(t):
            if box is not None:
                x0, y0, x1, y1 = box
                frames[t, y0:y1, max(x0, 0):x1] = 255
    return write_frames(list(frames), path, 10.0, (WIDTH, HEIGHT))


def _markers(box) -> np.ndarray:
    return to_upper_body(box_landmarks(box))


def _full_frame_detections() -> tuple[np.ndarray, np.ndarray]:
    """What a one-person detector finds on the full frames: the largest person (the passer-by
    from frame ENTERS)."""
    points = np.stack([_markers(b if b is not None else a) for a, b in map(_boxes,
                                                                            range(FRAMES))])
    return points, np.full(points.shape[:2], 0.9)


def _truth() -> np.ndarray:
    return np.stack([_markers(_boxes(t)[0]) for t in range(FRAMES)])


def _error(markers: np.ndarray) -> np.ndarray:
    """Per frame, the median marker distance to the tracked person (pixels)."""
    return np.median(np.linalg.norm(markers - _truth(), axis=-1), axis=-1)


@pytest.fixture
def fake_detector(monkeypatch):
    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", sys.executable)
    monkeypatch.setenv("FAKE_DETECTOR", "largest")
    monkeypatch.setattr(mediapipe, "WORKER", FAKE)


def test_the_guided_region_follows_the_prediction_and_the_track_keeps_its_person(
        tmp_path, fake_detector):
    video = _crossing_video(tmp_path / "crossing.mp4")
    pose = _truth()[0]
    keypoints = _full_frame_detections()
    tracker = ChunkDetections(detection_tracker(pose, num_particles=64, step=0.2),
                              (float(WIDTH), float(HEIGHT)))
    guide = RegionGuide(lambda: MediaPipeDetector(static=True, worker=mediapipe.WORKER))
    record = track_video(GuidedDetections(tracker, guide), video, tmp_path / "guided",
                         key=jr.key(0), initial_pose=pose, keypoints=keypoints,
                         progress=False, chunk_frames=8)
    markers = record["result"].markers
    assert _error(markers).max() < 5.0, _error(markers)
    written = json.loads((tmp_path / "guided" / "track.json").read_text())
    frames = [entry["guided_detection"] for entry in written["frames"]]
    assert frames[0] is None and all(frame["found"] for frame in frames[1:])
    for t in range(1, FRAMES):  # the region is the tracker's prediction from its estimates
        expected, source = guided_region(markers[t - 1], markers[max(t - 2, 0)],
                                         (WIDTH, HEIGHT))
        np.testing.assert_allclose(frames[t]["region"], expected, atol=0.06)
        assert frames[t]["region_from"] == source == "tracker prediction"
        # it holds the person's markers, and none of the passer-by
        low, high = _truth()[t].min(0), _truth()[t].max(0)
        assert np.all(expected[:2] < low) and np.all(expected[2:] > high)
        other = _boxes(t)[1]
        assert other is None or other[1] > expected[3] or other[0] > expected[2] \
            or other[2] < expected[0]
    # the passer-by fills the full frame: the track followed the region's detection there
    assert [frame["followed"] for frame in frames[ENTERS + 1:]] == ["region"] * (
        FRAMES - ENTERS - 1)
    assert [frame["followed"] for frame in frames[1:ENTERS]] == ["both"] * (ENTERS - 1)
    assert written["guided_detection"]["frames_detected"] == FRAMES - 1
    timings = written["timings"]
    assert timings["guided_detector_wall_seconds"] > timings["guided_detector_seconds"] > 0
    assert timings["tracker_seconds_per_frame"] < timings["seconds_per_frame"]
    assert guide.detector is None  # the detector's process ended with the run


@pytest.mark.slow  # a second tracker's compile
def test_without_guidance_the_full_frames_passer_by_loses_the_person(tmp_path):
    """The same tracker on the full frame's detections alone (the passer-by from frame ENTERS)
    loses its person, who walks on while the track stays behind: what the test above would
    see without the guided detections."""
    video = _crossing_video(tmp_path / "crossing.mp4")
    pose = _truth()[0]
    tracker = ChunkDetections(detection_tracker(pose, num_particles=64, step=0.2),
                              (float(WIDTH), float(HEIGHT)))
    alone = track_video(tracker, video, tmp_path / "alone", key=jr.key(0), initial_pose=pose,
                        keypoints=_full_frame_detections(), progress=False, chunk_frames=8)
    assert _error(alone["result"].markers)[-1] > 10.0


def test_the_region_of_a_known_prediction():
    previous = np.array([[100.0, 200.0], [120.0, 260.0], [np.nan, np.nan]])
    before = previous - [10.0, 0.0]  # moving right 10 px a frame: predicted 110 .. 130
    region, source = guided_region(previous, before, (1000, 1000), margin=0.5)
    # the box of both, x 100 .. 130, y 200 .. 260: side 60 grown by 30 each side, plus a pixel
    np.testing.assert_allclose(region, [115 - 61, 230 - 61, 115 + 61, 230 + 61])
    assert source == "tracker prediction"
    region, source = guided_region(np.full((3, 2), np.nan), before, (64, 48))
    np.testing.assert_allclose(region, [0, 0, 64, 48])
    assert source == "full frame"


def test_bad_input_is_one_line():
    with pytest.raises(ValueError, match="same markers"):
        guided_region(np.zeros((12, 2)), np.zeros((11, 2)), (64, 48))
    with pytest.raises(ValueError, match="frame_size must be a positive"):
        guided_region(np.zeros((12, 2)), np.zeros((12, 2)), (0, 48))
    with pytest.raises(ValueError, match="margin must be"):
        RegionGuide(lambda: None, margin=-1.0)
    with pytest.raises(TypeError, match="open_detector must make"):
        RegionGuide(object())
    guide = RegionGuide(lambda: None)
    with pytest.raises(ValueError, match=r"uint8 RGB"):
        guide.keep(np.zeros((2, 8, 8), np.uint8))
    tracker = GuidedDetections(ChunkDetections(detection_tracker(_truth()[0]), (160.0, 120.0)),
                               guide)
    with pytest.raises(ValueError, match="give colour="):
        tracker.observe(VideoChunk(keypoints=_full_frame_detections()))


def test_a_detector_that_fails_during_tracking_is_one_line_after_the_scan():
    # the real worker with jaxtrack's python, which has no mediapipe: it stops at once
    guide = RegionGuide(lambda: MediaPipeDetector(python=Path(sys.executable)))
    position = guide.keep(np.zeros((1, 48, 64, 3), np.uint8))[0]
    points, confidence = guide.detect(position, _truth()[0], _truth()[0], *(
        value[0] for value in _full_frame_detections()))
    assert (confidence == 0).all() and points.dtype == np.float32
    with pytest.raises(ValueError, match="guided detection failed.*make detector") as error:
        guide.report(_truth()[:1], (1.0, 1.0))
    assert "\n" not in str(error.value)
    guide.close()
