"""Silhouettes and their projection histograms: the posture features of the extended Ghost system.

Kwatra, Bobick & Johnson (2002, §3.1) classify posture from a silhouette's vertical and
horizontal projection histograms (Haritaoglu et al.'s Ghost). Over the silhouette's bounding box
of ``h × w`` pixels, with ``B`` bins per axis:

    vertical_j   = (foreground pixels in column bin j) / (h · w / B)     j = 0 … B−1
    horizontal_k = (foreground pixels in row bin k)    / (w · h / B)     k = 0 … B−1

so each bin holds the fraction of its strip of the box that is foreground (in [0, 1], whatever
the person's size in the image). Normalising over the box removes the box's shape, which is the
plainest cue between standing and lying, so the feature vector ends with ``log(h / w)``: it has
``2 B + 1`` entries. Bins split columns (rows) fractionally, so a box narrower than ``B`` pixels
still gives ``B`` well-defined bins.

A frame whose silhouette is empty, or covers nearly the whole image (a lighting change or a
moved camera), has no posture to read: :func:`silhouette_features` reports it in a per-frame
status and returns finite zeros, never NaN. See ``docs/mixed-state.md``.
"""

from __future__ import annotations

import numpy as np

from jaxtrack.vision.foreground import foreground_mask

__all__ = ["FRAME_EMPTY", "FRAME_FULL", "FRAME_OK", "STATUS_NAMES", "bounding_box",
           "feature_size", "projection_histograms", "silhouette_features", "silhouettes"]

FRAME_OK, FRAME_EMPTY, FRAME_FULL = 0, 1, 2
STATUS_NAMES = ("ok", "empty silhouette", "silhouette fills the frame")
FULL_FRACTION = 0.9
"""A silhouette covering more than this fraction of the image is reported as ``FRAME_FULL``."""


def feature_size(num_bins: int) -> int:
    """Length of the feature vector for ``num_bins`` bins per axis (``2 B + 1``)."""
    return 2 * num_bins + 1


def _check_mask(mask: np.ndarray, name: str = "mask") -> np.ndarray:
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.dtype != np.bool_:
        raise ValueError(f"{name} must be a (height, width) bool array, got shape {mask.shape} "
                         f"dtype {mask.dtype}")
    return mask


def bounding_box(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` inclusive pixel bounds of the foreground, None if it is empty."""
    mask = _check_mask(mask)
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    columns = np.flatnonzero(mask.any(axis=0))
    return int(columns[0]), int(rows[0]), int(columns[-1]), int(rows[-1])


def _binned(profile: np.ndarray, num_bins: int) -> np.ndarray:
    """Sums of ``profile`` over ``num_bins`` equal fractional bins of its length."""
    cumulative = np.concatenate([[0.0], np.cumsum(profile, dtype=np.float64)])
    edges = np.linspace(0.0, profile.size, num_bins + 1)
    return np.diff(np.interp(edges, np.arange(profile.size + 1), cumulative))


def projection_histograms(mask: np.ndarray, num_bins: int = 16) -> np.ndarray:
    """The ``(2 B + 1,)`` features of a non-empty silhouette: vertical and horizontal projection
    fill fractions over its bounding box, then ``log(height / width)`` of the box (module doc).

    Raises:
        ValueError: ``mask`` is not a 2-D bool array, is empty, or ``num_bins < 1``.
    """
    if num_bins < 1:
        raise ValueError(f"num_bins must be at least 1, got {num_bins}")
    box = bounding_box(mask)
    if box is None:
        raise ValueError("mask has no foreground pixel: an empty silhouette has no histograms "
                         "(silhouette_features reports such frames as FRAME_EMPTY)")
    x0, y0, x1, y1 = box
    crop = mask[y0:y1 + 1, x0:x1 + 1].astype(np.float64)
    height, width = crop.shape
    vertical = _binned(crop.sum(axis=0), num_bins) / (height * width / num_bins)
    horizontal = _binned(crop.sum(axis=1), num_bins) / (height * width / num_bins)
    return np.concatenate([vertical, horizontal, [np.log(height / width)]])


def silhouette_features(masks: np.ndarray, num_bins: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Features and status of every frame.

    Args:
        masks: ``(time, height, width)`` bool silhouettes.
        num_bins: bins per axis.

    Returns:
        ``features (time, 2 B + 1)`` float64 (zeros where the status is not ``FRAME_OK``) and
        ``status (time,)`` int32 (``FRAME_OK``, ``FRAME_EMPTY`` or ``FRAME_FULL``).
    """
    masks = np.asarray(masks)
    if masks.ndim != 3 or masks.dtype != np.bool_:
        raise ValueError(f"masks must be (time, height, width) bool, got shape {masks.shape} "
                         f"dtype {masks.dtype}")
    features = np.zeros((len(masks), feature_size(num_bins)))
    status = np.full(len(masks), FRAME_OK, dtype=np.int32)
    for index, mask in enumerate(masks):
        fraction = mask.mean() if mask.size else 0.0
        if fraction == 0.0:
            status[index] = FRAME_EMPTY
        elif fraction > FULL_FRACTION:
            status[index] = FRAME_FULL
        else:
            features[index] = projection_histograms(mask, num_bins)
    return features, status


def silhouettes(frames: np.ndarray, background: np.ndarray, *, threshold: int = 30,
                smoothing: int = 5) -> np.ndarray:
    """Background subtraction of every frame (:func:`jaxtrack.vision.foreground.foreground_mask`),
    keeping the largest connected blob (the person; speckle and small shadows dropped).

    Args:
        frames: ``(time, height, width, 3)`` uint8 RGB.
        background: ``(height, width, 3)`` uint8 RGB empty scene (or a median background).

    Returns:
        ``(time, height, width)`` bool.
    """
    import cv2

    frames = np.asarray(frames)
    if frames.ndim != 4:
        raise ValueError(f"frames must be (time, height, width, 3) uint8 RGB, got shape "
                         f"{frames.shape}")
    masks = np.zeros(frames.shape[:3], dtype=bool)
    for index, frame in enumerate(frames):
        mask = foreground_mask(frame, background, threshold=threshold, smoothing=smoothing)
        count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), 8)
        if count > 1:
            largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
            masks[index] = labels == largest
    return masks
