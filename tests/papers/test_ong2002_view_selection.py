"""``python -m papers.ong2002.view_selection``: its rules, their errors against the oracle and the
worst view, the predictors' correlations and the table (the benchmark itself tracks five clips
in four views, minutes on 2 cores, so it is not a test)."""

import numpy as np
import pytest

from papers.ong2002 import view_selection as vs


def _result():
    # view 1 is always the better skeleton; its fitness says so except in frame 2, and the
    # ambiguity says the opposite every frame
    errors = np.array([[0.3, 0.1], [0.3, 0.1], [0.3, 0.1], [0.3, 0.1]])
    log_fitness = np.array([[-2.0, -1.0], [-2.0, -1.0], [-0.5, -1.0], [-2.0, -1.0]])
    ambiguity = np.array([[0.1, 1.0]] * 4)
    # the particles' skeleton spread says so except in frame 3
    spread = np.array([[0.2, 0.05]] * 3 + [[0.05, 0.2]])
    found = np.ones((4, 2), bool)
    # skeletons in the world's axes: view 0 is 0.3 m off along x, view 1 0.1 m the other
    # way, so the two agree with each other equally and their mean is 0.1 m off
    truth = np.stack([_skeleton()] * 4)
    skeletons = np.stack([truth + [0.3, 0, 0], truth - [0.1, 0, 0]], axis=1)
    best = {"errors_m": errors.tolist(), "skeletons_world": skeletons.tolist()}
    return {"clip": "c", **best, "log_fitness": log_fitness.tolist(),
            "ambiguity": ambiguity.tolist(), "found": found.tolist(),
            "skeleton_spread_m": spread.tolist(),
            "single_view_m": errors.mean(axis=0).tolist(), "truth_world": truth.tolist(),
            "estimates": {"best": best, "mean": best}}


def test_each_rule_is_scored_against_the_oracle_and_the_worst_view():
    clip = vs.evaluate_clip(_result())
    rules = clip["rules"]
    assert rules["fitness"]["selected_m"] == pytest.approx((3 * 0.1 + 0.3) / 4)
    assert rules["fitness ±5"]["selected_m"] == pytest.approx(0.1)  # the dip is outvoted
    assert rules["ambiguity"]["selected_m"] == pytest.approx(0.3)
    assert rules["spread"]["selected_m"] == pytest.approx((3 * 0.1 + 0.3) / 4)
    assert rules["spread ±5"]["selected_m"] == pytest.approx(0.1)
    # frame 2: the spread outweighs the fitness's dip; frame 3: the fitness outweighs the
    # spread's
    assert rules["fitness/spread"]["selected_m"] == pytest.approx((3 * 0.1 + 0.3) / 4)
    assert rules["paper"]["oracle_m"] == pytest.approx(0.1)
    assert rules["paper"]["worst_m"] == pytest.approx(0.3)
    assert rules["best single view (hindsight)"]["selected_m"] == pytest.approx(0.1)
    assert rules["consensus"]["selected_m"] == pytest.approx(0.3)  # a tie: the first view
    assert rules["fused (not a selection)"]["selected_m"] == pytest.approx(0.1)
    assert rules["fused (not a selection)"]["oracle_m"] == pytest.approx(0.1)
    # across the two views, the error falls as the fitness rises (except in frame 2) and
    # rises as the ambiguity falls
    assert clip["error_vs_fitness"] == pytest.approx((3 * -1.0 + 1.0) / 4)
    assert clip["error_vs_ambiguity"] == pytest.approx(-1.0)
    assert clip["error_vs_spread"] == pytest.approx((3 * 1.0 - 1.0) / 4)
    summary = vs.summarise([clip, clip])
    assert summary["fitness ±5"]["below_worst"] == pytest.approx(1 - 0.1 / 0.3)
    assert summary["fitness ±5"]["above_oracle"] == pytest.approx(0.0)
    text = vs.table(summary, summary, "fitness ±5")
    assert "| **fitness ±5** (chosen) | 100 / 100 / 300 | 67 % | 0 % |" in text


def test_each_skeleton_estimate_is_scored_from_its_own_errors_and_skeletons():
    result = _result()
    mean = {"errors_m": (np.asarray(result["errors_m"])[:, ::-1]).tolist(),
            "skeletons_world": np.asarray(result["skeletons_world"])[:, ::-1].tolist()}
    result["estimates"]["mean"] = mean
    best, swapped = vs.evaluate_clip(result, "best"), vs.evaluate_clip(result, "mean")
    assert best["estimate"] == "best" and swapped["estimate"] == "mean"
    assert best["rules"]["fitness ±5"]["selected_m"] == pytest.approx(0.1)
    # the mean's errors are the views swapped: the fitness now points at the worse view
    assert swapped["rules"]["fitness ±5"]["selected_m"] == pytest.approx(0.3)
    assert swapped["single_view_m"] == pytest.approx([0.1, 0.3])


def test_too_few_frames_for_the_window_are_refused(capsys):
    with pytest.raises(SystemExit):
        vs.main(["--frames", "5"])
    assert "--frames must be at least 11" in capsys.readouterr().err


