"""Silhouette contours as fixed-length point lists (a point-distribution model's shape vector).

Ong & Gong (2002, §5.1) describe the body outline by a fixed number of 2-D contour points; for
such a vector to be comparable across frames the points must be evenly spaced along the outline,
start at a reproducible place and run in one direction. :func:`silhouette_contour` does that for
the outer contour of the largest blob in a binary mask.

OpenCV is imported inside the functions, so importing this module needs no cv2.
"""

from __future__ import annotations

import numpy as np

__all__ = ["resample_closed_curve", "signed_area", "silhouette_contour"]


def signed_area(points: np.ndarray) -> float:
    """Shoelace area of a closed polygon ``(N, 2)`` in image coordinates (x right, y down).

    Positive when the points run clockwise as seen on screen.
    """
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def resample_closed_curve(points: np.ndarray, num_points: int) -> np.ndarray:
    """``num_points`` points evenly spaced by arc length along a closed polygon, from ``points[0]``.

    Args:
        points: ``(N, 2)`` polygon vertices in order (the closing edge back to ``points[0]`` is
            implied).
        num_points: how many points to return.

    Returns:
        ``(num_points, 2)`` float64; the first is ``points[0]``, consecutive points (and the last
        and the first) are one perimeter ÷ ``num_points`` apart along the polygon.
    """
    points = np.asarray(points, dtype=np.float64)
    closed = np.vstack([points, points[:1]])
    segment = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(segment)])
    perimeter = cumulative[-1]
    if perimeter <= 0:
        return np.repeat(points[:1], num_points, axis=0)
    targets = np.arange(num_points) * (perimeter / num_points)
    return np.column_stack(
        [np.interp(targets, cumulative, closed[:, 0]), np.interp(targets, cumulative, closed[:, 1])]
    )


def silhouette_contour(mask: np.ndarray, num_points: int = 100) -> np.ndarray:
    """The outer contour of the largest blob of a mask, as ``num_points`` evenly spaced points.

    The points start at the blob's top-most contour pixel (the left-most one if several share the
    top row) and run clockwise as seen on screen (in image coordinates x right, y down: rightwards
    from the top), so the same silhouette always gives the same vector.

    Args:
        mask: ``(height, width)`` bool or integer image; non-zero pixels are the silhouette.
        num_points: number of contour points (≥ 3).

    Returns:
        ``(num_points, 2)`` float64 ``(x, y)`` pixel coordinates of points on the contour through
        the boundary pixels' centres.

    Raises:
        ValueError: the mask is not 2-D, or it has no foreground pixel.
    """
    import cv2

    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"mask must be a (height, width) image, got shape {mask.shape}")
    if num_points < 3:
        raise ValueError(f"num_points must be at least 3, got {num_points}")
    binary = (mask != 0).astype(np.uint8)
    if not binary.any():
        raise ValueError("mask is empty (no foreground pixel): there is no silhouette contour")
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    # the largest blob by enclosed area; a 1-pixel-wide blob has area 0, so break ties by length
    largest = max(contours, key=lambda c: (cv2.contourArea(c), len(c)))
    points = largest[:, 0, :].astype(np.float64)
    if signed_area(points) < 0:
        points = points[::-1]
    top = np.lexsort((points[:, 0], points[:, 1]))[0]  # smallest y, then smallest x
    return resample_closed_curve(np.roll(points, -top, axis=0), num_points)
