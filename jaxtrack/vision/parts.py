"""Per-posture body-part hypotheses on a silhouette, and the nearest-silhouette-point map.

Kwatra, Bobick & Johnson (2002, §2) take Ghost's (Haritaoglu et al.) idea: once the posture is
known, the head, hands and feet sit at predictable extremes of the silhouette. They compute the
hypotheses of *every* posture in every frame, Z_t = {z_t^q : q ∈ Q}, and let the tracker decide
which posture to believe. The heuristics here, per posture, on the silhouette's bounding box
``[x0, x1] × [y0, y1]`` of height h and width w (image y points down):

- standing: head = topmost point; hands = the leftmost and the rightmost point above
  ``y0 + 0.65 h``; feet = the lowest point left and right of the bottom fifth's centre.
- sitting: head = topmost point; hands = leftmost and rightmost point between ``y0 + 0.2 h`` and
  ``y0 + 0.75 h``; feet = the bottom-left-most and bottom-right-most points (max y − x, y + x).
- crawling / bending: the head is at the end whose outer third of columns reaches less high
  (the hips are the top of a stooping or crawling body); head = that end's extreme point; hands =
  the lowest point in each of the two quarters of the box on the head's side; feet = the lowest
  point in each of the two quarters on the other side. Ghost's rule needs a side view of a body
  whose trunk is horizontal. A box at least :data:`TALL_BENDING` times as high as wide is a
  crouch or a stoop seen from the front, where the trunk's length is hidden and the head is
  the top: there the head and feet are the standing ones and the hands the sitting ones.
- lying facing left (head at the image's left): head = leftmost point; feet = the rightmost point
  in the upper and in the lower half of the box; hands = the topmost and the bottommost point in
  the columns from 15 % to 60 % of the box (arms lie along the trunk).
- lying facing right: the mirror image.

Slots are ordered consistently within a posture (the image-left hand first for standing and
sitting, the outer quarter first for crawling, the upper point first for lying), so particles
that follow them keep their labels; scoring is under the best left/right assignment anyway.
Every point is a foreground pixel (x, y) on the silhouette's boundary or inside it.

The nearest-point map (:func:`nearest_silhouette_points`) holds, for every pixel, the nearest
foreground pixel (Euclidean distance transform); the tracker projects a predicted part that has
left the silhouette by one gather from it. See ``docs/mixed-state.md``.

A per-frame pose detector's keypoints are part hypotheses too (:func:`detection_hypotheses`):
where the detector is confident, its head, wrists and ankles replace the silhouette's
hypotheses of every posture, beside the silhouette's elsewhere.
"""

from __future__ import annotations

import numpy as np

from jaxtrack.priors.postures import NUM_POSTURES, POSTURE_NAMES
from jaxtrack.vision.histograms import FRAME_OK, _check_mask, bounding_box

__all__ = ["DETECTION_PART_MARKERS", "NUM_PARTS", "PART_NAMES", "TALL_BENDING",
           "detection_hypotheses", "nearest_silhouette_points", "part_hypotheses",
           "posture_hypotheses"]

PART_NAMES = ("head", "hand_1", "hand_2", "foot_1", "foot_2")
NUM_PARTS = len(PART_NAMES)
DETECTION_PART_MARKERS = (("head",), ("right_wrist", "left_wrist"),
                          ("right_ankle", "left_ankle"))
"""The detector's markers (:data:`jaxtrack.vision.detections.DETECTION_MARKERS` names) that
stand for the head, the two hands and the two feet: ``head`` is the best head point the
readers give (the base of the skull, by their stated rules, :data:`jaxtrack.vision.detections.
MARKER_RULES`), the hands are the wrists and the feet the ankles (mapped when the readers are
asked for ``markers=DETECTION_MARKERS``)."""
TALL_BENDING = 1.2
"""A crawling/bending silhouette at least this many times as high as wide takes the standing
head and feet and the sitting hands. Chosen on the validation clips of
``jaxtrack.experiments.mixed_state`` (2026-11-27, their 591 crawling/bending frames from five
azimuths): with the box 1.2–1.5 times as high as wide the end rule's head is 229 px (root mean
square) from the true head and the top point's 24 px, from 1.5 on 236 against 15 px; below 1.2
neither rule is better (135–215 against 148–159 px)."""