def test_consensus_prefers_the_views_that_agree_and_skips_those_that_did_not_observe():
    truth = np.zeros((2, 2, 3))
    # frame 0: views 0 and 1 agree, view 2 is 1 m away; frame 1: view 1 saw nothing
    skeletons = np.stack([truth, truth + [0.1, 0, 0], truth + [1.0, 0, 0]], axis=1)
    found = np.array([[True, True, True], [True, False, True]])
    distance = vs.consensus(skeletons, found)
    assert distance[0] == pytest.approx([0.55, 0.5, 0.95])  # medians of two distances each
    assert distance[1, 0] == pytest.approx(1.0) and distance[1, 2] == pytest.approx(1.0)
    assert np.isnan(distance[1, 1])
    scores = vs.consensus_scores(skeletons, found)
    assert np.argmax(scores[0]) == 1 and scores[1, 1] == -np.inf
    assert np.array_equal(vs.consensus(skeletons[:, :1], found[:, :1]), [[0.0], [0.0]])
    # the fused skeleton averages the views that observed: frame 0 (0 + 0.1 + 1) / 3 off,
    # frame 1 (0 + 1) / 2 off
    assert vs.fused_error(skeletons, truth, found) == pytest.approx((1.1 / 3 + 0.5) / 2)


def _skeleton(turn: float = 0.0) -> np.ndarray:
    """A 12-vertex upper body (``UPPER_BODY_12``) facing +z, turned by ``turn`` radians about
    the vertical (y) through the neck, neck-relative."""
    skeleton = np.zeros((12, 3))
    skeleton[0] = [0, 0.2, 0]  # head
    skeleton[2:4] = [[0, -0.2, 0], [0, -0.5, 0]]  # thorax, pelvis
    skeleton[4:8] = [[-0.2, 0, 0], [-0.3, -0.25, 0.1], [-0.3, -0.5, 0.2], [-0.1, -0.5, 0]]
    skeleton[8:12] = skeleton[4:8] * [-1, 1, 1]  # the left side mirrors the right
    c, s = np.cos(turn), np.sin(turn)
    return skeleton @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]).T


def test_facing_counts_skeletons_turned_away_and_what_turning_them_back_would_give():
    truth = np.stack([_skeleton()] * 4)
    # view 0 right every frame; view 1 turned half round in frames 0-2, a little in frame 3
    views = np.stack([truth, np.stack([_skeleton(np.pi)] * 3 + [_skeleton(0.3)])], axis=1)
    assert vs.torso_normal(truth)[0] == pytest.approx([0, 0, 1])
    result = vs.facing(views, truth)
    assert result["flipped"] == pytest.approx([0.0, 0.75])
    assert result["other_error_m"] == pytest.approx(
        np.linalg.norm(_skeleton(0.3) - truth[0], axis=-1).mean() / 5)  # 4 right + 1 off
    assert result["flipped_error_m"] > 0.1
    # turned back, the flipped frames are exact: only frame 3's small turn is left
    assert result["turned_single_view_m"][0] == pytest.approx(0.0)
    assert result["turned_single_view_m"][1] == pytest.approx(
        np.linalg.norm(_skeleton(0.3) - truth[0], axis=-1).mean() / 4)
    assert result["turned_oracle_m"] == pytest.approx(0.0)


def test_training_clips_of_an_evaluated_subject_are_refused(capsys):
    with pytest.raises(SystemExit):
        vs.main(["--train-clips", "bandai/dataset-2_walk_normal_001"])
    assert "subject bandai:dataset-2 is in both" in capsys.readouterr().err


def test_the_linear_bound_finds_the_signal_that_tells_the_views_apart():
    """Two views; only the spread (the third signal) says which is better, and a frame that
    view 1 did not observe is never given to it."""
    errors = np.array([[0.3, 0.1], [0.1, 0.3], [0.3, 0.1], [0.2, 0.4]])
    spread = np.array([[0.2, 0.05], [0.05, 0.2], [0.2, 0.05], [0.1, 0.01]])
    found = np.array([[True, True], [True, True], [True, True], [True, False]])
    result = {"found": found.tolist(), "ambiguity": [[0.5, 0.5]] * 4,
              "log_fitness": [[-1.0, -1.0]] * 4, "skeleton_spread_m": spread.tolist(),
              "estimates": {"best": {"skeletons_world": np.zeros((4, 2, 12, 3)).tolist()}}}
    features = vs.signals(result, "best", window=0)
    assert features.shape == (4, 2, 4) and features[3, 1, 0] == -np.inf
    assert features[0, :, 0] == pytest.approx([0.0, 0.0])  # equal fitness: centred to 0
    bound = vs.linear_bound([(features, errors)])
    assert bound["weights"][2] > 0  # the spread, counted as −log spread, selects
    assert bound["selected_m"] == pytest.approx(bound["oracle_m"]) == pytest.approx(0.125)
    assert bound["worst_m"] == pytest.approx((0.3 + 0.3 + 0.3 + 0.4) / 4)
    flipped = vs.scored_with([(features, errors)], [0.0, 0.0, -1.0, 0.0])
    assert flipped["selected_m"] == pytest.approx((0.3 + 0.3 + 0.3 + 0.2) / 4)


def test_an_unknown_training_clip_is_refused_in_one_line(capsys):
    with pytest.raises(SystemExit):
        vs.main(["--train-clips", "animateddrawings/no_such_clip"])
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "no data file for 'animateddrawings/no_such_clip'" in error
