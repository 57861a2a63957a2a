"""``python -m papers.tian2005.likelihood_at_truth``: its summary of where the truth outscores the
tracker's estimate, and its refusals (the benchmark itself tracks seven sequences and takes
minutes, so it is not a test)."""

import numpy as np
import pytest

from jaxtrack.vision.mediapipe import masks_or_exit
from papers.tian2005 import likelihood_at_truth as check


def _check(truth, estimate, static, estimate_error, static_error):
    return {"log_likelihood": {"truth": truth, "estimate": estimate, "static": static},
            "estimate_error_torso": estimate_error, "static_error_torso": static_error}


def test_only_frames_off_by_more_than_the_threshold_are_counted():
    row = check.summarise("s", "rendered", _check(
        truth=[-10.0, -10.0, -10.0, -10.0], estimate=[-5.0, -12.0, -20.0, -1.0],
        static=[-30.0, -30.0, -5.0, -30.0],
        estimate_error=[0.10, 0.30, 0.40, 0.50], static_error=[0.2, 0.2, 0.2, 0.05]))
    # frame 0's estimate is within 15 %: it outscores the truth but does not count
    assert row["estimate_off_frames"] == 3
    assert row["truth_beats_estimate"] == pytest.approx(2 / 3)
    assert row["median_margin_estimate"] == pytest.approx(2.0)  # median of −9, +2, +10
    assert row["static_off_frames"] == 3
    assert row["truth_beats_static"] == pytest.approx(2 / 3)
    assert row["estimate_error_torso"] == pytest.approx(np.mean([0.1, 0.3, 0.4, 0.5]))


def test_a_tracker_never_off_reports_no_share_rather_than_a_number():
    row = check.summarise("s", "rendered", _check(
        [-1.0, -1.0], [-2.0, -2.0], [-3.0, -3.0], [0.01, 0.02], [0.3, 0.3]))
    assert row["estimate_off_frames"] == 0
    assert row["truth_beats_estimate"] is None and row["median_margin_estimate"] is None
    text = check.table([row])
    assert "| s | rendered | 2 | 1.5 % | 0 | — | — | 2 | 100 % | +2.0 |" in text


@pytest.mark.parametrize("argv, message", [
    (["--frames", "1"], "--frames must be at least 2"),
    (["--no-rendered", "--views"], "nothing to check"),
    (["--likelihood", "markers", "--no-background"], "has none"),
    (["--likelihood", "limbs", "--masks", "mediapipe"], "--masks is about limbs+edges"),
    (["--likelihood", "markers", "--foreground-weight", "3"], "--foreground-weight is about"),
    (["--no-background", "--masks", "mediapipe"], "--masks gives it masks"),
    (["--foreground-weight", "-1"], "--foreground-weight must be a non-negative number"),
    (["--likelihood", "limbs", "--coverage-weight", "3"], "--coverage-weight is about"),
    (["--coverage-weight", "3"], "--coverage-weight: the coverage term reads the person's"),
])
def test_bad_arguments_are_refused_in_one_line(argv, message, capsys):
    with pytest.raises(SystemExit):
        check.main(argv)
    assert message in capsys.readouterr().err


def test_masks_without_mediapipe_stop_the_run_with_the_reason(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXTRACK_MEDIAPIPE_PYTHON", str(tmp_path / "no-python"))
    with pytest.raises(SystemExit, match="--masks mediapipe, cam01: no MediaPipe python"):
        masks_or_exit(np.zeros((2, 8, 8, 3), np.uint8), "cam01")
