"""Skin-colour detection and the three skin blobs of a person: head and two hands.

Ong & Gong (2002, §5.2) find the head and hands as skin-coloured blobs: skin pixels are
grouped by k-means into three clusters; the top-most cluster is the head and the other two are
the hands. Skin is a fixed box in the YCrCb chroma plane (Cr 135–180, Cb 85–135, the usual rule
for real skin tones under white light, brightness ignored so shading does not matter), restricted
to a foreground mask when one is given, so skin-coloured background is ignored. Clothes of a
skin-like hue pass that box too: given a sample of the person's skin (``reference``, an RGB
colour), skin is instead the pixels whose chroma lies within ``tolerance`` of the sample's.

The hands are ordered by their image x (left-most first), the order the hybrid vectors use in
training and tracking alike; which hand is the person's right depends on the view.

OpenCV is imported inside the functions, so importing this module needs no cv2.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["SKIN_CB", "SKIN_CR", "SkinBlobs", "skin_blobs", "skin_mask"]

SKIN_CR = (135, 180)
"""The Cr range (OpenCV's 8-bit YCrCb) of skin."""

SKIN_CB = (85, 135)
"""The Cb range (OpenCV's 8-bit YCrCb) of skin."""


class SkinBlobs(NamedTuple):
    """One frame's skin blobs.

    Attributes:
        head: ``(2,)`` the head blob's centre ``(x, y)``, pixels.
        hands: ``(2, 2)`` the two hand blobs' centres, left-most first.
        sizes: ``(3,)`` pixels in the head, first and second hand blob.
        found: whether enough skin was seen for three blobs (when False the positions are NaN
            and must not be used; :func:`skin_blobs` says why in ``reason``).
        reason: empty when found, else why not.
    """

    head: np.ndarray
    hands: np.ndarray
    sizes: np.ndarray
    found: bool
    reason: str = ""


def skin_mask(image: np.ndarray, foreground: np.ndarray | None = None, *,
              reference: tuple[int, int, int] | None = None, tolerance: float = 6.0,
              smoothing: int = 3, backend: str = "opencv") -> np.ndarray:
    """Skin-coloured pixels of an RGB image.

    Args:
        image: ``(height, width, 3)`` uint8 RGB.
        foreground: ``(height, width)`` bool; skin is kept only inside it (None: everywhere).
        reference: an RGB sample of the person's skin; None: the fixed chroma box
            (:data:`SKIN_CR`, :data:`SKIN_CB`).
        tolerance: with ``reference``, the largest |ΔCr| and |ΔCb| (8-bit YCrCb levels).
        smoothing: size of the square opening that drops isolated pixels (1: none).
        backend: ``"opencv"``, or ``"kornia"`` for torch tensors (any device; the result is then
            a ``jax.Array`` shared through DLPack: ``jaxtrack.vision._kornia``).

    Returns:
        ``(height, width)`` bool.
    """
    from jaxtrack.vision._kornia import check_backend

    check_backend(backend)
    if backend == "kornia":
        from jaxtrack.vision._kornia import _as_tensor, skin_masks

        image = _as_tensor(image, "image", 3)
        return skin_masks(image[None], None if foreground is None else
                          np.asarray(foreground, bool)[None], reference=reference,
                          tolerance=tolerance, smoothing=smoothing)[0]
    import cv2

    image = np.asarray(image)
    if image.ndim != 3 or image.shape[-1] != 3 or image.dtype != np.uint8:
        raise ValueError(f"image must be (height, width, 3) uint8 RGB, got shape {image.shape} "
                         f"dtype {image.dtype}")
    ycrcb = cv2.cvtColor(image, cv2.COLOR_RGB2YCrCb)
    cr, cb = ycrcb[..., 1].astype(np.int16), ycrcb[..., 2].astype(np.int16)
    if reference is None:
        mask = ((cr >= SKIN_CR[0]) & (cr <= SKIN_CR[1]) & (cb >= SKIN_CB[0])
                & (cb <= SKIN_CB[1]))
    else:
        sample = np.asarray(reference, np.uint8).reshape(1, 1, 3)
        if np.asarray(reference).shape != (3,):
            raise ValueError(f"reference must be one RGB colour (3 numbers), got {reference!r}")
        _, cr_ref, cb_ref = (int(v) for v in cv2.cvtColor(sample, cv2.COLOR_RGB2YCrCb)[0, 0])
        mask = (np.abs(cr - cr_ref) <= tolerance) & (np.abs(cb - cb_ref) <= tolerance)
    if foreground is not None:
        foreground = np.asarray(foreground, bool)
        if foreground.shape != mask.shape:
            raise ValueError(f"foreground {foreground.shape} and image {image.shape[:2]} differ "
                             "in size")
        mask &= foreground
    if smoothing > 1:
        element = np.ones((smoothing, smoothing), np.uint8)
        mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, element).astype(bool)
    return mask


def skin_blobs(mask: np.ndarray, *, min_pixels: int = 12, seed: int = 0) -> SkinBlobs:
    """The head and hand blobs of a skin mask: k-means of the skin pixels' positions into three
    clusters (OpenCV, k-means++ seeding, fixed seed), the top-most (smallest mean y) the head.

    Args:
        mask: ``(height, width)`` bool skin mask (:func:`skin_mask`).
        min_pixels: fewest skin pixels for three blobs (fewer: ``found`` is False).
        seed: OpenCV's random seed for the k-means seeding (the result is reproducible).

    Returns:
        :class:`SkinBlobs`; never raises for a mask without skin (``found`` is False).
    """
    import cv2

    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"mask must be (height, width), got shape {mask.shape}")
    rows, columns = np.nonzero(mask)
    missing = SkinBlobs(np.full(2, np.nan), np.full((2, 2), np.nan), np.zeros(3, np.int64),
                        False)
    if len(rows) < max(3, min_pixels):
        return missing._replace(reason=f"{len(rows)} skin pixels, fewer than the {min_pixels} "
                                       "needed for a head and two hands")
    points = np.column_stack([columns, rows]).astype(np.float32)
    cv2.setRNGSeed(int(seed))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.1)
    _, labels, centres = cv2.kmeans(points, 3, None, criteria, 3, cv2.KMEANS_PP_CENTERS)
    labels = labels.ravel()
    sizes = np.bincount(labels, minlength=3)
    if np.any(sizes == 0):
        return missing._replace(reason="the skin pixels form fewer than three blobs")
    order = np.argsort(centres[:, 1], kind="stable")
    head, others = order[0], order[1:]
    others = others[np.argsort(centres[others, 0], kind="stable")]
    return SkinBlobs(head=centres[head].astype(np.float64),
                     hands=centres[others].astype(np.float64),
                     sizes=sizes[[head, *others]].astype(np.int64), found=True)
