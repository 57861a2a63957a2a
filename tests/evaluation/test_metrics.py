"""Metrics: hand-computed errors, torso normalisation, fraction within ε, failures, summaries."""

import json

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.evaluation import (
    DEFAULT_EPSILONS,
    compare_methods,
    evaluate_track,
    marker_errors,
    summarise,
    torso_lengths,
)

NECK, PELVIS = UPPER_BODY_12.index("neck"), UPPER_BODY_12.index("pelvis")


def upright_truth(num_frames: int, torso: float | np.ndarray = 100.0) -> np.ndarray:
    """Integer-valued markers with the pelvis `torso` pixels below the neck in every frame."""
    torso = np.broadcast_to(np.asarray(torso, dtype=np.float64), (num_frames,))
    rng = np.random.default_rng(0)
    truth = rng.integers(0, 200, size=(num_frames, len(UPPER_BODY_12), 2)).astype(np.float64)
    truth[:, NECK] = (120.0, 50.0)
    truth[:, PELVIS, 0] = 120.0
    truth[:, PELVIS, 1] = 50.0 + torso
    return truth


def shifted(truth: np.ndarray, errors_px) -> np.ndarray:
    """Every marker moved right by the frame's error, so the mean error is exactly that."""
    predicted = truth.copy()
    predicted[..., 0] += np.asarray(errors_px, dtype=np.float64)[:, None]
    return predicted


def test_marker_errors_by_hand():
    truth = np.zeros((2, 2, 2))
    predicted = np.array([[[3.0, 4.0], [0.0, 0.0]], [[1.0, 0.0], [0.0, 2.0]]])
    np.testing.assert_allclose(marker_errors(predicted, truth), [2.5, 1.5])
    visible = np.array([[True, False], [False, True]])
    np.testing.assert_allclose(marker_errors(predicted, truth, visible), [5.0, 2.0])


def test_invisible_truth_may_be_missing_but_counted_truth_may_not():
    truth = np.zeros((1, 2, 2))
    truth[0, 1] = np.nan
    predicted = np.array([[[6.0, 8.0], [1.0, 1.0]]])
    np.testing.assert_allclose(marker_errors(predicted, truth, [[True, False]]), [10.0])
    with pytest.raises(ValueError, match="truth .*non-finite"):
        marker_errors(predicted, truth)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_prediction_raises_naming_predicted(bad):
    truth = upright_truth(5)
    predicted = truth.copy()
    predicted[3, 7, 1] = bad
    with pytest.raises(ValueError, match=r"predicted .*frame 3, marker 7"):
        marker_errors(predicted, truth)
    # even where the marker is not counted: a diverged tracker must not pass unnoticed
    visible = np.ones((5, len(UPPER_BODY_12)), bool)
    visible[3, 7] = False
    with pytest.raises(ValueError, match="predicted"):
        evaluate_track(predicted, truth, UPPER_BODY_12, visible=visible)


def test_shape_mismatches_raise_naming_the_argument():
    truth = upright_truth(4)
    with pytest.raises(ValueError, match="predicted has shape"):
        marker_errors(truth[:3], truth)
    with pytest.raises(ValueError, match=r"predicted must have shape \(time, markers, 2\)"):
        marker_errors(truth[..., :1], truth)
    with pytest.raises(ValueError, match="visible has shape"):
        marker_errors(truth, truth, np.ones((4, 3), bool))
    with pytest.raises(ValueError, match="no marker in 1 frame"):
        marker_errors(truth, truth, np.eye(4, len(UPPER_BODY_12), k=-1, dtype=bool))


def test_torso_lengths_and_missing_names():
    truth = upright_truth(3, torso=np.array([100.0, 50.0, 80.0]))
    truth[2, PELVIS] = truth[2, NECK] + (48.0, 64.0)  # 3-4-5 triangle, 80 px, leaning
    np.testing.assert_allclose(torso_lengths(truth, UPPER_BODY_12), [100.0, 50.0, 80.0])
    names = tuple("hip_centre" if n == "pelvis" else n for n in UPPER_BODY_12)
    with pytest.raises(ValueError, match=r"'neck' and 'pelvis'.*\['pelvis'\]"):
        torso_lengths(truth, names)
    with pytest.raises(ValueError, match="names 11"):
        torso_lengths(truth, UPPER_BODY_12[:-1])


