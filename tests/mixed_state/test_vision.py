"""Silhouette features, per-posture part hypotheses and the nearest-point map, on drawn
silhouettes."""

import numpy as np
import pytest

from jaxtrack.priors.postures import POSTURE_NAMES
from jaxtrack.vision.histograms import (
    FRAME_EMPTY,
    FRAME_FULL,
    FRAME_OK,
    projection_histograms,
    silhouette_features,
)
from jaxtrack.vision.parts import nearest_silhouette_points, part_hypotheses, posture_hypotheses

from ._figures import HEAD_RADIUS, draw

pytest.importorskip("cv2")


def test_histograms_of_a_rectangle_and_an_l_shape():
    mask = np.zeros((60, 50), bool)
    mask[10:50, 20:30] = True  # 40 high, 10 wide: full in every bin, even with 16 bins > 10 px
    features = projection_histograms(mask, num_bins=16)
    np.testing.assert_allclose(features[:32], 1.0)
    np.testing.assert_allclose(features[32], np.log(40 / 10))
    # an L: a 40 x 8 column and a 8 x 32 foot; 4 bins over a 40 x 40 box
    mask = np.zeros((60, 60), bool)
    mask[10:50, 10:18] = True
    mask[42:50, 10:50] = True
    features = projection_histograms(mask, num_bins=4)
    # columns 0-9 hold 40 + ... : bin 0 (cols 0-9) = 8 cols x 40 + 2 cols x 8; others 10 x 8
    np.testing.assert_allclose(features[:4], [(8 * 40 + 2 * 8) / 400, 0.2, 0.2, 0.2])
    # rows 0-29 hold 8 per row; rows 30-31 8; rows 32-39 40 per row
    np.testing.assert_allclose(features[4:8], [0.2, 0.2, 0.2, (2 * 8 + 8 * 40) / 400])
    assert features[8] == 0.0


def test_empty_and_full_frames_are_reported_not_nan():
    masks = np.zeros((3, 40, 40), bool)
    masks[1, 5:30, 10:20] = True
    masks[2] = True
    features, status = silhouette_features(masks, num_bins=8)
    assert status.tolist() == [FRAME_EMPTY, FRAME_OK, FRAME_FULL]
    assert np.all(np.isfinite(features)) and np.all(features[[0, 2]] == 0)
    hypotheses = part_hypotheses(masks, status)
    assert np.all(np.isfinite(hypotheses))
    with pytest.raises(ValueError, match="no foreground"):
        projection_histograms(masks[0])


def _pair_errors(estimate, truth):
    """Distances per part, hands and feet under the better left/right assignment."""
    out = [np.linalg.norm(estimate[0] - truth[0])]
    for pair in ((1, 2), (3, 4)):
        straight = np.linalg.norm(estimate[list(pair)] - truth[list(pair)], axis=1)
        crossed = np.linalg.norm(estimate[list(pair)] - truth[list(pair[::-1])], axis=1)
        out.extend(straight if straight.sum() <= crossed.sum() else crossed)
    return np.array(out)


@pytest.mark.parametrize("name, mirror, posture, feet_tolerance", [
    ("standing", False, "standing", 5), ("standing", True, "standing", 5),
    ("sitting", False, "sitting", 5), ("crawling_bending", False, "crawling_bending", 22),
    ("crawling_bending", True, "crawling_bending", 22), ("lying_left", False, "lying_left", 5),
    ("lying_left", True, "lying_right", 5), ("crouching", False, "crawling_bending", 5)])
def test_each_postures_heuristics_find_the_drawn_extremes(name, mirror, posture, feet_tolerance):
    mask, truth = draw(name, mirror=mirror)
    estimate = posture_hypotheses(mask)[POSTURE_NAMES.index(posture)]
    errors = _pair_errors(estimate, truth)
    # the head's extreme point is a radius from its centre; hands and feet end half a line out
    assert errors[0] <= HEAD_RADIUS + 1.5, errors
    assert np.all(errors[1:3] <= 5), errors
    assert np.all(errors[3:] <= feet_tolerance), errors
    assert np.all(mask[np.round(estimate[:, 1]).astype(int), np.round(estimate[:, 0]).astype(int)])


def test_the_wrong_posture_misplaces_the_parts():
    mask, truth = draw("standing")
    lying = posture_hypotheses(mask)[POSTURE_NAMES.index("lying_left")]
    assert _pair_errors(lying, truth)[0] > 20


def test_nearest_points_against_brute_force():
    rng = np.random.default_rng(0)
    mask = rng.random((23, 31)) < 0.05
    nearest = nearest_silhouette_points(mask).astype(float)
    ys, xs = np.nonzero(mask)
    grid_y, grid_x = np.mgrid[:23, :31]
    brute = np.sqrt((grid_x[..., None] - xs) ** 2 + (grid_y[..., None] - ys) ** 2).min(axis=-1)
    found = np.hypot(nearest[..., 0] - grid_x, nearest[..., 1] - grid_y)
    np.testing.assert_allclose(found, brute)
    assert np.all(mask[nearest[..., 1].astype(int), nearest[..., 0].astype(int)])
