"""Silhouette contours: count, even spacing, start point and orientation on OpenCV drawings."""

import cv2
import numpy as np
import pytest

import jaxtrack.vision.contours as contours_module
from jaxtrack.vision.contours import resample_closed_curve, signed_area, silhouette_contour


def ellipse_mask(centre=(150, 100), axes=(60, 40), angle=20.0, shape=(200, 300)):
    mask = np.zeros(shape, np.uint8)
    cv2.ellipse(mask, centre, axes, angle, 0, 360, 255, thickness=-1)
    return mask


def test_ellipse_contour_is_evenly_spaced_from_the_top_clockwise():
    mask = ellipse_mask()
    points = silhouette_contour(mask, num_points=100)
    assert points.shape == (100, 2) and points.dtype == np.float64
    boundary = np.argwhere(mask > 0)
    assert points[0, 1] == boundary[:, 0].min()  # starts on the top-most row
    assert signed_area(points) > 0  # clockwise on screen
    chords = np.linalg.norm(np.diff(np.vstack([points, points[:1]]), axis=0), axis=1)
    assert chords.std() / chords.mean() < 0.05
    # the enclosed area is close to the drawn ellipse's π·a·b (boundary through pixel centres)
    assert abs(signed_area(points) - np.pi * 60 * 40) / (np.pi * 60 * 40) < 0.05
    # every point is on the mask's boundary: within a pixel of a foreground pixel
    assert np.all(mask[np.round(points[:, 1]).astype(int), np.round(points[:, 0]).astype(int)])


def test_rectangle_contour_visits_boundary_pixels_in_order():
    mask = np.zeros((80, 80), bool)
    mask[20:60, 10:50] = True  # pixel centres x 10..49, y 20..59: perimeter 4·39
    points = silhouette_contour(mask, num_points=4 * 39)
    np.testing.assert_allclose(points[0], [10, 20])
    np.testing.assert_allclose(points[1], [11, 20])  # rightwards from the top-left: clockwise
    np.testing.assert_allclose(points[39], [49, 20])
    np.testing.assert_allclose(points[78], [49, 59])
    np.testing.assert_allclose(points[117], [10, 59])
    np.testing.assert_allclose(points, np.round(points), atol=1e-9)


def test_largest_blob_is_chosen_and_translation_is_exact():
    mask = ellipse_mask()
    cv2.circle(mask, (30, 30), 10, 255, thickness=-1)
    points = silhouette_contour(mask, num_points=50)
    assert points[:, 0].min() > 80  # the ellipse, not the small disc at x ≈ 30
    shifted = np.roll(mask, (7, -5), axis=(0, 1))
    np.testing.assert_allclose(silhouette_contour(shifted, 50), points + [-5, 7], atol=1e-9)


def test_resample_closed_curve_spacing():
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    points = resample_closed_curve(square, 8)
    np.testing.assert_allclose(points, [[0, 0], [2, 0], [4, 0], [4, 2], [4, 4], [2, 4], [0, 4],
                                        [0, 2]])


def test_errors_and_lazy_opencv():
    with pytest.raises(ValueError, match="empty"):
        silhouette_contour(np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError, match="height, width"):
        silhouette_contour(np.ones((4, 4, 3), np.uint8))
    assert "cv2" not in vars(contours_module)  # imported inside the function only
