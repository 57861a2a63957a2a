"""Foreground from a static camera: a median background and a cleaned difference mask.

A person who moves during a clip is absent from most frames at any one pixel, so the per-pixel
median of frames spread over the clip is the empty scene; the foreground of a frame is where it
differs from that background by more than a threshold (the largest colour channel's absolute
difference), opened and closed morphologically to drop speckle and fill small holes. This is
the template-free cue the automatic initialisation scores candidate poses against
(``jaxtrack.trackers.autoinit``). Parts of a person that stay still for most of the clip become
background: supply an empty-scene ``background`` image when there is one.

OpenCV is imported inside the functions, so importing this module needs no cv2. Its use on a
real video: ``docs/real-video.md``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["foreground_mask", "head_boxes", "largest_component", "median_background",
           "median_grey_background"]


def _check_rgb(images: np.ndarray, name: str, ndim: int) -> np.ndarray:
    images = np.asarray(images)
    if images.ndim != ndim or images.shape[-1] != 3 or images.dtype != np.uint8:
        kind = "(time, height, width, 3)" if ndim == 4 else "(height, width, 3)"
        raise ValueError(f"{name} must be {kind} uint8 RGB, got shape {images.shape} "
                         f"dtype {images.dtype}")
    return images


def _evenly_spaced(frames: np.ndarray, max_samples: int) -> np.ndarray:
    """Up to ``max_samples`` of ``frames`` spread evenly over the clip, first and last included."""
    picks = np.unique(np.linspace(0, len(frames) - 1, min(max_samples, len(frames))).round())
    return frames[picks.astype(int)]


def median_background(frames: np.ndarray, *, max_samples: int = 64) -> np.ndarray:
    """The per-pixel median of up to ``max_samples`` frames spread evenly over the clip.

    Args:
        frames: ``(time, height, width, 3)`` uint8 RGB frames of a static camera.
        max_samples: frames used (evenly spaced); the median's cost grows with it.

    Returns:
        ``(height, width, 3)`` uint8 RGB background.

    Raises:
        ValueError: ``frames`` is not uint8 RGB video, or holds fewer than 3 frames (a median of
            one or two frames is the frames themselves, so the person would be background).
    """
    frames = _check_rgb(frames, "frames", 4)
    if len(frames) < 3:
        raise ValueError(f"a median background needs at least 3 frames, got {len(frames)}")
    return np.median(_evenly_spaced(frames, max_samples), axis=0).round().astype(np.uint8)


def median_grey_background(frames: np.ndarray, *, max_samples: int = 64) -> np.ndarray:
    """The per-pixel median of up to ``max_samples`` grey frames spread evenly over the clip:
    the background the limb-edge likelihood's foreground term compares frames with
    (``jaxtrack.likelihoods.make_edge_limb_templates(..., background=...)``).

    Args:
        frames: ``(time, height, width)`` grey frames of a static camera (floats, as the
            trackers take them, or uint8), at least 3.
        max_samples: frames used (evenly spaced).

    Returns:
        ``(height, width)`` float32 background on the frames' grey scale.
    """
    frames = np.asarray(frames)
    if frames.ndim != 3 or not (np.issubdtype(frames.dtype, np.floating)
                                or frames.dtype == np.uint8):
        raise ValueError(f"frames must be (time, height, width) grey images, got shape "
                         f"{frames.shape} dtype {frames.dtype}")
    if len(frames) < 3:
        raise ValueError(f"a median background needs at least 3 frames, got {len(frames)}")
    if int(max_samples) != max_samples or max_samples < 3:
        raise ValueError(f"max_samples must be an integer of at least 3, got {max_samples}")
    background = np.median(_evenly_spaced(frames, max_samples), axis=0).astype(np.float32)
    if not np.all(np.isfinite(background)):
        raise ValueError("frames hold non-finite values")
    return background


def foreground_mask(frame: np.ndarray, background: np.ndarray, *, threshold: int = 30,
                    smoothing: int = 5, backend: str = "opencv") -> np.ndarray:
    """Where ``frame`` differs from ``background``: a cleaned boolean mask.

    Args:
        frame, background: ``(height, width, 3)`` uint8 RGB images of the same size.
        threshold: grey levels (0–255) the largest channel difference must exceed.
        smoothing: size in pixels of the square opening/closing element (odd, ≥ 1; 1 disables).
        backend: ``"opencv"``, or ``"kornia"`` for torch tensors (any device; the result is then
            a ``jax.Array`` shared through DLPack: ``jaxtrack.vision._kornia``).

    Returns:
        ``(height, width)`` bool mask, True on the foreground.
    """
    from jaxtrack.vision._kornia import check_backend

    check_backend(backend)
    if backend == "kornia":
        from jaxtrack.vision._kornia import _as_tensor, foreground_masks

        frame = _as_tensor(frame, "frame", 3)
        return foreground_masks(frame[None], background, threshold=threshold,
                                smoothing=smoothing)[0]
    import cv2

    frame = _check_rgb(frame, "frame", 3)
    background = _check_rgb(background, "background", 3)
    if frame.shape != background.shape:
        raise ValueError(f"frame {frame.shape} and background {background.shape} differ in size")
    if not 0 <= threshold < 255:
        raise ValueError(f"threshold must be in [0, 255), got {threshold}")
    difference = cv2.absdiff(frame, background).max(axis=-1)
    mask = (difference > threshold).astype(np.uint8)
    if smoothing > 1:
        element = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (smoothing, smoothing))
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, element)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, element)
    return mask.astype(bool)


def head_boxes(mask: np.ndarray, *, max_people: int = 3, min_area: float = 0.005) -> np.ndarray:
    """Head boxes guessed from the top of the largest foreground blobs (people standing up).

    For each connected blob (after closing gaps of 2 % of the image height) covering at least
    ``min_area`` of the image, largest first, the head is taken at its top: centred on the
    blob's pixels in its top 8 %, with a size of 9 % of the blob's height (a standing adult is
    about 7.5 heads tall; a face box is about two thirds of a head). Arms raised above the head
    move the guess up, which a pose search has to absorb.

    Args:
        mask: ``(height, width)`` bool foreground.

    Returns:
        ``(boxes, 4)`` int64 ``(x, y, width, height)``, largest blob first.
    """
    import cv2

    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"mask must be (height, width), got shape {mask.shape}")
    # close gaps first (a shirt the colour of the wall splits a person into pieces)
    size = max(5, int(0.02 * mask.shape[0]) | 1)
    element = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    closed = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, element)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(closed, 8)
    order = np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1
    boxes = []
    for label in order[:max_people]:
        if stats[label, cv2.CC_STAT_AREA] < min_area * mask.size:
            break
        top, height = stats[label, cv2.CC_STAT_TOP], stats[label, cv2.CC_STAT_HEIGHT]
        band = labels[top:top + max(1, int(0.08 * height))] == label
        columns = np.nonzero(band)[1]
        size = max(4, int(round(0.09 * height)))
        centre_x, centre_y = columns.mean(), top + 0.6 * size
        boxes.append((int(round(centre_x - size / 2)), int(round(centre_y - size / 2)), size, size))
    return np.asarray(boxes, np.int64).reshape(-1, 4)


def largest_component(mask: np.ndarray, *, min_area: int = 50) -> np.ndarray:
    """The largest 8-connected blob of a mask (Ong & Gong's silhouette: background subtraction,
    then connected components).

    Args:
        mask: ``(height, width)`` bool foreground (:func:`foreground_mask`).
        min_area: pixels the blob must cover; a smaller (or no) blob gives an empty mask, which
            callers report as a frame without a silhouette.

    Returns:
        ``(height, width)`` bool, True on the largest blob only (all False when there is none).
    """
    import cv2

    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"mask must be (height, width), got shape {mask.shape}")
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), 8)
    if count < 2:
        return np.zeros(mask.shape, bool)
    label = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[label, cv2.CC_STAT_AREA] < min_area:
        return np.zeros(mask.shape, bool)
    return labels == label
