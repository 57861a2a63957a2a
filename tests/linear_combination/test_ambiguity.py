"""Ambiguity (Ong & Gong 2002, eq. 10-14) and view selection: a view where two skeletons share one
silhouette is ambiguous, one where a silhouette has a single skeleton is not."""

import numpy as np
import pytest

from jaxtrack.body.hybrid import HybridLayout, make_hybrid
from jaxtrack.priors.linear_combinations import (
    nearest_ambiguity,
    select_views,
    training_ambiguity,
    view_scores,
)

LAYOUT = HybridLayout(num_contour=4, num_skeleton=2)


def _vector(contour_shift, skeleton_shift):
    contour = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float) + contour_shift
    hands = np.array([[-5.0, 5.0], [15.0, 5.0]]) + contour_shift
    skeleton = np.array([[0, 0, 0], [0, 0.3, 0]]) + np.array([skeleton_shift, 0, 0])
    return np.asarray(make_hybrid(contour, hands, np.zeros(2), skeleton))


def test_two_skeletons_sharing_one_silhouette_are_ambiguous():
    vectors = np.stack([
        _vector(0.0, 0.0), _vector(0.0, 0.4),      # one silhouette, two skeletons
        _vector(50.0, 0.0), _vector(50.5, 0.0),    # two near silhouettes, one skeleton
    ])
    ambiguity = training_ambiguity(vectors, LAYOUT, sigma=4.0, beta=100.0, threshold=0.05)
    assert ambiguity[0] == pytest.approx(1.0, abs=1e-6)  # G = 1, sigmoid(100 × 0.35) ≈ 1
    assert ambiguity[1] == pytest.approx(1.0, abs=1e-6)
    # every point moved by (0.5, 0.5): d_ob² = 0.5, G ≈ 0.98, but the skeletons agree:
    # sigmoid(−5) ≈ 0.0067
    assert ambiguity[2] == pytest.approx(np.exp(-0.5 / 32) / (1 + np.exp(5)), rel=1e-6)
    assert ambiguity[3] == pytest.approx(ambiguity[2])
    # eq. 14: a new vector takes its nearest training vector's ambiguity
    near = np.stack([_vector(0.3, 0.1), _vector(49.0, 0.2)])
    np.testing.assert_allclose(nearest_ambiguity(near, vectors, ambiguity, LAYOUT),
                               [ambiguity[0], ambiguity[2]])


def test_view_selection_trades_fitness_against_ambiguity():
    log_fitness = np.log([[0.5, 0.5, 0.9], [0.9, 0.1, 0.5]])
    ambiguity = np.array([[2.0, 0.1, 5.0], [0.1, 0.1, 0.1]])
    found = np.array([[True, True, True], [False, True, True]])
    chosen = select_views(log_fitness, ambiguity, found)
    # frame 0: 0.5/2.0, 0.5/0.1, 0.9/5.0 -> view 1; frame 1: view 0 unseen -> view 2
    np.testing.assert_array_equal(chosen, [1, 2])
    with pytest.raises(ValueError, match="both be"):
        select_views(log_fitness, ambiguity[:, :2])


def test_view_scores_weigh_fitness_and_ambiguity_and_average_over_a_window():
    log_fitness = np.array([[0.0, -1.0], [0.0, -1.0], [-5.0, -1.0], [0.0, -1.0], [0.0, 0.0]])
    ambiguity = np.array([[1.0, 0.01]] * 5)
    found = np.ones((5, 2), bool)
    found[4, 0] = False
    # fitness alone: view 0 except where its fitness dips (frame 2) and where it is unseen
    np.testing.assert_array_equal(
        select_views(log_fitness, ambiguity, found, ambiguity_weight=0.0), [0, 0, 1, 0, 1])
    # over ±1 frame the dip is outvoted: frame 2's view-0 mean is −5/3 < −1, frame 1's −5/3
    # too, but frame 3's (−5 + 0) / 2 = −2.5 (frame 4 unseen does not count): still view 1
    scores = view_scores(log_fitness, ambiguity, found, ambiguity_weight=0.0, window=1)
    np.testing.assert_allclose(scores[:, 0][:4], [0.0, -5 / 3, -5 / 3, -2.5])
    assert scores[4, 0] == -np.inf
    np.testing.assert_allclose(scores[:, 1], [-1.0, -1.0, -1.0, -2 / 3, -0.5])
    # ambiguity alone: the unambiguous view 1 wherever it is seen
    np.testing.assert_array_equal(
        select_views(log_fitness, ambiguity, found, fitness_weight=0.0), [1] * 5)
    # the default is the paper's: log f − log(a + 1e-3)
    np.testing.assert_allclose(view_scores(log_fitness, ambiguity)[0],
                               [-np.log(1.001), -1.0 - np.log(0.011)])
    for bad, message in (({"fitness_weight": 0.0, "ambiguity_weight": 0.0}, "not both 0"),
                         ({"window": -1}, "window"), ({"window": 1.5}, "window"),
                         ({"floor": 0.0}, "floor")):
        with pytest.raises(ValueError, match=message):
            view_scores(log_fitness, ambiguity, **bad)


def test_bad_vectors_are_refused():
    with pytest.raises(ValueError, match="hybrid vectors"):
        training_ambiguity(np.zeros((3, 5)), LAYOUT)
    vectors = np.stack([_vector(0.0, 0.0), _vector(1.0, 0.0)])
    vectors[1, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        training_ambiguity(vectors, LAYOUT)
