"""Haar-cascade faces: on a real Pose2Sim frame, none on blank or noise, largest first.

OpenCV 5 wheels have neither ``cv2.CascadeClassifier`` nor the cascade files; there the
detector must say so (and what to install) instead of failing obscurely, and the tests that need
a working detector are skipped.
"""

import numpy as np
import pytest

import jaxtrack.vision.faces as faces_module
from jaxtrack.data import shared_folder
from jaxtrack.vision import (
    FaceDetectorUnavailableError,
    detect_face,
    detect_faces,
    face_detector_available,
    read_video,
)

AVAILABLE = face_detector_available()
SHARED = shared_folder()
POSE2SIM = None if SHARED is None else SHARED / "pose2sim_demo_singleperson/videos/cam01.mp4"
needs_detector = pytest.mark.skipif(not AVAILABLE, reason="this OpenCV has no Haar cascade")


@needs_detector
@pytest.mark.skipif(POSE2SIM is None or not POSE2SIM.is_file(),
                    reason="the shared/data collection is not beside this checkout")
def test_face_on_a_real_pose2sim_frame():
    frames = read_video(POSE2SIM, max_frames=2, stride=60).frames  # frames 0 and 60
    height, width = frames.shape[1:3]
    boxes = [detect_face(frame) for frame in frames]
    for box in boxes:
        assert box is not None and box.shape == (4,)
        x, y, w, h = box
        # the bystander at the back left (the subject's own face is pixelated in the data set):
        # a face-sized box in the upper part of the portrait frame
        assert 0.02 * width < w < 0.15 * width and 0.7 < h / w < 1.4
        assert y + h < 0.3 * height and 0 <= x and x + w <= width
    # she stands still: the same box a second later
    np.testing.assert_allclose(boxes[0], boxes[1], atol=6)


@needs_detector
def test_no_face_on_blank_or_noise():
    rng = np.random.default_rng(0)
    for image in (np.zeros((480, 640, 3), np.uint8), np.full((480, 640, 3), 200, np.uint8),
                  rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)):
        assert detect_face(image) is None
        boxes = detect_faces(image)
        assert boxes.shape == (0, 4) and boxes.dtype == np.int64


def test_boxes_sorted_largest_first(monkeypatch):
    class Classifier:  # stands in for cv2.CascadeClassifier: the ordering is ours to test
        def __init__(self, boxes):
            self.boxes = boxes

        def detectMultiScale(self, grey, **options):  # noqa: N802 (OpenCV's name)
            assert grey.dtype == np.uint8 and grey.ndim == 2
            return self.boxes

    found = np.array([[5, 5, 20, 20], [50, 40, 60, 60], [200, 10, 30, 30]], np.int32)
    monkeypatch.setattr(faces_module, "_cascade_path", lambda cascade: None)
    monkeypatch.setattr(faces_module, "_classifier", lambda path: Classifier(found))
    image = np.zeros((120, 260, 3), np.uint8)
    np.testing.assert_array_equal(detect_faces(image), found[[1, 2, 0]])
    np.testing.assert_array_equal(detect_face(image), [50, 40, 60, 60])
    monkeypatch.setattr(faces_module, "_classifier", lambda path: Classifier(()))  # OpenCV's none
    assert detect_faces(image).shape == (0, 4) and detect_face(image) is None


def test_bad_input_and_missing_cascade_file(tmp_path):
    with pytest.raises(ValueError, match="uint8"):
        detect_faces(np.zeros((40, 40, 3), np.float32))
    with pytest.raises(ValueError, match="shape"):
        detect_faces(np.zeros((40, 40, 4), np.uint8))
    missing = tmp_path / "faces.xml"
    with pytest.raises(FaceDetectorUnavailableError, match="faces.xml: no such Haar cascade"):
        detect_faces(np.zeros((40, 40, 3), np.uint8), cascade=missing)
    assert not face_detector_available(missing)


@pytest.mark.skipif(AVAILABLE, reason="this OpenCV has a working Haar cascade")
def test_opencv_without_cascade_says_what_to_install():
    with pytest.raises(FaceDetectorUnavailableError, match="opencv-python-headless<5"):
        detect_faces(np.zeros((40, 40, 3), np.uint8))


@needs_detector
@pytest.mark.skipif(POSE2SIM is None or not POSE2SIM.is_file(),
                    reason="the shared/data collection is not beside this checkout")
def test_face_candidates_keep_the_detected_face_and_merge_duplicates():
    from jaxtrack.vision import face_candidates

    frame = read_video(POSE2SIM, max_frames=1).frames[0]
    candidates = face_candidates(frame)
    height, width = frame.shape[:2]
    assert candidates.ndim == 2 and candidates.shape[1] == 4 and 1 <= len(candidates) <= 8
    assert np.all(candidates[:, :2] >= 0) and np.all(candidates[:, 0] + candidates[:, 2] <= width)
    assert np.all(candidates[:, 1] + candidates[:, 3] <= height)
    # the frontal detector's face is among them (merged with its twins from other cascades)
    face = detect_face(frame)
    overlaps = [faces_module._overlap(face, box[None])[0] for box in candidates]
    assert max(overlaps) > 0.5
    # no two candidates overlap by more than half of the smaller
    for i, box in enumerate(candidates):
        assert np.all(faces_module._overlap(box, np.delete(candidates, i, axis=0)) <= 0.5)
    assert face_candidates(np.zeros((240, 320, 3), np.uint8)).shape == (0, 4)
