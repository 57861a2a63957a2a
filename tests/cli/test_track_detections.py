"""``jaxtrack track`` with detections: ``--detector mediapipe`` runs the detector over the video
first (here the real worker's code around a bright-pixel stand-in, ``tests/vision/
_fake_mediapipe_worker.py``; with ``make detector`` done, MediaPipe itself in a slow test) and
writes the detections beside the outputs, detecting again around the person where the full
frame shows someone else; without the detector's venv it is one line naming ``make detector``;
and (slow) the detection density is fitted on the video and ``track.json`` records the fitted
values, the hand-set ones and the fit's cost."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.cli._detector import detect_video
from jaxtrack.data import path as data_path
from jaxtrack.likelihoods.detections import detection_model
from jaxtrack.vision import mediapipe
from jaxtrack.vision.detections import Detections, read_detections, write_detections
from jaxtrack.vision.video import write_frames

FAKE = Path(__file__).parents[1] / "vision" / "_fake_mediapipe_worker.py"
VIDEO = data_path("pose2sim/videos/cam03_half.mp4")  # 544x960
MEDIAPIPE_CAM03 = Path(__file__).parents[1] / "data" / "detections" / "mediapipe_pose2sim" / \
    "cam03.npz"
SHARED_VIDEO = Path("/work/shared/data/pose2sim_demo_singleperson/videos/cam01.mp4")
PERSON = (20.0, 24.0)  # the bright "person" blob's centre in the test video (x, y)


def _video_with_a_passer_by(path: Path) -> Path:
    """Five 80x60 frames: a still 10x10 bright blob (the person) centred at PERSON; in frames
    2 and 3 a second one at the right (the fake detector, MediaPipe-like, reports one person:
    the centroid of every bright pixel, between the two)."""
    frames = np.zeros((5, 60, 80, 3), np.uint8)
    frames[:, 19:29, 15:25] = 255
    frames[2:4, 30:40, 60:70] = 255
    return write_frames(list(frames), path, 10.0, (80, 60))


def test_the_detector_runs_over_the_video_and_detects_again_around_the_person(tmp_path,
                                                                             monkeypatch):
    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", sys.executable)
    monkeypatch.setattr(mediapipe, "WORKER", FAKE)
    video = _video_with_a_passer_by(tmp_path / "v.mp4")
    args = argparse.Namespace(video=video, max_size=960, out=tmp_path / "out")
    path, record = detect_video(args, 0, None, (10.0, 14.0, 30.0, 34.0))
    detections = read_detections(path)
    assert path.name == "detections.npz" and detections.frame_size == (80.0, 60.0)
    assert detections.people.tolist() == [1, 1, 1, 1, 1]
    head = detections.points[:, 0, detections.marker("head")]
    # the full frame's "person" lies between the two blobs in frames 2 and 3; the region
    # around the person's last detection holds the person alone
    assert {2, 3} <= set(record["redetected_frames"])
    np.testing.assert_allclose(head, np.tile(PERSON, (5, 1)), atol=2.0)
    assert record["seconds"] > 0 and record["wall_seconds"] >= record["seconds"]
    # without the box, the full frame's detection is kept: 20 px away in frames 2 and 3
    path, record = detect_video(args, 0, None, None)
    moved = read_detections(path).points[2, 0, 0] - np.array(PERSON)
    assert record["redetected_frames"] == [] and np.linalg.norm(moved) > 15


def test_without_the_detectors_venv_it_is_one_line_naming_make_detector(tmp_path, monkeypatch,
                                                                        capsys):
    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", str(tmp_path / "no" / "python"))
    code = main(["track", "--method", "condensation", "--video", str(VIDEO), "--out",
                 str(tmp_path / "out"), "--detector", "mediapipe", "--init", "keypoints"])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and "make detector" in error
    assert "--detector mediapipe" in error and not (tmp_path / "out").exists()


@pytest.mark.parametrize(("extra", "message"), [
    (["--no-fit"], "--no-fit: it reads a detector's keypoints"),
    (["--fit-iterations", "3"], "--fit-iterations: it reads a detector's keypoints"),
    (["--no-image"], "--no-image: it reads a detector's keypoints"),
    (["--keypoints", "k.npz", "--detector", "mediapipe"], "not both"),
    (["--keypoints", "k.npz", "--keypoint-weight", "2", "--no-fit"], "not fitted"),
    (["--guided"], "--guided: it runs the detector on the region the tracker predicts"),
    (["--keypoints", "k.npz", "--guided"], "give --detector mediapipe"),
])
def test_detection_options_without_detections_are_one_line(tmp_path, capsys, extra, message):
    code = main(["track", "--method", "condensation", "--video", str(VIDEO), "--out",
                 str(tmp_path / "out"), *extra])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and message in error, error


def _half_size_detections(path: Path) -> Path:
    """MediaPipe's detections of cam03 (1088x1920) in the pixels of its half-size copy."""
    from jaxtrack.vision.detections import read_mediapipe

    full = read_mediapipe(MEDIAPIPE_CAM03)
    return write_detections(path, Detections(
        (full.points + 0.5) * 0.5 - 0.5, full.confidence, full.people, full.markers,
        full.layout, (544.0, 960.0)))


