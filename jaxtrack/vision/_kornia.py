"""The kornia backend of the linear-combination tracker's preprocessing: frames that already
live in PyTorch (on a GPU, say) are processed there and handed to JAX through DLPack.

Each function mirrors an OpenCV function of this package, batched over frames:
:func:`foreground_masks` (``foreground.foreground_mask``), :func:`skin_masks`
(``skin.skin_mask``) and :func:`gradient_magnitudes` (``normals.gradient_magnitude``). Inputs
are ``(time, height, width, 3)`` uint8 RGB as NumPy arrays or torch tensors on any device;
outputs are ``jax.Array`` on the same device, shared with the torch result through DLPack
(no copy). They agree with the OpenCV path pixel for pixel up to rounding of the colour
conversion and the image border (``tests/vision/test_kornia_backend.py``).

On a CPU the OpenCV path is the fast one (``python -m benchmarks.vision_backends``): kornia's
case is frames already on a GPU, where a round trip through host memory costs more than the
filters (on an H200, 5–34× more per frame than kornia there: ``--device cuda``,
``docs/linear-combination.md``).

torch and kornia are imported inside the functions (the optional ``kornia`` extra; install
``torch==2.13.0`` first).
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["BACKENDS", "KorniaUnavailableError", "check_backend", "foreground_masks",
           "gradient_magnitudes", "skin_masks", "to_jax"]

BACKENDS = ("opencv", "kornia")
"""``backend=`` of the preprocessing functions: OpenCV on NumPy arrays (the default) or kornia
on torch tensors."""


def check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")


class KorniaUnavailableError(ImportError):
    """``backend="kornia"`` without torch and kornia installed."""


def _modules():
    try:
        import kornia
        import torch
    except ImportError as error:
        raise KorniaUnavailableError(
            f"backend='kornia' needs torch and kornia ({error}); install them with "
            f"`pip install torch==2.13.0` then `pip install 'jaxtrack[kornia]'`") from None
    return torch, kornia


def _as_tensor(images, name: str, ndim: int, device=None):
    """A torch tensor of ``images`` (NumPy arrays are wrapped without a copy)."""
    torch, _ = _modules()
    if not isinstance(images, torch.Tensor):
        with warnings.catch_warnings():  # read-only arrays: the filters never write to them
            warnings.filterwarnings("ignore", "The given NumPy array is not writable")
            images = torch.from_numpy(np.ascontiguousarray(images))
    if device is not None:
        images = images.to(device)
    if images.ndim != ndim or images.shape[-1] != 3 or images.dtype != torch.uint8:
        kind = "(time, height, width, 3)" if ndim == 4 else "(height, width, 3)"
        raise ValueError(f"{name} must be {kind} uint8 RGB, got shape {tuple(images.shape)} "
                         f"dtype {images.dtype}")
    return images


def _channels_first(images):
    """``(time, height, width, 3)`` uint8 → ``(time, 3, height, width)`` float32 in [0, 255]."""
    return images.permute(0, 3, 1, 2).float()


def to_jax(tensor):
    """A torch tensor as a ``jax.Array`` on its device, through DLPack (no copy)."""
    import jax

    return jax.dlpack.from_dlpack(tensor.contiguous())


def _ellipse(size: int, device):
    """OpenCV's ``getStructuringElement(MORPH_ELLIPSE, (size, size))`` as a float tensor."""
    import cv2

    torch, _ = _modules()
    element = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    return torch.as_tensor(element, dtype=torch.float32, device=device)


def _open(mask, kernel):
    _, kornia = _modules()
    return kornia.morphology.opening(mask, kernel, border_type="geodesic")


def _close(mask, kernel):
    _, kornia = _modules()
    return kornia.morphology.closing(mask, kernel, border_type="geodesic")


def foreground_masks(frames, background, *, threshold: int = 30, smoothing: int = 5):
    """``foreground.foreground_mask`` of every frame: ``(time, height, width)`` bool."""
    torch, _ = _modules()
    frames = _as_tensor(frames, "frames", 4)
    background = _as_tensor(background, "background", 3, frames.device)
    if tuple(frames.shape[1:]) != tuple(background.shape):
        raise ValueError(f"frames {tuple(frames.shape[1:])} and background "
                         f"{tuple(background.shape)} differ in size")
    if not 0 <= threshold < 255:
        raise ValueError(f"threshold must be in [0, 255), got {threshold}")
    difference = (frames.int() - background.int()[None]).abs().amax(dim=-1)
    mask = (difference > threshold).float()[:, None]
    if smoothing > 1:
        kernel = _ellipse(smoothing, frames.device)
        mask = _close(_open(mask, kernel), kernel)
    return to_jax(mask[:, 0] > 0.5)