class _Pixels:
    """The foreground pixels of one mask and its bounding box."""

    def __init__(self, mask: np.ndarray):
        self.ys, self.xs = np.nonzero(mask)
        self.x0, self.y0, self.x1, self.y1 = bounding_box(mask)
        self.width = self.x1 - self.x0 + 1
        self.height = self.y1 - self.y0 + 1

    def select(self, where: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels where ``where`` holds; all pixels if none does (never an empty choice)."""
        if not where.any():
            return self.xs, self.ys
        return self.xs[where], self.ys[where]


def _extreme(xs: np.ndarray, ys: np.ndarray, score: np.ndarray) -> np.ndarray:
    """The pixel of largest ``score``; of tied pixels the one nearest their mean (a pixel of
    the silhouette even when the ties lie on two separate limbs)."""
    best = np.flatnonzero(score == score.max())
    mean_x, mean_y = xs[best].mean(), ys[best].mean()
    pick = best[np.argmin((xs[best] - mean_x) ** 2 + (ys[best] - mean_y) ** 2)]
    return np.array([xs[pick], ys[pick]], np.float64)


def _standing(p: _Pixels) -> np.ndarray:
    head = _extreme(p.xs, p.ys, -p.ys)
    xs, ys = p.select(p.ys <= p.y0 + 0.65 * p.height)
    hands = [_extreme(xs, ys, -xs), _extreme(xs, ys, xs)]
    xs, ys = p.select(p.ys >= p.y0 + 0.8 * p.height)
    centre = xs.mean()
    left, right = xs <= centre, xs > centre
    feet = [_extreme(xs[left], ys[left], ys[left]) if left.any() else _extreme(xs, ys, ys),
            _extreme(xs[right], ys[right], ys[right]) if right.any() else _extreme(xs, ys, ys)]
    return np.stack([head, *hands, *feet])


def _sitting(p: _Pixels) -> np.ndarray:
    head = _extreme(p.xs, p.ys, -p.ys)
    xs, ys = p.select((p.ys >= p.y0 + 0.2 * p.height) & (p.ys <= p.y0 + 0.75 * p.height))
    hands = [_extreme(xs, ys, -xs), _extreme(xs, ys, xs)]
    feet = [_extreme(p.xs, p.ys, p.ys - p.xs), _extreme(p.xs, p.ys, p.ys + p.xs)]
    return np.stack([head, *hands, *feet])


def _lowest_in_columns(p: _Pixels, start: float, stop: float) -> np.ndarray:
    xs, ys = p.select((p.xs >= p.x0 + start * p.width) & (p.xs < p.x0 + stop * p.width))
    return _extreme(xs, ys, ys)


def _crawling_head_left(p: _Pixels) -> np.ndarray:
    head = _extreme(p.xs, p.ys, -p.xs)
    hands = [_lowest_in_columns(p, 0.0, 0.25), _lowest_in_columns(p, 0.25, 0.5)]
    feet = [_lowest_in_columns(p, 0.75, 1.01), _lowest_in_columns(p, 0.5, 0.75)]
    return np.stack([head, *hands, *feet])


def _lying_head_left(p: _Pixels) -> np.ndarray:
    head = _extreme(p.xs, p.ys, -p.xs)
    middle = p.y0 + 0.5 * p.height
    upper_xs, upper_ys = p.select(p.ys <= middle)
    lower_xs, lower_ys = p.select(p.ys > middle)
    feet = [_extreme(upper_xs, upper_ys, upper_xs), _extreme(lower_xs, lower_ys, lower_xs)]
    xs, ys = p.select((p.xs >= p.x0 + 0.15 * p.width) & (p.xs <= p.x0 + 0.6 * p.width))
    hands = [_extreme(xs, ys, -ys), _extreme(xs, ys, ys)]
    return np.stack([head, *hands, *feet])


def _mirrored(function, mask: np.ndarray) -> np.ndarray:
    """``function`` applied to the left-right mirror of ``mask``, its points mapped back."""
    points = function(_Pixels(mask[:, ::-1]))
    points[:, 0] = mask.shape[1] - 1 - points[:, 0]
    return points


def _crawling(mask: np.ndarray, p: _Pixels, standing: np.ndarray, sitting: np.ndarray
              ) -> np.ndarray:
    if p.height >= TALL_BENDING * p.width:  # a crouch, or a stoop seen from the front
        return np.stack([standing[0], sitting[1], sitting[2], standing[3], standing[4]])
    third = p.width / 3
    left_top = p.ys[p.xs < p.x0 + third].min()
    right_top = p.ys[p.xs > p.x1 - third].min()
    # the hips are the top of a stooping or crawling body; the head is at the lower end
    return _crawling_head_left(p) if left_top >= right_top else _mirrored(_crawling_head_left,
                                                                           mask)


def posture_hypotheses(mask: np.ndarray) -> np.ndarray:
    """``(postures, parts, 2)`` pixel positions (x, y) of head, hands and feet under each posture
    (:data:`jaxtrack.priors.postures.POSTURE_NAMES` order) for one non-empty silhouette."""
    mask = _check_mask(mask)
    if not mask.any():
        raise ValueError("mask has no foreground pixel: an empty silhouette has no part "
                         "hypotheses (part_hypotheses reports such frames by their status)")
    p = _Pixels(mask)
    standing, sitting = _standing(p), _sitting(p)
    hypotheses = np.stack([
        standing,
        sitting,
        _crawling(mask, p, standing, sitting),
        _lying_head_left(p),
        _mirrored(_lying_head_left, mask),
    ])
    assert hypotheses.shape == (NUM_POSTURES, NUM_PARTS, 2), POSTURE_NAMES
    return hypotheses


def part_hypotheses(masks: np.ndarray, status: np.ndarray) -> np.ndarray:
    """Every posture's hypotheses in every frame, Z_t = {z_t^q}.

    Args:
        masks: ``(time, height, width)`` bool silhouettes.
        status: ``(time,)`` from :func:`jaxtrack.vision.histograms.silhouette_features`;
            frames not ``FRAME_OK`` get the image centre for every part (finite, and ignored
            by the tracker, which reads the status).

    Returns:
        ``(time, postures, parts, 2)`` float64 pixels.
    """
    masks = np.asarray(masks)
    status = np.asarray(status)
    if masks.ndim != 3 or status.shape != masks.shape[:1]:
        raise ValueError(f"masks must be (time, height, width) and status (time,), got "
                         f"{masks.shape} and {status.shape}")
    height, width = masks.shape[1:]
    centre = np.array([(width - 1) / 2, (height - 1) / 2])
    out = np.broadcast_to(centre, (len(masks), NUM_POSTURES, NUM_PARTS, 2)).copy()
    for index, mask in enumerate(masks):
        if status[index] == FRAME_OK:
            out[index] = posture_hypotheses(mask)
    return out


def nearest_silhouette_points(mask: np.ndarray) -> np.ndarray:
    """For every pixel, the nearest foreground pixel: ``(height, width, 2)`` int16 (x, y).

    A foreground pixel maps to itself; an empty mask maps every pixel to itself (nothing to
    project onto). Exact Euclidean distance transform (``scipy.ndimage``).
    """
    from scipy import ndimage

    mask = _check_mask(mask)
    height, width = mask.shape
    if max(height, width) > np.iinfo(np.int16).max:
        raise ValueError(f"mask of {mask.shape} is too large for int16 pixel indices")
    if not mask.any():
        ys, xs = np.mgrid[:height, :width]
        return np.stack([xs, ys], axis=-1).astype(np.int16)
    _, (rows, columns) = ndimage.distance_transform_edt(~mask, return_indices=True)
    return np.stack([columns, rows], axis=-1).astype(np.int16)


def detection_hypotheses(hypotheses: np.ndarray, points: np.ndarray, confidence: np.ndarray,
                         markers, *, min_confidence: float) -> np.ndarray:
    """Every posture's part hypotheses with a detector's confident keypoints in place of the
    silhouette's: Z_t of Kwatra et al. (2002, §2) with a second source of instantaneous
    hypotheses beside Ghost's silhouette extremes.

    The rule, per frame and posture q:

    - the head: the detector's ``head`` marker (:data:`DETECTION_PART_MARKERS`), where its
      confidence is at least ``min_confidence`` and its position finite, replaces z^q's head;
    - the hands (wrists) and the feet (ankles), each pair on its own: of the two assignments of
      the detected pair to q's two slots, the one of smaller squared distance to the
      silhouette's own hypotheses of those slots is taken, and each confident, finite keypoint
      replaces the slot it is assigned to (an unconfident one costs nothing in either
      assignment, so a lone confident wrist takes the nearer slot);
    - every other part (unconfident, NaN, or a marker ``markers`` does not hold) keeps the
      silhouette's hypothesis.

    Why: the detector labels the person's own left and right, while each posture orders its
    slots by its own image convention (the image-left hand first when standing, the outer
    quarter first when crawling, ...), and the tracker's particles follow the slots by that
    convention (their parts move by constant velocity from frame to frame). Assigning the pair
    to the slots it lies nearest keeps every posture's convention, so a particle's hand stays in
    its slot whichever of the two hypotheses the hand came from; the detector's own left/right
    swaps (a person seen from behind) do not move the slots either. Replacing, not adding, keeps
    Z_t the paper's one hypothesis per posture and part, so the likelihood (eq. 4–7) and the
    posterior proposal are unchanged; a posture whose silhouette heuristics are wrong still
    gets the detector's parts, which is why every posture is replaced and not only the
    likeliest.

    Args:
        hypotheses: ``(time, postures, parts, 2)`` the silhouette's hypotheses
            (:func:`part_hypotheses`), pixels.
        points: ``(time, markers, 2)`` the detector's keypoints in the same pixels (NaN where
            absent).
        confidence: ``(time, markers)`` their confidences (NaN counts as 0).
        markers: the names of the ``markers`` axis (names of
            :data:`jaxtrack.vision.detections.DETECTION_MARKERS`).
        min_confidence: the least confidence of a keypoint that is taken.

    Returns:
        ``(time, postures, parts, 2)`` float64 hypotheses, finite wherever ``hypotheses`` is.
    """
    hypotheses = np.asarray(hypotheses, np.float64)
    points = np.asarray(points, np.float64)
    confidence = np.asarray(confidence, np.float64)
    markers = tuple(markers)
    if hypotheses.ndim != 4 or hypotheses.shape[2:] != (NUM_PARTS, 2):
        raise ValueError(f"hypotheses must be (time, postures, {NUM_PARTS}, 2), got "
                         f"{hypotheses.shape}")
    time = hypotheses.shape[0]
    if points.shape != (time, len(markers), 2) or confidence.shape != (time, len(markers)):
        raise ValueError(f"points must be (time, markers, 2) and confidence (time, markers) "
                         f"for {time} frames and {len(markers)} markers, got {points.shape} "
                         f"and {confidence.shape}")
    if not np.isfinite(min_confidence):
        raise ValueError(f"min_confidence must be a finite number, got {min_confidence}")
    usable = (np.nan_to_num(confidence, nan=0.0) >= min_confidence) & (
        np.isfinite(points).all(axis=-1))
    out = hypotheses.copy()
    slot = 0
    for names in DETECTION_PART_MARKERS:
        slots = list(range(slot, slot + len(names)))
        slot += len(names)
        found = [markers.index(name) if name in markers else None for name in names]
        detected = np.stack([np.zeros((time, 2)) if index is None else
                             np.where(usable[:, index, None], points[:, index], 0.0)
                             for index in found], axis=1)  # (time, n, 2), finite
        taken = np.stack([np.zeros(time, bool) if index is None else usable[:, index]
                          for index in found], axis=1)  # (time, n)
        own = hypotheses[:, :, slots]  # (time, postures, n, 2)
        if len(names) == 1:
            assigned, chosen = detected[:, None], taken[:, None]
        else:  # the cheaper of the two assignments of the pair to the posture's two slots
            kept, swapped = (np.sum(np.where(
                taken[:, None, order], np.sum((detected[:, None, order] - own) ** 2, axis=-1),
                0.0), axis=-1) for order in ([0, 1], [1, 0]))
            swap = swapped < kept  # (time, postures)
            assigned = np.where(swap[..., None, None], detected[:, None, ::-1],
                                detected[:, None])
            chosen = np.where(swap[..., None], taken[:, None, ::-1], taken[:, None])
        out[:, :, slots] = np.where(chosen[..., None], assigned, own)
    return out
