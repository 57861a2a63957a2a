"""``python -m benchmarks.mixed_state_evaluation``: its refusals and its posture error (the
benchmark itself renders and tracks for minutes, so it is a script, not a test)."""

import numpy as np
import pytest

from benchmarks import mixed_state_evaluation as evaluation


@pytest.mark.parametrize("argv, message", [
    (["--cutoff", "0"], "--cutoff values must be finite and above 0, got 0"),
    (["--regularisation", "0.05", "-1"], "--regularisation values must be finite and above 0"),
    (["--redetect", "1.5"], "--redetect values must be finite and in [0, 1], got 1.5"),
    (["--cutoff", "nan"], "--cutoff values must be finite"),
    (["--frames", "1"], "--frames must be at least 2, got 1"),
    (["--particles", "0"], "--particles must be at least 1, got 0"),
    (["--pose2sim-cameras", "4"], "--pose2sim-cameras must be distinct indices 0-3"),
    (["--pose2sim-cameras", "1", "1"], "--pose2sim-cameras must be distinct indices 0-3")])
def test_bad_arguments_are_refused_in_one_line_before_any_work(argv, message, capsys):
    with pytest.raises(SystemExit):
        evaluation.main(argv)
    assert message in capsys.readouterr().err


def test_instantaneous_posture_error_counts_the_classifiers_mistakes():
    class Classifier:  # posture 0 when the first feature is negative, else 1
        def classify(self, features):
            return (np.asarray(features)[:, 0] >= 0).astype(int)

    features = np.array([[-1.0], [2.0], [3.0], [-4.0]])
    assert evaluation.instantaneous_posture_error(Classifier(), features,
                                                  np.array([0, 1, 0, 1])) == 0.5
