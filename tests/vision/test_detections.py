"""Detectors' files read as the body's markers: real OpenPose, COCO and MediaPipe output, the
library's own .npz, and one-line errors for bad files."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from jaxtrack.body import SPM_MARKERS
from jaxtrack.data import shared_folder
from jaxtrack.evaluation.reference import read_openpose as reference_read_openpose
from jaxtrack.vision import (
    DetectionFileError,
    Detections,
    load_detections,
    read_coco,
    read_detections,
    read_mediapipe,
    read_openpose,
    write_detections,
)
from jaxtrack.vision.detections import LAYOUT_KEYPOINTS, mapping_table, openpose_layout
from jaxtrack.vision.mediapipe import keypoint_confidence, to_upper_body

DATA = Path(__file__).resolve().parent.parent / "data" / "detections"
OPENPOSE = DATA / "openpose_body25b" / "cam01_json"
COCO = DATA / "coco17" / "test_coco.json"
MEDIAPIPE = DATA / "mediapipe"
FULL = (*SPM_MARKERS, "right_knee", "right_ankle", "left_knee", "left_ankle")
SHARED = shared_folder()
DEMO = None if SHARED is None else \
    SHARED / "pose2sim_demo_singleperson" / "reference" / "openpose_body25b"


def _at(detections, frame, person, marker):
    index = detections.marker(marker)
    return detections.points[frame, person, index], detections.confidence[frame, person, index]


def test_openpose_body25b_folder_lands_each_keypoint_on_its_marker():
    detections = read_openpose(OPENPOSE, markers=FULL)
    assert detections.layout == "BODY_25B"  # told apart from BODY_25 by where the neck lies
    assert detections.points.shape == (3, 2, 16, 2)
    np.testing.assert_array_equal(detections.people, [2, 2, 2])
    np.testing.assert_array_equal(detections.frame_ids, [0, 1, 2])
    raw = reference_read_openpose(OPENPOSE)  # the evaluation layer's own reader of these files
    for frame in range(3):
        for person in range(2):
            keypoints = raw[frame][person]
            for marker, index in (("right_shoulder", 6), ("left_shoulder", 5),
                                  ("right_wrist", 10), ("left_elbow", 7), ("neck", 17),
                                  ("right_hip", 12), ("left_knee", 13), ("right_ankle", 16)):
                point, confidence = _at(detections, frame, person, marker)
                if keypoints[index, 2] > 0:
                    np.testing.assert_allclose(point, keypoints[index, :2])
                    assert confidence == pytest.approx(keypoints[index, 2])
                else:
                    assert confidence == 0 and np.all(np.isnan(point))
    # the man's right shoulder in the first file, as written there
    point, confidence = _at(detections, 0, 0, "right_shoulder")
    np.testing.assert_allclose(point, [384.303, 478.904])
    assert confidence == pytest.approx(0.666443)
    # derived markers, by their stated rules
    keypoints = raw[0][0]
    np.testing.assert_allclose(_at(detections, 0, 0, "pelvis")[0],
                               0.5 * (keypoints[11, :2] + keypoints[12, :2]))
    np.testing.assert_allclose(_at(detections, 0, 0, "head")[0],
                               keypoints[17, :2] + 0.35 * (keypoints[18, :2] - keypoints[17, :2]))
    assert _at(detections, 0, 0, "head")[1] == pytest.approx(keypoints[[17, 18], 2].min())
    assert any("Head the top of the head" in line for line in mapping_table("BODY_25B"))


def _rewrite(folder: Path, out: Path, layout: str) -> Path:
    """The real BODY_25B files with their keypoints re-indexed into ``layout`` (BODY_25's MidHip:
    the hips' midpoint; BODY_25B's upper neck stands for the other layouts' neck)."""
    out.mkdir()
    source = {name: i for i, name in enumerate(LAYOUT_KEYPOINTS["BODY_25B"])}
    for file in sorted(folder.glob("*.json")):
        data = json.loads(file.read_text())
        for person in data["people"]:
            keypoints = np.asarray(person["pose_keypoints_2d"]).reshape(25, 3)
            rows = []
            for name in LAYOUT_KEYPOINTS[layout]:
                if name in ("MidHip", "Hip"):  # BODY_25's and HALPE_26's hip centre
                    hips = keypoints[[source["LHip"], source["RHip"]]]
                    rows.append([*hips[:, :2].mean(0), hips[:, 2].min()])
                else:
                    rows.append(keypoints[source[name]])
            person["pose_keypoints_2d"] = np.ravel(rows).tolist()
        number = file.stem.split(".")[-1]
        (out / f"take_{int(number):012d}_keypoints.json").write_text(json.dumps(data))
    return out


def _as_body_25(keypoints):
    """BODY_25B keypoints ``(..., 25, 3)`` re-indexed into BODY_25 (MidHip: the hips' midpoint)."""
    source = {name: i for i, name in enumerate(LAYOUT_KEYPOINTS["BODY_25B"])}
    hips = keypoints[..., [source["LHip"], source["RHip"]], :]
    mid = np.concatenate([hips[..., :2].mean(-2), hips[..., 2:].min(-2)], -1)
    return np.stack([mid if name == "MidHip" else keypoints[..., source[name], :]
                     for name in LAYOUT_KEYPOINTS["BODY_25"]], -2)


@pytest.mark.skipif(DEMO is None or not DEMO.is_dir(),
                    reason="the shared/data collection (pose2sim_demo_singleperson) is not "
                           "beside this checkout")
def test_body_25_and_body_25b_are_told_apart_on_every_camera_of_the_demo():
    # front views (cam01, cam02) and views from behind (cam03, cam04: no eyes found), from one
    # frame to all 100, as written (BODY_25B) and re-indexed into BODY_25
    for camera in ("cam01", "cam02", "cam03", "cam04"):
        frames = reference_read_openpose(DEMO / f"{camera}_json")
        for count in (1, 3, 100):
            keypoints = np.concatenate(frames[:count])
            assert openpose_layout(keypoints) == "BODY_25B", (camera, count)
            assert openpose_layout(_as_body_25(keypoints)) == "BODY_25", (camera, count)


@pytest.mark.parametrize("layout", ["BODY_25", "COCO_18", "HALPE_26", "COCO_17"])
def test_other_openpose_layouts_map_the_same_keypoints_to_the_same_markers(tmp_path, layout):
    detections = read_openpose(_rewrite(OPENPOSE, tmp_path / layout, layout))
    reference = read_openpose(OPENPOSE)
    assert detections.layout == layout
    # markers every layout takes from the same keypoints (the pelvis: BODY_25's MidHip and
    # HALPE_26's Hip are the hips' midpoint here); the head from the top of the head where
    # there is one (HALPE_26), the neck from the ears where there is none (COCO_17)
    same = {"right_shoulder", "right_elbow", "right_wrist", "right_hip", "left_shoulder",
            "left_elbow", "left_wrist", "left_hip", "pelvis", "neck", "thorax"}
    same |= {"head"} if layout == "HALPE_26" else set()
    same -= {"neck", "thorax"} if layout == "COCO_17" else set()
    columns = [SPM_MARKERS.index(marker) for marker in sorted(same)]
    np.testing.assert_allclose(detections.points[..., columns, :],
                               reference.points[..., columns, :], atol=1e-9)
    np.testing.assert_allclose(detections.confidence[..., columns],
                               reference.confidence[..., columns])


def test_a_25_keypoint_layout_is_given_when_asked_and_refused_when_it_does_not_fit(tmp_path):
    assert read_openpose(OPENPOSE, layout="BODY_25B").layout == "BODY_25B"
    with pytest.raises(DetectionFileError, match="18 keypoints per person, but BODY_25 has 25"):
        read_openpose(_rewrite(OPENPOSE, tmp_path / "coco", "COCO_18"), layout="BODY_25")


def test_coco_annotation_file_lands_each_keypoint_on_its_marker():
    detections = read_coco(COCO, markers=FULL)
    data = json.loads(COCO.read_text())
    assert detections.layout == "COCO_17"
    np.testing.assert_array_equal(detections.frame_ids, [785, 40083, 196141, 197388])
    labelled = [sum(a["image_id"] == i and a["num_keypoints"] > 0 for a in data["annotations"])
                for i in detections.frame_ids]
    np.testing.assert_array_equal(detections.people, labelled)  # people with no keypoint: dropped
    assert detections.frame_size is None  # the four images differ in size
    # person 442619, image 785: all 17 labelled
    np.testing.assert_allclose(_at(detections, 0, 0, "right_shoulder")[0], [358, 129])
    np.testing.assert_allclose(_at(detections, 0, 0, "left_shoulder")[0], [399, 108])
    np.testing.assert_allclose(_at(detections, 0, 0, "left_ankle")[0], [466, 362])
    np.testing.assert_allclose(_at(detections, 0, 0, "pelvis")[0],
                               [(424 + 393) / 2, (203 + 214) / 2])
    assert _at(detections, 0, 0, "pelvis")[1] == 1.0
    # person 198196, image 40083: left ear (3) unlabelled, so no head or neck; hips labelled v=1
    assert _at(detections, 1, 0, "head")[1] == 0 and _at(detections, 1, 0, "neck")[1] == 0
    np.testing.assert_allclose(_at(detections, 1, 0, "left_hip")[0], [57, 246])
    assert _at(detections, 1, 0, "left_hip")[1] == 1.0
    assert read_coco(COCO, frame_size=(640, 480)).frame_size == (640.0, 480.0)


def test_coco_results_list_reads_scores_as_confidences(tmp_path):
    data = json.loads(COCO.read_text())
    results = []
    for annotation in data["annotations"]:
        keypoints = np.asarray(annotation["keypoints"], float).reshape(17, 3)
        keypoints[:, 2] = np.where(keypoints[:, 2] > 0, 0.25 + 0.04 * np.arange(17), 0.0)
        results.append({"image_id": annotation["image_id"], "category_id": 1,
                        "keypoints": keypoints.ravel().tolist(), "score": 0.9})
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    detections = read_coco(path)
    annotated = read_coco(COCO)
    np.testing.assert_allclose(detections.points, annotated.points)
    # right shoulder: keypoint 6's score; neck: the least of shoulders' and ears' (3 = left ear)
    assert _at(detections, 0, 0, "right_shoulder")[1] == pytest.approx(0.25 + 0.04 * 6)
    assert _at(detections, 0, 0, "neck")[1] == pytest.approx(0.25 + 0.04 * 3)


def test_mediapipe_run_file_matches_the_benchmarks_adapter():
    detections = read_mediapipe(MEDIAPIPE / "mediapipe_run.npz", frame_size=(1080, 1920))
    with np.load(MEDIAPIPE / "mediapipe_run.npz") as run:
        landmarks, visibility = run["landmarks"], run["visibility"]
    assert detections.layout == "MEDIAPIPE_33"
    np.testing.assert_array_equal(detections.people, [1, 1, 1])
    np.testing.assert_allclose(_at(detections, 0, 0, "right_shoulder")[0], landmarks[0, 12])
    np.testing.assert_allclose(_at(detections, 0, 0, "left_wrist")[0], landmarks[0, 15])
    # the whole mapping against jaxtrack/vision/mediapipe.py's, an independent implementation
    np.testing.assert_allclose(detections.points[:, 0], to_upper_body(landmarks), atol=1e-9)
    np.testing.assert_allclose(detections.confidence[:, 0], keypoint_confidence(visibility),
                               atol=1e-9)


def test_mediapipe_normalised_landmarks_need_the_frame_size_and_land_in_pixels():
    path = MEDIAPIPE / "mediapipe_landmarks.npy"
    with pytest.raises(DetectionFileError, match=r"frame_size=\(width, height\)"):
        read_mediapipe(path)
    detections = read_mediapipe(path, frame_size=(1080, 1920))
    run = read_mediapipe(MEDIAPIPE / "mediapipe_run.npz")
    # the same frames through MediaPipe twice: the same landmarks to float32 precision
    np.testing.assert_allclose(detections.points, run.points, atol=0.01)
    raw = np.load(path)
    np.testing.assert_allclose(_at(detections, 2, 0, "right_elbow")[0],
                               raw[2, 14, :2] * [1080, 1920], rtol=1e-6)
    assert _at(detections, 2, 0, "right_elbow")[1] == pytest.approx(raw[2, 14, 3])


def test_own_npz_round_trips_and_load_detections_picks_the_reader(tmp_path):
    detections = read_openpose(OPENPOSE, frame_size=(1080, 1920), markers=FULL)
    path = write_detections(tmp_path / "out.npz", detections)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.npz"]  # nothing half-written left
    back = read_detections(path)
    np.testing.assert_allclose(back.points, detections.points, rtol=1e-6)
    np.testing.assert_allclose(back.confidence, detections.confidence, rtol=1e-6)
    np.testing.assert_array_equal(back.people, detections.people)
    assert (back.markers, back.layout, back.frame_size) == (FULL, "BODY_25B", (1080.0, 1920.0))
    assert load_detections(path).layout == "BODY_25B"
    some = read_detections(path, markers=("left_wrist", "neck"))
    np.testing.assert_allclose(some.points[..., 0, :],
                               back.points[..., FULL.index("left_wrist"), :])
    with pytest.raises(DetectionFileError, match="no marker 'chin'") as error:
        read_detections(path, markers=("chin",))
    _one_line(error, path)
    assert load_detections(OPENPOSE).layout == "BODY_25B"
    assert load_detections(COCO).layout == "COCO_17"
    assert load_detections(MEDIAPIPE / "mediapipe_run.npz").layout == "MEDIAPIPE_33"
    no_size = write_detections(tmp_path / "no_size.npz", read_coco(COCO))
    assert read_detections(no_size).frame_size is None


def _one_line(error, path):
    message = str(error.value)
    assert "\n" not in message and str(path) in message, message


def _folder(tmp_path, files: dict[str, str]) -> Path:
    folder = tmp_path / "json"
    folder.mkdir(parents=True)
    for name, text in files.items():
        (folder / name).write_text(text)
    return folder


def test_bad_openpose_folders_are_refused_in_one_line(tmp_path):
    real = [file.read_text() for file in sorted(OPENPOSE.glob("*.json"))]
    person = json.loads(real[0])["people"][0]["pose_keypoints_2d"]
    cases = {
        "empty": ({}, "no OpenPose JSON files"),
        "gap": ({"a_000000000000_keypoints.json": real[0], "a_000000000002_keypoints.json":
                 real[2]}, "frame 1 missing"),
        "nan": ({"a_0_keypoints.json": real[0].replace("463.158", "NaN", 1)},
                "NaN where a number must be"),
        "count": ({"a_0_keypoints.json": json.dumps(
            {"people": [{"pose_keypoints_2d": person[:69]}]})}, "23 keypoints per person is no "
                                                                  "known layout"),
        "shape": ({"a_0_keypoints.json": json.dumps(
            {"people": [{"pose_keypoints_2d": person[:74]}]})}, "one flat list of x, y, c"),
        "not_json": ({"a_0_keypoints.json": real[0][:100]}, "not JSON"),
        "not_openpose": ({"a_0_keypoints.json": "{\"persons\": []}"}, "not OpenPose JSON"),
        "mixed": ({"a_0_keypoints.json": real[0], "a_1_keypoints.json": json.dumps(
            {"people": [{"pose_keypoints_2d": person[:54]}]})}, "keep one detector's output"),
        "nobody": ({"a_0_keypoints.json": "{\"people\": []}"}, "pass layout="),
    }
    for name, (files, message) in cases.items():
        folder = _folder(tmp_path / name, files) if files else (tmp_path / name)
        folder.mkdir(parents=True, exist_ok=True)
        with pytest.raises(DetectionFileError, match=message) as error:
            read_openpose(folder)
        _one_line(error, folder)
    with pytest.raises(DetectionFileError, match="no such folder"):
        read_openpose(tmp_path / "absent")


def test_bad_coco_mediapipe_and_npz_files_are_refused_in_one_line(tmp_path):
    data = json.loads(COCO.read_text())
    short = dict(data, annotations=[dict(data["annotations"][0],
                                         keypoints=data["annotations"][0]["keypoints"][:50])])
    no_id = [{"keypoints": data["annotations"][0]["keypoints"]}]
    nan = COCO.read_text().replace("367,", "NaN,", 1)
    for name, text, message in (("short.json", json.dumps(short), "has 50 keypoint values"),
                                ("no_id.json", json.dumps(no_id), "needs image_id"),
                                ("nan.json", nan, "NaN where a number must be"),
                                ("dict.json", "{\"images\": 3}", "neither a COCO results"),
                                ("empty.json", "[]", "no images and no keypoint entries")):
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(DetectionFileError, match=message) as error:
            read_coco(path)
        _one_line(error, path)
    landmarks = np.load(MEDIAPIPE / "mediapipe_landmarks.npy")
    for name, arrays, message in (
            ("rows.npy", landmarks[:, :32], r"must be \(time, 33, 3 \| 4\)"),
            ("two.npz", {"a": landmarks, "b": landmarks}, "give one"),
            ("novis.npz", {"landmarks": landmarks[..., :2]}, "need visibility"),
            ("nanvis.npz", {"landmarks": landmarks[..., :2],
                            "visibility": np.where(np.arange(33) == 4, np.nan, 0.5)[None]
                            .repeat(3, 0)}, "NaN or infinity in visibility")):
        path = tmp_path / name
        if name.endswith(".npy"):
            np.save(path, arrays)
        else:
            np.savez(path, **arrays)
        with pytest.raises(DetectionFileError, match=message) as error:
            read_mediapipe(path, frame_size=(1080, 1920))
        _one_line(error, path)
    detections = read_coco(COCO)
    path = tmp_path / "bad.npz"
    for arrays, message in (({"points": detections.points}, "no array confidence"),
                            ({"points": detections.points[0], "confidence": 1, "layout": "x",
                              "frame_size": [1, 1]}, r"must be \(time, people, markers, 2\)"),
                            ({"points": detections.points, "layout": "COCO_17",
                              "confidence": detections.confidence * 2, "frame_size": [1, 1]},
                             r"confidence must lie in \[0, 1\]")):
        np.savez(path, **arrays)
        with pytest.raises(DetectionFileError, match=message) as error:
            read_detections(path)
        _one_line(error, path)
    path.write_bytes(b"not a zip")
    with pytest.raises(DetectionFileError, match="not a readable") as error:
        read_detections(path)
    _one_line(error, path)


def test_detections_are_checked_and_absent_keypoints_made_uniform():
    points = np.zeros((2, 1, 12, 2))
    confidence = np.full((2, 1, 12), 0.5)
    confidence[1, 0, 3] = 0.0
    detections = Detections(points, confidence, np.array([1, 0]), SPM_MARKERS, "markers")
    assert np.all(np.isnan(detections.points[1]))  # frame 1 holds no one
    assert np.all(detections.confidence[1] == 0)
    with pytest.raises(ValueError, match=r"confidence must lie in \[0, 1\]"):
        Detections(points, confidence + 1, np.array([1, 1]), SPM_MARKERS, "markers")
    with pytest.raises(ValueError, match="people must be"):
        Detections(points, confidence, np.array([2, 1]), SPM_MARKERS, "markers")
    with pytest.raises(ValueError, match="no rule maps COCO_17 keypoints to chin"):
        from jaxtrack.vision.detections import map_keypoints
        map_keypoints(np.zeros((17, 3)), "COCO_17", ("chin",))


def test_copied_gap_in_real_frames_is_named(tmp_path):
    folder = tmp_path / "cam01_json"
    folder.mkdir()
    for name in ("cam01.0000.json", "cam01.0002.json"):
        shutil.copy(OPENPOSE / name, folder / name)
    with pytest.raises(DetectionFileError, match="frame 1 missing .*cam01.0000.json to "
                                                 "cam01.0002.json") as error:
        read_openpose(folder)
    _one_line(error, folder)
