"""Edge maps: how far each pixel is from the nearest image edge, and that edge's orientation
(OpenCV, per frame).

A limb's outline stays an edge when the limb turns in depth, while its texture (what the NCC
templates of :mod:`jaxtrack.likelihoods.limbs` match) changes. The edge likelihood of
:mod:`jaxtrack.likelihoods.edges` reads these maps at the strips' borders, and counts a border
point as on an edge only when the nearest edge runs along the limb (oriented chamfer matching):
in clutter, the nearest edge is often a background line across the limb.

    grey → Gaussian blur (σ = ``blur``) → Canny (``low``, ``high``) → for every pixel, the
    distance to the nearest edge pixel (``cv2.distanceTransformWithLabels``, L2, 5 × 5 mask)
    and the tangent direction of that edge pixel (Sobel gradient turned by 90°, in [0, π))

The 5 × 5 mask is near the exact Euclidean distance at the cost of the 3 × 3 one; the choice
and the maps' cost are measured in ``docs/likelihoods.md`` (section "Edge maps").
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["edge_distance_maps", "edge_observations"]


def _check_frames(frames: np.ndarray, low: float, high: float, blur: float) -> np.ndarray:
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
        if frames.min(initial=0.0) < 0:  # convertScaleAbs below would fold these up
            frames = np.maximum(frames, 0)
    return frames


def _check_out(out: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    if out is None:
        return np.empty(shape, np.float32)
    if out.shape != shape or out.dtype != np.float32:
        raise ValueError(f"out must be float32 of shape {shape}, got {out.dtype} {out.shape}")
    return out


def _edge_maps(frame: np.ndarray, low: float, high: float, blur: float,
               distance: np.ndarray, orientation: np.ndarray | None) -> None:
    """Write one frame's distance (and nearest-edge orientation) maps in place."""
    import cv2

    if frame.dtype != np.uint8:
        # round(255 · grey) saturated to 0–255 in one pass (NumPy's clip/rint/astype took
        # ~50× longer per frame)
        frame = cv2.convertScaleAbs(np.ascontiguousarray(frame), alpha=255.0)
    if blur > 0:
        frame = cv2.GaussianBlur(frame, (0, 0), blur)
    edges = cv2.Canny(frame, low, high)
    if not edges.any():
        distance[...] = np.hypot(*frame.shape)  # as far as any pixel can be from an edge
        if orientation is not None:
            orientation[...] = 0
        return
    if orientation is None:
        cv2.distanceTransform(255 - edges, cv2.DIST_L2, 5, dst=distance)
        return
    _, labels = cv2.distanceTransformWithLabels(255 - edges, cv2.DIST_L2, 5, dst=distance,
                                                labelType=cv2.DIST_LABEL_PIXEL)
    # labels number the edge pixels 1, 2, ... in raster order; each pixel holds its nearest's
    on_edge = edges.reshape(-1) != 0
    gx = cv2.Sobel(frame, cv2.CV_32F, 1, 0, ksize=3).reshape(-1)[on_edge]
    gy = cv2.Sobel(frame, cv2.CV_32F, 0, 1, ksize=3).reshape(-1)[on_edge]
    tangent = np.empty(gx.size + 1, np.float32)
    tangent[0] = 0
    tangent[1:] = np.mod(np.arctan2(gy, gx) + np.pi / 2, np.pi)
    np.take(tangent, labels, out=orientation)


def _for_each_frame(function, count: int, workers: int | None) -> None:
    """``function(index)`` for every frame, on ``workers`` threads (OpenCV releases the GIL, so
    frames are computed side by side; ``docs/likelihoods.md``, "Edge maps")."""
    workers = len(os.sched_getaffinity(0)) if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if workers == 1 or count < 2:
        for index in range(count):
            function(index)
        return
    with ThreadPoolExecutor(min(workers, count)) as pool:
        for _ in pool.map(function, range(count)):
            pass  # re-raises the first exception


def edge_distance_maps(frames: np.ndarray, *, low: float = 40.0, high: float = 120.0,
                       blur: float = 1.0, out: np.ndarray | None = None,
                       workers: int | None = None) -> np.ndarray:
    """Distance in pixels from every pixel to the nearest Canny edge, for each frame.

    Args:
        frames: ``(time, height, width)`` grey frames, floats in [0, 1] (``to_grey``) or uint8.
        low, high: Canny's hysteresis thresholds on the 0–255 grey scale.
        blur: σ in pixels of the Gaussian blur before Canny (0: none).
        out: optional ``(time, height, width)`` float32 array (each frame C-contiguous) to
            write the maps into.
        workers: threads, one frame each at a time (default: the cores this process may use).

    Returns:
        ``(time, height, width)`` float32 (``out`` when given). A frame without a single edge
        gets the image diagonal everywhere (as far as any pixel can be from an edge).
    """
    frames = _check_frames(frames, low, high, blur)
    out = _check_out(out, frames.shape)
    _for_each_frame(lambda index: _edge_maps(frames[index], low, high, blur, out[index], None),
                    len(frames), workers)
    return out


def edge_observations(frames: np.ndarray, *, out: np.ndarray | None = None, low: float = 40.0,
                      high: float = 120.0, blur: float = 1.0, workers: int | None = None,
                      masks: np.ndarray | None = None) -> np.ndarray:
    """``(time, 3, height, width)`` float32: each grey frame, its edge distance map and the
    tangent direction (radians in [0, π), image coordinates) of the nearest edge pixel: the
    image channels of ``jaxtrack.likelihoods.EdgeLimbTemplates`` (``likelihood="limbs+edges"``).
    With ``masks``, ``(time, 4, height, width)``: the person's mask (1 on the person, 0 off)
    as a fourth channel, which the likelihood's foreground term then reads frame by frame.
    A detector's keypoints travel beside these channels, not in them
    (:func:`jaxtrack.vision.image_observations`).

    Args:
        frames: ``(time, height, width)`` grey frames (floats in [0, 1], or uint8).
        out: optional ``(time, 3 or 4, height, width)`` float32 array to write into.
        low, high, blur, workers: as in :func:`edge_distance_maps`.
        masks: optional ``(time, height, width)`` bool person masks
            (:mod:`jaxtrack.vision.masks`).
    """
    frames = _check_frames(frames, low, high, blur)
    channels = 3
    if masks is not None:
        from jaxtrack.vision.masks import check_masks

        masks = check_masks(masks, frames.shape)
        channels = 4
    out = _check_out(out, (frames.shape[0], channels, *frames.shape[1:]))
    if masks is not None:
        out[:, 3] = masks
    _for_each_frame(lambda index: _edge_maps(frames[index], low, high, blur, out[index, 1],
                                             out[index, 2]), len(frames), workers)
    if frames.dtype == np.uint8:
        np.multiply(frames, np.float32(1 / 255), out=out[:, 0])
    else:
        out[:, 0] = frames
    return out
