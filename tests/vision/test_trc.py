"""``.trc`` files (``jaxtrack.vision.trc``): the header is OpenSim's and Pose2Sim's format, a
track written is read back (by this module and by the reader of Pose2Sim's reference), missing
markers stay missing, and bad input is refused in one line."""

from pathlib import Path

import numpy as np
import pytest

from jaxtrack.evaluation.reference import read_trc as read_reference_trc
from jaxtrack.vision.trc import TrcFileError, read_trc, write_trc

POSE2SIM_TRC = Path("/work/shared/data/pose2sim_demo_singleperson/reference/pose-3d/"
                    "S00_P00_T01_BalancingTrial_0-100.trc")
NAMES = ("head", "neck", "right_wrist")


def _track(frames: int = 4) -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.normal(size=(frames, len(NAMES), 3))


def test_the_header_is_the_format_opensim_and_pose2sim_read(tmp_path):
    path = write_trc(tmp_path / "track.trc", _track(), NAMES, 60.0)
    lines = path.read_text().split("\n")
    assert lines[0].split("\t") == ["PathFileType", "4", "(X/Y/Z)", "track.trc"]
    assert lines[1].split("\t") == ["DataRate", "CameraRate", "NumFrames", "NumMarkers",
                                    "Units", "OrigDataRate", "OrigDataStartFrame",
                                    "OrigNumFrames"]
    assert lines[2].split("\t") == ["60", "60", "4", "3", "m", "60", "1", "4"]
    # each name heads its X, Y, Z columns: two empty fields after it
    assert lines[3].split("\t") == ["Frame#", "Time", "head", "", "", "neck", "", "",
                                    "right_wrist", "", ""]
    assert lines[4].split("\t") == ["", "", "X1", "Y1", "Z1", "X2", "Y2", "Z2", "X3", "Y3",
                                    "Z3"]
    assert lines[5].split("\t")[:2] == ["1", "0.000000"]
    assert lines[6].split("\t")[:2] == ["2", "0.016667"]
    if POSE2SIM_TRC.is_file():  # Pose2Sim's own file has the same first, second and fifth lines
        theirs = POSE2SIM_TRC.read_text().split("\n")
        assert theirs[0].split("\t")[:3] == lines[0].split("\t")[:3]
        assert theirs[1] == lines[1]
        assert theirs[3].split("\t")[:2] == ["Frame#", "Time"]


def test_a_track_is_read_back_by_this_reader_and_by_the_reference_reader(tmp_path):
    track = _track()
    path = write_trc(tmp_path / "track.trc", track, NAMES, 30.0, first_frame=5)
    positions, names, header = read_trc(path)
    np.testing.assert_allclose(positions, track, atol=1e-6)
    assert names == NAMES and header["DataRate"] == 30.0 and header["Units"] == "m"
    assert header["frames"].tolist() == [5, 6, 7, 8]
    np.testing.assert_allclose(header["times"], np.arange(4) / 30.0, atol=1e-6)
    their_names, theirs, rate = read_reference_trc(path)
    np.testing.assert_allclose(theirs, track, atol=1e-6)
    assert their_names == NAMES and rate == 30.0


def test_missing_markers_are_blank_and_read_back_as_nan(tmp_path):
    track = _track()
    track[1, 2] = np.nan
    path = write_trc(tmp_path / "gap.trc", track, NAMES, 60.0, units="mm")
    row = path.read_text().split("\n")[6].split("\t")
    assert row[2 + 6:2 + 9] == ["", "", ""]
    positions, _, header = read_trc(path)
    assert np.isnan(positions[1, 2]).all() and np.isfinite(positions[1, :2]).all()
    assert header["Units"] == "mm"


def test_pose2sims_reference_file_reads(tmp_path):
    if not POSE2SIM_TRC.is_file():
        pytest.skip("the shared Pose2Sim data is not here")
    positions, names, header = read_trc(POSE2SIM_TRC)
    assert positions.shape == (100, 21, 3) and names[:2] == ("RHip", "RKnee")
    assert header["DataRate"] == 60.0


@pytest.mark.parametrize(("track", "names", "rate", "units", "message"), [
    (np.zeros((4, 3)), NAMES, 60.0, "m", "must be \\(time, markers, 3\\)"),
    (np.zeros((4, 2, 3)), NAMES, 60.0, "m", "3 names for 2 markers"),
    (np.zeros((4, 3, 3)), ("a", "b\tc", "d"), 60.0, "m", "without tabs"),
    (np.full((4, 3, 3), np.inf), NAMES, 60.0, "m", "infinite"),
    (np.zeros((4, 3, 3)), NAMES, 0.0, "m", "rate must be positive"),
    (np.zeros((4, 3, 3)), NAMES, 60.0, "cm", "units must be"),
])
def test_bad_tracks_are_refused_in_one_line_and_nothing_is_written(tmp_path, track, names, rate,
                                                                   units, message):
    with pytest.raises(TrcFileError, match=message) as error:
        write_trc(tmp_path / "bad.trc", track, names, rate, units)
    assert "\n" not in str(error.value) and not list(tmp_path.iterdir())
