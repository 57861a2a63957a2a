"""Gradient-magnitude maps for the contour-normal edge search of Ong & Gong (2002, §5.2).

The contour term of the linear-combination tracker's fitness looks, from every model contour
vertex, along the contour's normal for the pixel of greatest intensity gradient
(``jaxtrack.likelihoods.contour_normals``). The whole-image work is done once per frame here:
the grey image is smoothed (Gaussian, ``sigma`` pixels) and its Sobel gradient magnitude is
scaled to [0, 1] by the frame's largest value, so a threshold on it means the same in every
frame. The per-particle search then only gathers pixels of this map.

OpenCV is imported inside the functions, so importing this module needs no cv2.
"""

from __future__ import annotations

import numpy as np

__all__ = ["gradient_magnitude"]


def gradient_magnitude(image: np.ndarray, *, sigma: float = 1.0,
                       backend: str = "opencv") -> np.ndarray:
    """The smoothed intensity-gradient magnitude of an image, scaled to [0, 1].

    Args:
        image: ``(height, width, 3)`` uint8 RGB or ``(height, width)`` grey (any real dtype).
        sigma: Gaussian smoothing in pixels before the Sobel derivatives (0: none).
        backend: ``"opencv"``, or ``"kornia"`` for a uint8 RGB torch tensor (any device; the
            result is then a ``jax.Array`` shared through DLPack: ``jaxtrack.vision._kornia``).

    Returns:
        ``(height, width)`` float32; all zeros for a flat image.
    """
    from jaxtrack.vision._kornia import check_backend

    check_backend(backend)
    if backend == "kornia":
        from jaxtrack.vision._kornia import _as_tensor, gradient_magnitudes

        return gradient_magnitudes(_as_tensor(image, "image", 3)[None], sigma=sigma)[0]
    import cv2

    image = np.asarray(image)
    if image.ndim == 3 and image.shape[-1] == 3:
        if image.dtype != np.uint8:
            raise ValueError(f"a colour image must be uint8 RGB, got dtype {image.dtype}")
        grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
    elif image.ndim == 2 and np.issubdtype(image.dtype, np.number):
        grey = image.astype(np.float32)
    else:
        raise ValueError(f"image must be (height, width, 3) uint8 RGB or (height, width) grey, "
                         f"got shape {image.shape} dtype {image.dtype}")
    if not np.all(np.isfinite(grey)):
        raise ValueError("image holds non-finite values")
    if sigma < 0:
        raise ValueError(f"sigma must be >= 0, got {sigma}")
    if sigma > 0:
        grey = cv2.GaussianBlur(grey, (0, 0), sigma)
    dx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3)
    dy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3)
    magnitude = np.sqrt(dx * dx + dy * dy)
    peak = float(magnitude.max())
    return magnitude / peak if peak > 0 else magnitude
