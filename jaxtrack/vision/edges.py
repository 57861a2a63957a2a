"""Edge distance maps: how far each pixel is from the nearest image edge (OpenCV, per frame).

A limb's outline stays an edge when the limb turns in depth, while its texture (what the NCC
templates of :mod:`jaxtrack.likelihoods.limbs` match) changes. The edge likelihood of
:mod:`jaxtrack.likelihoods.edges` reads these maps at the strips' borders.

    grey → Gaussian blur (σ = ``blur``) → Canny (``low``, ``high``) → distance to the nearest
    edge pixel (``cv2.distanceTransform``, L2, 5 × 5 mask)

The 5 × 5 mask is within ~2 % of the true Euclidean distance (the 3 × 3 mask's horizontal
steps count 0.955 px) at the same cost; the exact transform took ~1.4 ms more per frame.
About 2.5 ms per 640 × 480 frame on this 2-core CPU.
"""

from __future__ import annotations

import numpy as np

__all__ = ["edge_distance_maps", "edge_observations"]


def edge_distance_maps(frames: np.ndarray, *, low: float = 40.0, high: float = 120.0,
                       blur: float = 1.0) -> np.ndarray:
    """Distance in pixels from every pixel to the nearest Canny edge, for each frame.

    Args:
        frames: ``(time, height, width)`` grey frames, floats in [0, 1] (``to_grey``) or uint8.
        low, high: Canny's hysteresis thresholds on the 0–255 grey scale.
        blur: σ in pixels of the Gaussian blur before Canny (0: none).

    Returns:
        ``(time, height, width)`` float32. A frame without a single edge gets the image
        diagonal everywhere (as far as any pixel can be from an edge).
    """
    import cv2

    frames = np.asarray(frames)
    if frames.ndim != 3:
        raise ValueError(f"frames must be (time, height, width) grey images, got {frames.shape}")
    if not 0 <= low <= high:
        raise ValueError(f"need 0 <= low <= high, got low={low}, high={high}")
    if blur < 0:
        raise ValueError(f"blur must be a non-negative σ in pixels, got {blur}")
    if frames.dtype != np.uint8:
        if not np.all(np.isfinite(frames)):
            raise ValueError("frames hold non-finite values")
        frames = np.clip(np.rint(frames * 255.0), 0, 255).astype(np.uint8)
    diagonal = float(np.hypot(*frames.shape[1:]))
    maps = np.empty(frames.shape, np.float32)
    for index, frame in enumerate(frames):
        if blur > 0:
            frame = cv2.GaussianBlur(frame, (0, 0), blur)
        edges = cv2.Canny(frame, low, high)
        if not edges.any():
            maps[index] = diagonal
            continue
        maps[index] = cv2.distanceTransform(255 - edges, cv2.DIST_L2, 5)
    return maps


def edge_observations(frames: np.ndarray, **edge_options) -> np.ndarray:
    """``(time, 2, height, width)`` float32: each grey frame and its edge distance map, the
    observations of ``jaxtrack.likelihoods.EdgeLimbTemplates`` (``likelihood="limbs+edges"``).

    Args:
        frames: ``(time, height, width)`` grey frames (floats in [0, 1], or uint8).
        edge_options: ``low``, ``high``, ``blur`` of :func:`edge_distance_maps`.
    """
    frames = np.asarray(frames)
    distances = edge_distance_maps(frames, **edge_options)
    grey = frames.astype(np.float32) / (255.0 if frames.dtype == np.uint8 else 1.0)
    return np.stack([grey, distances], axis=1)
