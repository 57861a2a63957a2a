"""The Pose2Sim reference: its projection agrees with the 2-D detections it was triangulated from.

The independent reference is OpenPose's own BODY_25B detections in each camera
(``reference/openpose_body25b``): the triangulated keypoints, projected by our reading of
``Calib.qca.txt``, must land on them within the accuracy SOURCE.txt measured (median 8-17 px per
camera). A wrong axis convention, rotation reading or unit puts them hundreds of pixels off.
"""

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data import shared_folder
from jaxtrack.evaluation import evaluate_track
from jaxtrack.evaluation.reference import (
    BODY_25B_INDEX,
    TRC_KEYPOINTS,
    ReferenceDataError,
    load_reference,
    read_openpose,
    read_trc,
    to_upper_body,
)

SHARED = shared_folder()
FOLDER = None if SHARED is None else SHARED / "pose2sim_demo_singleperson"
needs_data = pytest.mark.skipif(
    FOLDER is None or not (FOLDER / "reference" / "pose-3d").is_dir(),
    reason="the shared/data collection (pose2sim_demo_singleperson/reference) is not beside "
           "this checkout")
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
MIN_CONFIDENCE = 0.3


@pytest.fixture(scope="module")
def references():
    return load_reference(FOLDER, num_video_frames=100)


@pytest.fixture(scope="module")
def references_by_row():
    # the detections were triangulated row by row: JSON k made .trc row k
    return load_reference(FOLDER, frame_offset=0)


def _distances_to_detections(reference, detections):
    """Pixel distances from the projected keypoints to the confident detections of the person
    nearest them (the JSONs also hold a bystander)."""
    order = [BODY_25B_INDEX[name] for name in TRC_KEYPOINTS]
    distances = []
    for projected, row in zip(reference.keypoints, reference.rows, strict=True):
        people = detections[row][:, order]
        if len(people) == 0:
            continue
        gaps = np.linalg.norm(people[..., :2] - projected, axis=-1)
        confident = people[..., 2] >= MIN_CONFIDENCE
        medians = [np.median(gap[ok]) if ok.any() else np.inf
                   for gap, ok in zip(gaps, confident, strict=True)]
        person = int(np.argmin(medians))
        distances.append(gaps[person][confident[person]])
    return np.concatenate(distances)


@needs_data
@pytest.mark.parametrize("camera", CAMERAS)
def test_projection_lands_on_the_detections(references_by_row, camera):
    detections = read_openpose(FOLDER / "reference" / "openpose_body25b" / f"{camera}_json")
    distances = _distances_to_detections(references_by_row[camera], detections)
    assert len(distances) > 1000  # most of 100 frames × 21 keypoints were detected confidently
    # SOURCE.txt: per camera 11.4, 7.9, 17.2, 9.1 px; a wrong convention is off by hundreds
    assert np.median(distances) < 20.0
    assert np.percentile(distances, 90) < 60.0


@needs_data
def test_frames_are_aligned_one_later_and_cover_the_videos(references):
    for camera in CAMERAS:
        reference = references[camera]
        # row k is video frame k + 1; the 100-frame video has no frame for the last row
        np.testing.assert_array_equal(reference.frame_indices, np.arange(1, 100))
        np.testing.assert_array_equal(reference.rows, np.arange(99))
        assert reference.markers.shape == (99, 12, 2)
        assert reference.keypoints.shape == (99, 21, 2)
        assert np.all(reference.depth > 1.0)


