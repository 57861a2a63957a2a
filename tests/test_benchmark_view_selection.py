"""``python -m benchmarks.view_selection``: its rules, their errors against the oracle and the
worst view, the predictors' correlations and the table (the benchmark itself tracks five clips
in four views, minutes on 2 cores, so it is not a test)."""

import numpy as np
import pytest

from benchmarks import view_selection as vs


def _result():
    # view 1 is always the better skeleton; its fitness says so except in frame 2, and the
    # ambiguity says the opposite every frame
    errors = np.array([[0.3, 0.1], [0.3, 0.1], [0.3, 0.1], [0.3, 0.1]])
    log_fitness = np.array([[-2.0, -1.0], [-2.0, -1.0], [-0.5, -1.0], [-2.0, -1.0]])
    ambiguity = np.array([[0.1, 1.0]] * 4)
    found = np.ones((4, 2), bool)
    return {"clip": "c", "errors_m": errors.tolist(), "log_fitness": log_fitness.tolist(),
            "ambiguity": ambiguity.tolist(), "found": found.tolist(),
            "single_view_m": errors.mean(axis=0).tolist()}


def test_each_rule_is_scored_against_the_oracle_and_the_worst_view():
    clip = vs.evaluate_clip(_result())
    rules = clip["rules"]
    assert rules["fitness"]["selected_m"] == pytest.approx((3 * 0.1 + 0.3) / 4)
    assert rules["fitness ±5"]["selected_m"] == pytest.approx(0.1)  # the dip is outvoted
    assert rules["ambiguity"]["selected_m"] == pytest.approx(0.3)
    assert rules["paper"]["oracle_m"] == pytest.approx(0.1)
    assert rules["paper"]["worst_m"] == pytest.approx(0.3)
    assert rules["best single view (hindsight)"]["selected_m"] == pytest.approx(0.1)
    # across the two views, the error falls as the fitness rises (except in frame 2) and
    # rises as the ambiguity falls
    assert clip["error_vs_fitness"] == pytest.approx((3 * -1.0 + 1.0) / 4)
    assert clip["error_vs_ambiguity"] == pytest.approx(-1.0)
    summary = vs.summarise([clip, clip])
    assert summary["fitness ±5"]["below_worst"] == pytest.approx(1 - 0.1 / 0.3)
    assert summary["fitness ±5"]["above_oracle"] == pytest.approx(0.0)
    text = vs.table(summary, summary, "fitness ±5")
    assert "| **fitness ±5** (chosen) | 100 / 100 / 300 | 67 % | 0 % |" in text


def test_too_few_frames_for_the_window_are_refused(capsys):
    with pytest.raises(SystemExit):
        vs.main(["--frames", "5"])
    assert "--frames must be at least 11" in capsys.readouterr().err