def test_evaluate_track_exact_on_a_constructed_case():
    errors = [0, 4, 9, 14, 16, 24, 26, 49, 51, 60]
    truth = upright_truth(10)
    result = evaluate_track(shifted(truth, errors), truth, UPPER_BODY_12)
    assert result["num_frames"] == 10
    assert result["mean_error_px"] == pytest.approx(25.3)
    assert result["median_error_px"] == pytest.approx(20.0)
    assert result["mean_error_torso"] == pytest.approx(0.253)
    np.testing.assert_allclose(result["errors_px"], errors)
    np.testing.assert_allclose(result["errors_torso"], np.array(errors) / 100)
    expected = {"0.05": 0.2, "0.1": 0.3, "0.15": 0.4, "0.2": 0.5, "0.25": 0.6, "0.3": 0.7,
                "0.35": 0.7, "0.4": 0.7, "0.45": 0.7, "0.5": 0.8}
    assert result["fraction_within"] == pytest.approx(expected)
    assert list(result["fraction_within"]) == list(expected)  # keys in ε order, tidy strings
    assert result["fraction_within_15"] == pytest.approx(0.4)
    # above 25 % for frames 5..9 only: a run of 5 < 10, so no failure
    assert (result["failed"], result["failure_frame"], result["frames_tracked"]) == (False, None,
                                                                                     10)
    assert result["ms_per_frame"] is None and result["compile_seconds"] is None


def test_errors_are_normalised_by_each_frames_torso():
    torso = np.array([100.0, 200.0, 50.0])
    truth = upright_truth(3, torso)
    result = evaluate_track(shifted(truth, [20.0, 20.0, 20.0]), truth, UPPER_BODY_12,
                            epsilons=(0.1, 0.2))
    np.testing.assert_allclose(result["errors_torso"], [0.2, 0.1, 0.4])
    assert result["fraction_within"] == pytest.approx({"0.1": 1 / 3, "0.2": 2 / 3})


def test_fraction_within_is_monotone_in_epsilon():
    rng = np.random.default_rng(1)
    truth = upright_truth(200, torso=rng.uniform(40, 160, 200))
    predicted = truth + rng.normal(scale=15.0, size=truth.shape)
    epsilons = np.linspace(0.01, 1.0, 40)
    result = evaluate_track(predicted, truth, UPPER_BODY_12, epsilons=epsilons)
    curve = [result["fraction_within"][f"{e:g}"] for e in epsilons]
    assert np.all(np.diff(curve) >= 0)
    assert curve[0] < 0.5 < curve[-1]  # the noise makes the curve rise across the range


def run_of_bad_frames(num_frames: int, start: int, length: int) -> np.ndarray:
    errors = np.full(num_frames, 10.0)  # 10 % of the torso
    errors[start:start + length] = 30.0  # 30 % > 25 %
    return errors


def test_nine_bad_frames_do_not_fail_ten_do():
    truth = upright_truth(30)
    nine = evaluate_track(shifted(truth, run_of_bad_frames(30, 5, 9)), truth, UPPER_BODY_12)
    assert nine["failed"] is False and nine["failure_frame"] is None
    assert nine["frames_tracked"] == 30
    ten = evaluate_track(shifted(truth, run_of_bad_frames(30, 12, 10)), truth, UPPER_BODY_12)
    assert ten["failed"] is True and ten["failure_frame"] == 12
    assert ten["frames_tracked"] == 12 and ten["frames_tracked_fraction"] == pytest.approx(0.4)


def test_failure_is_the_first_long_run_and_the_threshold_is_strict():
    truth = upright_truth(40)
    errors = run_of_bad_frames(40, 2, 9)  # too short
    errors[15:27] = 30.0  # the first run of 10 or more: fails at 15
    errors[30:40] = 30.0
    result = evaluate_track(shifted(truth, errors), truth, UPPER_BODY_12)
    assert (result["failed"], result["failure_frame"], result["frames_tracked"]) == (True, 15, 15)
    at_threshold = evaluate_track(shifted(truth, np.full(40, 25.0)), truth, UPPER_BODY_12)
    assert at_threshold["failed"] is False  # exactly 25 % is not above 25 %
    custom = evaluate_track(shifted(truth, run_of_bad_frames(40, 3, 4)), truth, UPPER_BODY_12,
                            failure_threshold=0.2, failure_frames=4)
    assert custom["failure_frame"] == 3


