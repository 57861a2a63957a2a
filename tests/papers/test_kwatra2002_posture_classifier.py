"""The posture-classifier benchmark's scoring on made-up features (the benchmark itself renders
clips and is a script, not a test): errors per true posture, leave-one-clip-out, and a clip
that alone shows a posture reported as unfit rather than raised."""

import numpy as np
import pytest

from jaxtrack.priors.postures import NUM_POSTURES, POSTURE_NAMES
from papers.kwatra2002 import posture_classifier as pc


def _clip(name, postures, rng, frames=30, shift=0.0):
    """Features around a mean per posture (well apart), labelled."""
    labels = np.repeat(np.asarray(postures), frames)
    means = 3.0 * np.eye(NUM_POSTURES, 33)
    return name, means[labels] + shift + 0.3 * rng.standard_normal((len(labels), 33)), labels


def test_errors_are_counted_overall_and_per_true_posture():
    rng = np.random.default_rng(0)
    training = [_clip("a", range(NUM_POSTURES), rng), _clip("b", range(NUM_POSTURES), rng)]
    model = pc.fit(training, 0.2)
    name, values, labels = _clip("c", [0, 2], rng)
    right = pc.posture_errors(model, [(name, values, labels)])
    assert right["error"] == 0.0 and right["frames"] == 60
    assert right["per_posture"]["standing"] == 0.0 and right["per_posture"]["sitting"] is None
    wrong = pc.posture_errors(model, [(name, values, np.where(labels == 0, 1, labels))])
    assert wrong["error"] == pytest.approx(0.5)
    assert wrong["per_posture"][POSTURE_NAMES[1]] == 1.0
    assert wrong["per_posture"][POSTURE_NAMES[2]] == 0.0


def test_leave_one_clip_out_holds_each_clip_out_and_reports_an_unfit_model():
    rng = np.random.default_rng(1)
    everyday = list(range(4))  # standing, sitting, crawling, lying left
    training = [_clip("a", everyday, rng), _clip("a", everyday, rng),  # two views of one clip
                _clip("b", everyday, rng), _clip("only_b", [*everyday, 4], rng)]
    rows = pc.leave_one_clip_out(training, 0.2)
    assert [row["held_out"] for row in rows] == ["a", "b", "only_b"]
    assert rows[0]["frames"] == 2 * 4 * 30 and rows[0]["error"] == 0.0
    # without the only clip that shows lying right, that posture has no training frame
    assert "lying_right" in rows[2]["unfit"] and "error" not in rows[2]
    pooled = pc.leave_one_clip_out(training, 0.2, "pooled")
    assert [row["covariance"] for row in pooled] == ["pooled"] * 3
    assert pooled[0]["error"] == 0.0 and "unfit" in pooled[2]


def test_bad_ridges_are_refused_in_one_line(capsys):
    with pytest.raises(SystemExit):
        pc.main(["--ridges", "0"])
    assert "--ridges must be positive numbers" in capsys.readouterr().err


def test_leave_one_clip_out_keeps_the_held_out_clips_other_views_out_of_training():
    rng = np.random.default_rng(2)
    everyday = list(range(NUM_POSTURES))
    training = [_clip("a", everyday, rng), _clip("b", everyday, rng)]
    # "a" through other cameras, shifted far: were they kept in training while "a" is held
    # out, the held-out frames would be fitted on a copy of themselves
    views_of_a = [_clip("a", [1] * NUM_POSTURES, rng, shift=100.0)]
    rows = pc.leave_one_clip_out(training, 0.2, always=views_of_a)
    assert rows[0]["held_out"] == "a" and rows[0]["error"] == 0.0
    # while "b" is held out, a's other views train: their far-off "sitting" frames pull the
    # sitting Gaussian away, and b's sitting frames are no longer called sitting
    assert rows[1]["per_posture"]["sitting"] == 1.0


def test_the_hmm_smoother_corrects_a_lone_misread_frame_but_not_a_stretch():
    """Two postures far apart and transitions that rarely switch: a single frame whose
    features look like the other posture is smoothed back, a long stretch is not."""
    from jaxtrack.priors.postures import PostureModel

    means = np.zeros((NUM_POSTURES, 1))
    means[1] = 4.0
    log_transition = np.log(np.full((NUM_POSTURES, NUM_POSTURES), 0.01 / 4)
                            + np.eye(NUM_POSTURES) * (0.99 - 0.01 / 4))
    model = PostureModel(means, np.ones((NUM_POSTURES, 1, 1)), np.zeros(NUM_POSTURES),
                         log_transition, np.log(np.full(NUM_POSTURES, 0.2)), 100.0)
    labels = np.zeros(40, int)
    lone = np.zeros((40, 1))
    lone[20] = 4.0  # one frame read as posture 1
    stretch = np.zeros((40, 1))
    stretch[10:30] = 4.0  # twenty frames read as posture 1
    assert pc.posture_errors(model, [("a", lone, labels)])["error"] == pytest.approx(1 / 40)
    assert pc.hmm_smoothed_error(model, [("a", lone, labels)]) == 0.0
    assert pc.hmm_smoothed_error(model, [("a", stretch, labels)]) == pytest.approx(0.5)
