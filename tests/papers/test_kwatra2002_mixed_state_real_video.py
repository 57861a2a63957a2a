"""The mixed-state real-video benchmark's truth: which reference keypoints stand for the five
parts, the true postures labelled from the reference's 3-D, how much of the parts a silhouette
covers, and MediaPipe's masks skipped without its venv (the benchmark itself tracks four videos
and is a script, not a test)."""

import numpy as np
import pytest

from jaxtrack.data import shared_folder
from jaxtrack.evaluation.reference import TRC_KEYPOINTS
from jaxtrack.priors.postures import CRAWLING, STANDING
from jaxtrack.vision.parts import PART_NAMES
from papers.kwatra2002.mixed_state_real_video import (
    LABEL_KEYPOINTS,
    label_markers,
    posture_confusion,
    truth_in_silhouette,
    truth_parts,
    truth_postures,
)

SHARED = shared_folder()
FOLDER = None if SHARED is None else SHARED / "pose2sim_demo_singleperson"


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


def test_the_labelling_markers_are_the_named_keypoints_and_the_hips_midpoint():
    keypoints = np.arange(3 * len(TRC_KEYPOINTS), dtype=float).reshape(1, -1, 3)
    markers = label_markers(keypoints)
    assert markers.shape == (1, len(LABEL_KEYPOINTS), 3)
    names = list(LABEL_KEYPOINTS)
    row = {name: TRC_KEYPOINTS.index(name) for name in TRC_KEYPOINTS}
    np.testing.assert_array_equal(markers[0, names.index("neck")], keypoints[0, row["Neck"]])
    np.testing.assert_array_equal(markers[0, names.index("pelvis")],
                                  0.5 * (keypoints[0, row["LHip"]] + keypoints[0, row["RHip"]]))


@pytest.mark.skipif(FOLDER is None or not (FOLDER / "reference" / "pose-3d").is_dir(),
                    reason="the shared/data collection (pose2sim_demo_singleperson) is not "
                    "beside this checkout")
def test_the_man_on_the_beam_stands_then_bends_in_a_lunge_then_stands():
    from jaxtrack.evaluation.reference import TRC_FILES, load_reference, read_trc

    _, trc, _ = read_trc(FOLDER / "reference" / "pose-3d" / TRC_FILES[False])
    reference = load_reference(FOLDER, num_video_frames=100)["cam01"]
    labels = truth_postures(np.asarray(trc)[reference.rows], reference.keypoints)
    assert set(np.unique(labels)) == {STANDING, CRAWLING}
    # upright for the first 27 rows, bent through the lunge, upright again at the end
    assert np.all(labels[:25] == STANDING) and np.all(labels[-20:] == STANDING)
    assert np.mean(labels[30:65] == CRAWLING) == 1.0
    assert 40 <= np.sum(labels == CRAWLING) <= 50


def test_mediapipe_masks_are_skipped_with_a_reason_without_its_python(tmp_path, monkeypatch):
    from jaxtrack.vision.mediapipe import person_masks

    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", str(tmp_path / "no-python"))
    video = tmp_path / "v.mp4"
    from jaxtrack.vision import write_frames

    write_frames(np.zeros((3, 32, 32, 3), np.uint8), video, 30.0, (32, 32))
    result = person_masks(video, tmp_path / "masks.npz")
    assert isinstance(result, dict) and "no MediaPipe python" in result["skipped"]
    assert not (tmp_path / "masks.npz").exists()


def test_the_confusion_counts_frames_by_true_and_estimated_posture():
    counts = np.asarray(posture_confusion(np.array([0, 0, 2, 2, 2]), np.array([0, 2, 2, 2, 4])))
    assert counts.shape == (5, 5) and counts.sum() == 5
    assert counts[0, 0] == 1 and counts[0, 2] == 1 and counts[2, 2] == 2 and counts[2, 4] == 1


def test_a_bad_posture_model_is_refused_in_one_line(capsys):
    from papers.kwatra2002 import mixed_state_real_video as benchmark

    with pytest.raises(SystemExit):
        benchmark.main(["--posture-model", "2,pooled"])
    assert "--posture-model: '2,pooled' is not K,COVARIANCE,RIDGE,VIEWS" in (
        capsys.readouterr().err)