@needs_data
def test_the_markers_make_a_plausible_upright_torso(references):
    index = UPPER_BODY_12.index
    for camera in CAMERAS:
        markers = references[camera].markers
        head, neck, thorax, pelvis = (markers[:, index(name)] for name in
                                      ("head", "neck", "thorax", "pelvis"))
        torso = np.linalg.norm(neck - pelvis, axis=-1)
        # a 1.72 m man filling most of a 1920 px high frame: a torso of a few hundred pixels
        assert np.all((150 < torso) & (torso < 700)), (camera, torso.min(), torso.max())
        # image y points down: head above neck above thorax above pelvis (he stays upright)
        assert np.all(head[:, 1] < neck[:, 1])
        assert np.all(neck[:, 1] < thorax[:, 1]) and np.all(thorax[:, 1] < pelvis[:, 1])
        # head-neck 0.1-0.4 torso (the rigs' 0.22), shoulders and hips near the torso's ends
        head_neck = np.linalg.norm(head - neck, axis=-1) / torso
        assert 0.1 < np.median(head_neck) < 0.4
        for side in ("right", "left"):
            shoulder = np.linalg.norm(markers[:, index(f"{side}_shoulder")] - neck, axis=-1)
            hip = np.linalg.norm(markers[:, index(f"{side}_hip")] - pelvis, axis=-1)
            assert np.median(shoulder / torso) < 0.5 and np.median(hip / torso) < 0.35
        # the reference scores itself perfectly and is within the image
        assert evaluate_track(markers, markers, UPPER_BODY_12)["mean_error_torso"] == 0.0
        assert markers[..., 0].min() > 0 and markers[..., 0].max() < 1080
        assert markers[..., 1].min() > 0 and markers[..., 1].max() < 1920


@needs_data
def test_scaling_and_selecting_frames(references):
    reference = references["cam03"]
    half = reference.scaled(0.5)
    np.testing.assert_allclose(half.markers, (reference.markers + 0.5) * 0.5 - 0.5)
    picked = reference.select([5, 1, 99])
    np.testing.assert_array_equal(picked.rows, [4, 0, 98])
    np.testing.assert_array_equal(picked.markers[1], reference.markers[0])
    with pytest.raises(ValueError, match="covers video frames 1..99"):
        reference.select([0])


def test_the_marker_map_on_a_made_up_body():
    points = np.zeros((len(TRC_KEYPOINTS), 3))
    named = {"Neck": (0, 0, 1.5), "Head": (0, 0, 1.8), "RHip": (-0.1, 0, 1.0),
             "LHip": (0.1, 0, 1.0), "RShoulder": (-0.2, 0, 1.45), "LWrist": (0.5, 0, 1.2)}
    for name, value in named.items():
        points[TRC_KEYPOINTS.index(name)] = value
    markers = dict(zip(UPPER_BODY_12, to_upper_body(points), strict=True))
    np.testing.assert_allclose(markers["pelvis"], (0, 0, 1.0))
    np.testing.assert_allclose(markers["thorax"], (0, 0, 1.3))
    np.testing.assert_allclose(markers["head"], (0, 0, 1.605))
    np.testing.assert_allclose(markers["right_shoulder"], named["RShoulder"])
    np.testing.assert_allclose(markers["left_wrist"], named["LWrist"])
    with pytest.raises(ValueError, match="lack"):
        to_upper_body(points[:5], TRC_KEYPOINTS[:5])


def test_missing_and_damaged_files_raise_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        read_trc(tmp_path / "absent.trc")
    bad = tmp_path / "bad.trc"
    bad.write_text("not a trc\n")
    with pytest.raises(ReferenceDataError, match="not a .trc file"):
        read_trc(bad)
    damaged = tmp_path / "damaged.trc"
    damaged.write_text("PathFileType\t4\n"
                       "DataRate\tNumMarkers\tUnits\n60\t2\tm\n"
                       "Frame#\tTime\tA\t\t\tB\t\t\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
                       "1\t0.0\t1\t2\tthree\t4\t5\t6\n")
    with pytest.raises(ReferenceDataError, match="damaged"):
        read_trc(damaged)
    with pytest.raises(FileNotFoundError, match="not found"):
        load_reference(tmp_path)
    with pytest.raises(FileNotFoundError, match="no OpenPose"):
        read_openpose(tmp_path)
    (tmp_path / "x.json").write_text("{}")
    with pytest.raises(ReferenceDataError, match="not an OpenPose"):
        read_openpose(tmp_path)
