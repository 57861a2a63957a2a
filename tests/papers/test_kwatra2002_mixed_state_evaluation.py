"""``python -m papers.kwatra2002.mixed_state_evaluation``: its refusals and its posture error (the
benchmark itself renders and tracks for minutes, so it is a script, not a test)."""

from pathlib import Path

import numpy as np
import pytest

from papers.kwatra2002 import mixed_state_evaluation as evaluation


@pytest.mark.parametrize("argv, message", [
    (["--cutoff", "0"], "--cutoff values must be finite and above 0, got 0"),
    (["--posture-models", "1,per-posture,-1,level"], "K must be >= 1 and RIDGE positive"),
    (["--posture-models", "2,shared,1,level"], "COVARIANCE must be one of per-posture, pooled"),
    (["--posture-models", "2,pooled,1"], "is not K,COVARIANCE,RIDGE,VIEWS"),
    (["--redetect", "1.5"], "--redetect values must be finite and in [0, 1], got 1.5"),
    (["--cutoff", "nan"], "--cutoff values must be finite"),
    (["--frames", "1"], "--frames must be at least 2, got 1"),
    (["--particles", "0"], "--particles must be at least 1, got 0"),
    (["--skip-validation", "--cutoff", "9", "25"], "--skip-validation scores one setting"),
    (["--pose2sim-cameras", "4"], "--pose2sim-cameras must be Pose2Sim camera indices 0-3, got 4"),
    (["--pose2sim-cameras", "1", "1"], "--pose2sim-cameras names a camera twice: 1 1")])
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


def test_posture_model_specs_read_back_and_the_default_is_the_librarys():
    from jaxtrack.experiments import mixed_state as ms

    spec = evaluation.posture_model_spec("2,pooled,1,level+pose2sim")
    assert spec == evaluation.CLASSIFIERS_CHOICE
    assert evaluation.posture_model_spec(evaluation.spec_text(spec)) == spec
    components, covariance, ridge, views = evaluation.default_spec()
    assert (components, covariance, ridge) == (ms.DEFAULT_COMPONENTS, ms.DEFAULT_COVARIANCE,
                                               ms.DEFAULT_REGULARISATION)
    assert evaluation.VIEWS[views] == tuple(ms.TRAINING_POSE2SIM_CAMERAS)
    assert evaluation.model_path(Path("r"), spec).name == (
        "mixed_state_posture_model_k2_pooled_ridge1_level+pose2sim.npz")


def test_intervals_draw_every_view_of_a_clip_together():
    """Two clips of two views each: the interval spans the two clips' pooled values, and a
    clip with no rendered view is refused by name."""
    def scored(mse, error, frames=10):
        return {"smoothed": {"mse": {"all": mse}, "posture_error": error, "frames": frames}}

    sequences = {"139_16_az90_clutter": scored(100.0, 0.1), "139_16_az0_clutter": scored(300.0,
                                                                                       0.3),
                 "131_01_az90_clutter": scored(1000.0, 0.5), "131_01_az0_clutter": scored(1000.0,
                                                                                        0.5)}
    intervals = evaluation.clip_intervals(sequences, ["cmu_posture_bvh/139_16", "cmu_bvh/131_01"],
                                          kinds=("smoothed",))["smoothed"]
    assert intervals["mse_all_95"] == pytest.approx([200.0, 1000.0])
    assert intervals["posture_error_95"] == pytest.approx([0.2, 0.5])
    with pytest.raises(ValueError, match="75_20"):
        evaluation.clip_intervals(sequences, ["cmu_posture_bvh/75_20"], kinds=("smoothed",))