def skin_masks(images, foreground=None, *, reference: tuple[int, int, int] | None = None,
               tolerance: float = 6.0, smoothing: int = 3):
    """``skin.skin_mask`` of every image: ``(time, height, width)`` bool.

    ``foreground`` is ``(time, height, width)`` bool (NumPy, torch or JAX) or None.
    """
    from jaxtrack.vision.skin import SKIN_CB, SKIN_CR

    torch, kornia = _modules()
    images = _as_tensor(images, "images", 4)
    # kornia's YCbCr on [0, 1] is OpenCV's 8-bit YCrCb / 255 before rounding
    ycbcr = kornia.color.rgb_to_ycbcr(_channels_first(images) / 255.0) * 255.0
    cb, cr = ycbcr[:, 1].round(), ycbcr[:, 2].round()
    if reference is None:
        mask = (cr >= SKIN_CR[0]) & (cr <= SKIN_CR[1]) & (cb >= SKIN_CB[0]) & (cb <= SKIN_CB[1])
    else:
        if np.asarray(reference).shape != (3,):
            raise ValueError(f"reference must be one RGB colour (3 numbers), got {reference!r}")
        sample = torch.as_tensor(np.asarray(reference, np.uint8).reshape(1, 1, 1, 3),
                                 device=images.device)
        sample = kornia.color.rgb_to_ycbcr(_channels_first(sample) / 255.0) * 255.0
        cb_ref, cr_ref = sample[0, 1, 0, 0].round(), sample[0, 2, 0, 0].round()
        mask = ((cr - cr_ref).abs() <= tolerance) & ((cb - cb_ref).abs() <= tolerance)
    if foreground is not None:
        if isinstance(foreground, torch.Tensor):
            foreground = foreground.to(device=images.device, dtype=torch.bool)
        elif not isinstance(foreground, np.ndarray) and hasattr(foreground, "__dlpack__"):
            foreground = torch.from_dlpack(foreground).to(device=images.device,
                                                          dtype=torch.bool)
        else:
            foreground = torch.from_numpy(np.array(foreground, bool)).to(images.device)
        if tuple(foreground.shape) != tuple(mask.shape):
            raise ValueError(f"foreground {tuple(foreground.shape)} and images "
                             f"{tuple(mask.shape)} differ in size")
        mask &= foreground
    if smoothing > 1:
        kernel = torch.ones((smoothing, smoothing), device=images.device)
        mask = _open(mask.float()[:, None], kernel)[:, 0] > 0.5
    return to_jax(mask)


def gradient_magnitudes(images, *, sigma: float = 1.0):
    """``normals.gradient_magnitude`` of every image: ``(time, height, width)`` float32 in
    [0, 1], each frame scaled by its own largest value."""
    torch, kornia = _modules()
    images = _as_tensor(images, "images", 4)
    if sigma < 0:
        raise ValueError(f"sigma must be >= 0, got {sigma}")
    # OpenCV's RGB→grey weights (0.299, 0.587, 0.114), rounded to 8 bits as cv2.cvtColor does
    grey = kornia.color.rgb_to_grayscale(_channels_first(images)).round()
    if sigma > 0:
        size = int(round(sigma * 8 + 1)) | 1  # OpenCV's kernel size for float images
        grey = kornia.filters.gaussian_blur2d(grey, (size, size), (sigma, sigma),
                                              border_type="reflect")
    # OpenCV's Sobel reflects the border (reflect-101); kornia's would replicate it
    padded = torch.nn.functional.pad(grey, (1, 1, 1, 1), mode="reflect")
    gradient = kornia.filters.spatial_gradient(padded, mode="sobel",
                                               normalized=False)[:, 0, :, 1:-1, 1:-1]
    magnitude = torch.sqrt(gradient[:, 0] ** 2 + gradient[:, 1] ** 2)
    peak = magnitude.amax(dim=(1, 2), keepdim=True)
    return to_jax(torch.where(peak > 0, magnitude / peak.clamp_min(1e-30), magnitude))
