"""Table 1's scores: hands and feet under the best left/right assignment; no frame, no NaN."""

import numpy as np

from jaxtrack.experiments.mixed_state import part_squared_errors, score


def test_swapped_hands_and_feet_score_as_the_better_assignment():
    truth = np.array([[[10.0, 0.0], [0.0, 50.0], [40.0, 50.0], [5.0, 100.0], [35.0, 100.0]]])
    swapped = truth[:, [0, 2, 1, 4, 3]] + [[[0.0, 3.0]] * 5]
    np.testing.assert_allclose(part_squared_errors(swapped, truth), 9.0)


def test_a_sequence_without_a_valid_frame_scores_nothing_and_no_nan():
    truth = np.zeros((4, 5, 2))
    result = score(truth + 1.0, np.zeros(4, int), truth, np.zeros(4, int),
                   valid=np.zeros(4, bool))
    assert result["frames"] == 0 and result["mse"] is None and result["posture_error"] is None
    full = score(truth + 1.0, np.zeros(4, int), truth, np.ones(4, int))
    assert full["frames"] == 4 and full["mse"]["all"] == 2.0 and full["posture_error"] == 1.0
