"""``jaxtrack track --keypoints FILE_OR_FOLDER [--person x0,y0,x1,y1]``: any detections format
(a real OpenPose folder with two people per frame here), the person inside the box followed;
bad boxes refused in one line before any work."""

from pathlib import Path

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.cli import main
from jaxtrack.cli._common import UserError
from jaxtrack.cli._pose import read_keypoints
from jaxtrack.vision.detections import load_detections

OPENPOSE = Path(__file__).parents[1] / "data" / "detections" / "openpose_body25b" / "cam01_json"


def _box_around(points: np.ndarray) -> str:
    found = points[np.all(np.isfinite(points), -1)]
    (x0, y0), (x1, y1) = found.min(0) - 5, found.max(0) + 5
    return f"{x0},{y0},{x1},{y1}"


def test_the_person_in_the_box_is_read_from_an_openpose_folder():
    detections = load_detections(OPENPOSE, markers=UPPER_BODY_12)
    assert detections.people.tolist() == [2, 2, 2]
    for person in (0, 1):
        keypoints, confidence = read_keypoints(OPENPOSE, _box_around(detections.points[0,
                                                                                       person]))
        assert keypoints.shape == (3, 12, 2) and confidence.shape == (3, 12)
        np.testing.assert_array_equal(keypoints[0], detections.points[0, person])
    first, _ = read_keypoints(OPENPOSE, _box_around(detections.points[0, 0]))
    second, _ = read_keypoints(OPENPOSE, _box_around(detections.points[0, 1]))
    assert np.nanmin(np.linalg.norm(first - second, axis=-1)) > 50  # two different people


@pytest.mark.parametrize(("person", "message"), [
    ("1,2,3", "--person must be x0,y0,x1,y1"),
    ("10,10,5,20", "--person must be x0,y0,x1,y1"),
    ("0,0,5,5", "nobody detected in frame 0 lies inside the box"),
])
def test_a_bad_person_box_is_one_line(person, message):
    with pytest.raises(UserError, match=message):
        read_keypoints(OPENPOSE, person)


def test_person_without_keypoints_is_refused_before_any_work(tmp_path, capsys):
    code = main(["track", "--method", "condensation", "--video", str(tmp_path / "v.mp4"),
                 "--out", str(tmp_path / "out"), "--person", "0,0,10,10"])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and "give --keypoints" in error
    assert not (tmp_path / "out").exists()
