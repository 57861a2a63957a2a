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
                       blur: float = 1.0, out: np.ndarray | None = None) -> np.ndarray:
    """Distance in pixels from every pixel to the nearest Canny edge, for each frame.

    Args:
        frames: ``(time, height, width)`` grey frames, floats in [0, 1] (``to_grey``) or uint8.
        low, high: Canny's hysteresis thresholds on the 0–255 grey scale.
        blur: σ in pixels of the Gaussian blur before Canny (0: none).
        out: optional ``(time, height, width)`` float32 array (each frame C-contiguous) to
            write the maps into.

    Returns:
        ``(time, height, width)`` float32 (``out`` when given). A frame without a single edge
        gets the image diagonal everywhere (as far as any pixel can be from an edge).
    """
    import cv2

    frames = np.asarray(frames)
    if frames.ndim != 3:
        raise ValueError(f"frames must be (time, height, width) grey images, got {frames.shape}")
    if not 0 <= low <= high:
        raise ValueError(f"need 0 <= low <= high, got low={low}, high={high}")
    if blur < 0:
        raise ValueError(f"blur must be a non-negative σ in pixels, got {blur}")
    if out is None:
        out = np.empty(frames.shape, np.float32)
    elif out.shape != frames.shape or out.dtype != np.float32:
        raise ValueError(f"out must be float32 of shape {frames.shape}, got {out.dtype} "
                         f"{out.shape}")
    if frames.dtype != np.uint8:
        if not np.all(np.isfinite(frames)):
            raise ValueError("frames hold non-finite values")
        if frames.min(initial=0.0) < 0:  # convertScaleAbs below would fold these up
            frames = np.maximum(frames, 0)
    diagonal = float(np.hypot(*frames.shape[1:]))
    for index, frame in enumerate(frames):
        if frame.dtype != np.uint8:
            # round(255 · grey) saturated to 0–255 in one pass (NumPy's clip/rint/astype took
            # ~50× longer per frame)
            frame = cv2.convertScaleAbs(np.ascontiguousarray(frame), alpha=255.0)
        if blur > 0:
            frame = cv2.GaussianBlur(frame, (0, 0), blur)
        edges = cv2.Canny(frame, low, high)
        if not edges.any():
            out[index] = diagonal
            continue
        cv2.distanceTransform(255 - edges, cv2.DIST_L2, 5, dst=out[index])
    return out


def edge_observations(frames: np.ndarray, *, out: np.ndarray | None = None,
                      **edge_options) -> np.ndarray:
    """``(time, 2, height, width)`` float32: each grey frame and its edge distance map, the
    observations of ``jaxtrack.likelihoods.EdgeLimbTemplates`` (``likelihood="limbs+edges"``).

    Args:
        frames: ``(time, height, width)`` grey frames (floats in [0, 1], or uint8).
        out: optional ``(time, 2, height, width)`` float32 array to write into.
        edge_options: ``low``, ``high``, ``blur`` of :func:`edge_distance_maps`.
    """
    frames = np.asarray(frames)
    if frames.ndim != 3:
        raise ValueError(f"frames must be (time, height, width) grey images, got {frames.shape}")
    shape = (frames.shape[0], 2, *frames.shape[1:])
    if out is None:
        out = np.empty(shape, np.float32)
    elif out.shape != shape or out.dtype != np.float32:
        raise ValueError(f"out must be float32 of shape {shape}, got {out.dtype} {out.shape}")
    edge_distance_maps(frames, out=out[:, 1], **edge_options)
    if frames.dtype == np.uint8:
        np.multiply(frames, np.float32(1 / 255), out=out[:, 0])
    else:
        out[:, 0] = frames
    return out
