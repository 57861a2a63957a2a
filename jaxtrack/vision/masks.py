"""Person masks from a file: silhouettes a user brings instead of background subtraction.

The silhouette trackers (linear combinations, mixed state) take the person as what differs from
the video's median background. That needs a static camera and a person who leaves every place
they stand in; where the person barely moves (the Pose2Sim demo's man balancing on a beam), the
median holds them and the silhouette is fragments. A person segmenter's masks (MediaPipe's,
SAM's, a chroma key's) avoid that: ``jaxtrack track --masks FILE`` takes them per video.

The file: a ``.npz`` with an array ``masks``, or a ``.npy``, of shape ``(frames, height, width)``
holding bool, or 0 and 1, or 0 and 255 (uint8), one mask per frame of the video from its first
frame, at the video's size or any size of the same aspect ratio (they are resized to the frames
tracked, nearest neighbour). :func:`write_masks` writes one atomically.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from jaxtrack._files import write_npz_atomically

__all__ = ["MaskFileError", "check_masks", "masks_for_frames", "read_masks", "write_masks"]

ASPECT_TOLERANCE = 0.02
"""Largest relative difference between the masks' and the frames' aspect ratios."""


class MaskFileError(ValueError):
    """A masks file is missing, unreadable, or holds arrays that are not per-frame masks.

    The message names the file and what is wrong with it, in one line.
    """


def read_masks(path: str | os.PathLike) -> np.ndarray:
    """The ``(frames, height, width)`` bool masks of a ``.npz`` (array ``masks``) or ``.npy``.

    Raises:
        MaskFileError: no such file, not a readable ``.npz``/``.npy``, no ``masks`` array, or
            an array that is not 3-D bool / 0–1 / 0–255.
    """
    path = Path(path)
    fail = lambda reason: MaskFileError(f"{path}: {reason}")  # noqa: E731
    if not path.is_file():
        raise fail("no such masks file")
    with open(path, "rb") as file:
        magic = file.read(6)
    if not magic.startswith((b"PK", b"\x93NUMPY")):
        raise fail("not a .npz or .npy file")
    try:
        if magic.startswith(b"\x93NUMPY"):
            masks = np.load(path, allow_pickle=False)
        else:
            with np.load(path, allow_pickle=False) as archive:
                if "masks" not in archive.files:
                    raise fail(f"no array 'masks' (it has {', '.join(archive.files) or 'none'})")
                masks = archive["masks"]
    except MaskFileError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as error:
        raise fail(f"damaged or truncated ({type(error).__name__}: "
                   f"{' '.join(str(error).split())})") from None
    if masks.ndim != 3 or 0 in masks.shape:
        raise fail(f"masks must be (frames, height, width), got shape {masks.shape}")
    if masks.dtype == np.bool_:
        return masks
    if masks.dtype.kind not in "ui":
        raise fail(f"masks must be bool or integer 0/1 or 0/255, got dtype {masks.dtype}")
    values = np.unique(masks)
    if not (set(values.tolist()) <= {0, 1} or set(values.tolist()) <= {0, 255}):
        raise fail(f"integer masks must hold only 0 and 1, or 0 and 255; found values "
                   f"{values[:6].tolist()}")
    return masks > 0


def check_masks(masks, frames_shape: tuple[int, ...]) -> np.ndarray:
    """``masks`` as an array, refused (ValueError) unless it is bool of ``frames_shape``
    ``(time, height, width)``, one mask per grey frame."""
    masks = np.asarray(masks)
    if masks.shape != tuple(frames_shape) or masks.dtype != np.bool_:
        raise ValueError(f"masks must be (time, height, width) bool like the frames "
                         f"{tuple(frames_shape)}, got {masks.dtype} {masks.shape}")
    return masks


def masks_for_frames(masks: np.ndarray, frame_indices: np.ndarray, size: tuple[int, int], *,
                     name: str = "masks") -> np.ndarray:
    """The masks of the video frames ``frame_indices``, resized to ``size`` ``(width,
    height)`` (nearest neighbour).

    Raises:
        MaskFileError: a frame index beyond the masks, or an aspect ratio that differs from
            ``size``'s by more than :data:`ASPECT_TOLERANCE`. ``name`` names the file.
    """
    import cv2

    frame_indices = np.asarray(frame_indices, np.int64)
    if frame_indices.size and (frame_indices.min() < 0 or frame_indices.max() >= len(masks)):
        raise MaskFileError(f"{name}: holds {len(masks)} masks, but video frame "
                            f"{int(frame_indices.max())} is tracked (one mask per video frame, "
                            f"from its first)")
    width, height = size
    mask_height, mask_width = masks.shape[1:]
    if abs((mask_width / mask_height) / (width / height) - 1) > ASPECT_TOLERANCE:
        raise MaskFileError(f"{name}: masks are {mask_width}x{mask_height}, frames {width}x"
                            f"{height}; the aspect ratios differ")
    chosen = masks[frame_indices]
    if (mask_width, mask_height) == (width, height):
        return chosen.copy()
    return np.stack([cv2.resize(mask.astype(np.uint8), (width, height),
                                interpolation=cv2.INTER_NEAREST) > 0 for mask in chosen])


def write_masks(path: str | os.PathLike, masks: np.ndarray) -> Path:
    """Write ``(frames, height, width)`` bool ``masks`` to a ``.npz`` (array ``masks``,
    compressed) atomically; returns the path."""
    masks = np.asarray(masks)
    if masks.ndim != 3 or masks.dtype != np.bool_:
        raise ValueError(f"masks must be (frames, height, width) bool, got shape {masks.shape} "
                         f"dtype {masks.dtype}")
    return write_npz_atomically(path, {"masks": masks}, compress=True)