def test_result_is_plain_json():
    truth = upright_truth(12)
    result = evaluate_track(shifted(truth, np.arange(12.0)), truth, UPPER_BODY_12,
                            seconds_per_frame=np.float32(0.0025), compile_seconds=1.5)

    def plain(value) -> bool:
        if isinstance(value, dict):
            return all(isinstance(k, str) and plain(v) for k, v in value.items())
        if isinstance(value, list):
            return all(plain(v) for v in value)
        return value is None or type(value) in (bool, int, float, str)

    assert plain(result)
    assert json.loads(json.dumps(result)) == result
    assert result["ms_per_frame"] == pytest.approx(2.5)
    assert result["compile_seconds"] == 1.5
    assert set(result["fraction_within"]) == {f"{e:g}" for e in DEFAULT_EPSILONS}


def test_unusable_truth_torso_and_bad_settings_raise():
    truth = upright_truth(4)
    degenerate = truth.copy()
    degenerate[2, PELVIS] = degenerate[2, NECK]
    with pytest.raises(ValueError, match=r"torso.*\[2\]"):
        evaluate_track(truth, degenerate, UPPER_BODY_12)
    with pytest.raises(ValueError, match="failure_frames"):
        evaluate_track(truth, truth, UPPER_BODY_12, failure_frames=0)
    with pytest.raises(ValueError, match="epsilons"):
        evaluate_track(truth, truth, UPPER_BODY_12, epsilons=())
    with pytest.raises(ValueError, match="seconds_per_frame"):
        evaluate_track(truth, truth, UPPER_BODY_12, seconds_per_frame=float("nan"))


def test_summarise_pools_frames_and_counts_sequences():
    short_truth, long_truth = upright_truth(10), upright_truth(30, torso=200.0)
    short = evaluate_track(shifted(short_truth, np.full(10, 40.0)), short_truth, UPPER_BODY_12,
                           seconds_per_frame=0.001)  # 40 % of torso: fails at frame 0
    long = evaluate_track(shifted(long_truth, np.full(30, 20.0)), long_truth, UPPER_BODY_12,
                          seconds_per_frame=0.003)  # 10 % of torso
    untimed = evaluate_track(shifted(long_truth, np.full(30, 20.0)), long_truth, UPPER_BODY_12)
    overall = summarise([short, long, untimed])
    assert overall["num_sequences"] == 3 and overall["num_frames"] == 70
    assert overall["mean_error_px"] == pytest.approx((10 * 40 + 60 * 20) / 70)
    assert overall["median_error_px"] == pytest.approx(20.0)
    assert overall["mean_error_torso"] == pytest.approx((10 * 0.4 + 60 * 0.1) / 70)
    assert overall["fraction_within"]["0.1"] == pytest.approx(60 / 70)
    assert overall["fraction_within"]["0.4"] == pytest.approx(1.0)
    assert overall["fraction_within_15"] == pytest.approx(60 / 70)
    assert overall["num_failed"] == 1 and overall["failure_rate"] == pytest.approx(1 / 3)
    assert overall["frames_tracked_fraction"] == pytest.approx((0 + 1 + 1) / 3)
    assert overall["ms_per_frame"] == pytest.approx(2.0)  # median of 1 and 3; None is skipped
    assert overall["compile_seconds"] is None
    assert json.loads(json.dumps(overall)) == overall


def test_summarise_refuses_mixed_epsilons_and_nothing():
    truth = upright_truth(5)
    with pytest.raises(ValueError, match="same epsilons"):
        summarise([evaluate_track(truth, truth, UPPER_BODY_12),
                   evaluate_track(truth, truth, UPPER_BODY_12, epsilons=(0.1,))])
    with pytest.raises(ValueError, match="at least one"):
        summarise([])


def test_compare_methods_table():
    table = compare_methods({
        "gplvm": {"mean_error_px": 12.5, "mean_error_torso": 0.125, "fraction_within_15": 0.8,
                  "failure_rate": 0.25, "ms_per_frame": 1.234},
        "bootstrap-baseline": {"mean_error_px": 30.0, "mean_error_torso": 0.3,
                               "fraction_within_15": 0.1, "failure_rate": 1.0,
                               "ms_per_frame": None},
    })
    header, rule, gplvm, baseline = table.splitlines()
    assert header.split()[0] == "method" and set(rule) == {"-", " "}
    # one word for a lost run everywhere (the demo defines it where it prints the table)
    assert "lost" in header.split() and "failure" not in header
    assert gplvm.split() == ["gplvm", "12.50", "12.5", "80.0%", "0.25", "1.23"]
    assert baseline.split() == ["bootstrap-baseline", "30.00", "30.0", "10.0%", "1.00", "n/a"]
    assert len({len(line) for line in (header, gplvm, baseline)}) == 1  # columns line up
    with pytest.raises(ValueError):
        compare_methods({})