@pytest.mark.slow  # the fit's and the tracker's compiles: about a minute of CPU
def test_the_fitted_density_is_recorded_and_tracked_with(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["track", "--method", "condensation", "--video", str(VIDEO), "--out", str(out),
                 "--frames", "0:6", "--max-size", "96", "--particles", "16",
                 "--foreground", "none", "--keypoints",
                 str(_half_size_detections(tmp_path / "cam03.npz")), "--init", "keypoints",
                 "--fit-iterations", "3"])
    assert code == 0, capsys.readouterr().err
    record = json.loads((out / "track.json").read_text())
    fit = record["detections"]["fit"]
    hand_set = detection_model()
    assert fit["hand_set"]["pixel_noise"] == pytest.approx(float(hand_set.pixel_noise))
    assert list(fit["hand_set"]["joint_scales"].values()) == pytest.approx(
        np.asarray(hand_set.joint_scales).tolist(), abs=1e-5)
    assert fit["fitted"]["pixel_noise"] != fit["hand_set"]["pixel_noise"]
    assert fit["iterations"] == 3 and fit["particles"] == 16
    assert fit["seconds"] > 0 and np.isfinite(fit["log_evidence_final"])
    # the tracker ran with the fitted density
    tracked = record["tracker"]["likelihood"]
    assert tracked["kind"] == "limbs+edges+detections"
    assert tracked["pixel_noise"] == pytest.approx(fit["fitted"]["pixel_noise"], abs=1e-4)
    assert tracked["joint_scales"] == pytest.approx(
        list(fit["fitted"]["joint_scales"].values()), abs=1e-5)
    assert record["frames_tracked"] == 6 and record["timings"]["detector_seconds"] is None


@pytest.mark.slow  # MediaPipe itself, on three frames of a Pose2Sim video
def test_the_real_detector_finds_the_man_in_three_frames(tmp_path):
    if not mediapipe.mediapipe_python().exists() or not SHARED_VIDEO.is_file():
        pytest.skip("no detector venv (make detector) or no shared Pose2Sim video")
    args = argparse.Namespace(video=SHARED_VIDEO, max_size=480, out=tmp_path)
    path, record = detect_video(args, 1, 3, None)
    detections = read_detections(path)
    assert detections.people.tolist() == [0, 1, 1, 1] and record["frames_with_person"] == 3
    assert detections.frame_size == (1080.0, 1920.0)
    points = detections.points[1:, 0]
    assert np.isfinite(points).all() and record["seconds"] > 0
    # an upright man: head above the pelvis, in the video's own pixels
    assert np.all(points[:, detections.marker("head"), 1] <
                  points[:, detections.marker("pelvis"), 1] - 200)


def test_one_persons_keypoints_become_the_densitys_frames_outside_and_missing_left_out():
    from jaxtrack.experiments.detection_tracking import keypoint_frames

    points = np.full((3, 12, 2), 10.0)
    confidence = np.full((3, 12), 0.8)
    points[0, 2] = np.nan           # not found
    points[1, 3] = (79.6, 5.0)      # right of the 80-pixel-wide frame's last pixel centre
    confidence[2] = 0.0             # nobody in frame 2
    frames = keypoint_frames(points, confidence, (80, 60))
    assert frames.points.shape == (3, 1, 12, 2) and frames.num_people.tolist() == [1, 1, 0]
    assert frames.confidence[0, 0, 2] == 0 and frames.confidence[1, 0, 3] == 0
    assert frames.confidence[0, 0, 1] == pytest.approx(0.8)
    assert np.isfinite(frames.points).all() and frames.image_size.tolist() == [[80, 60]] * 3


def test_guided_detection_is_on_with_a_named_person_unless_refused():
    from jaxtrack.cli._detector import guided

    def args(**given):
        values = {"detector": "mediapipe", "person": None, "guided": None,
                  "keypoint_weight": None}
        return argparse.Namespace(**{**values, **given})

    assert guided(args(person="1,2,3,4")) and not guided(args())
    assert not guided(args(person="1,2,3,4", guided=False)) and guided(args(guided=True))
    assert not guided(args(person="1,2,3,4", detector=None))
    # --keypoint-weight scores the keypoints by the image likelihood: no mixture to choose
    assert not guided(args(person="1,2,3,4", keypoint_weight=1.5))


@pytest.mark.slow  # a tracker's compile and the detector's process, on 8 frames
def test_the_command_tracks_with_tracker_guided_detection(tmp_path, monkeypatch, capsys):
    """``--detector mediapipe --person`` on the crossing of ``tests/experiments/
    test_guided_detection.py`` (the stand-in detector finds the largest person): track.json
    records every frame's region, where it came from, and the detector's time apart."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "experiments"))
    from test_guided_detection import _boxes, _crossing_video

    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", sys.executable)
    monkeypatch.setenv("FAKE_DETECTOR", "largest")
    monkeypatch.setattr(mediapipe, "WORKER", FAKE)
    video = _crossing_video(tmp_path / "crossing.mp4")
    x0, y0, x1, y1 = _boxes(0)[0]
    out = tmp_path / "out"
    code = main(["track", "--method", "condensation", "--video", str(video), "--out", str(out),
                 "--frames", "0:8", "--particles", "32", "--no-fit", "--no-image",
                 "--detector", "mediapipe", "--person", f"{x0},{y0},{x1},{y1}"])
    assert code == 0, capsys.readouterr().err
    record = json.loads((out / "track.json").read_text())
    frames = [entry["guided_detection"] for entry in record["frames"]]
    assert frames[0] is None and len(frames) == 8
    assert {frame["region_from"] for frame in frames[1:]} == {"tracker prediction"}
    assert record["guided_detection"]["frames_detected"] == 7
    assert record["detections"]["guided"] and record["tracker"]["guided_detection"]
    timings = record["timings"]
    assert timings["guided_detector_wall_seconds"] > 0
    assert timings["tracker_seconds_per_frame"] < timings["seconds_per_frame"]
