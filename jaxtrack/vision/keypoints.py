"""Body keypoints from a per-frame detector: evidence the ``"limbs+edges"`` likelihood can score.

A per-frame pose detector (MediaPipe Pose, OpenPose, a user's own network) finds where the body's
joints are in each frame independently; it does not know which frame came before, and it can
confuse the person's left with their right (seen from behind, or as they turn). A tracker can
take its keypoints as one more observation, scored by the likelihood's keypoint term
(``jaxtrack.likelihoods.edges``, ``keypoint_weight``), and keep what the frames before say.

Keypoints here are the tracker's markers (``jaxtrack.body.SPM_MARKERS``: head, neck, thorax,
pelvis, shoulders, elbows, wrists, hips): ``(frames, 12, 2)`` pixel positions in the frames
tracked, and a confidence per keypoint in ``[0, 1]`` (the detector's visibility or score; 0: not
found, its position ignored). A frame where the detector found no one has confidence 0
throughout.

**Where they travel.** Beside the image channels, never inside one: an observation is a
:class:`jaxtrack.vision.ImageObservation` whose ``keypoints`` are a
:class:`jaxtrack.vision.Keypoints` (points and confidences, a leading ``time`` axis for a chunk;
:func:`jaxtrack.vision.image_observations`).

The file ``jaxtrack track --keypoints`` reads (:func:`read_keypoints`): a ``.npz`` with
``keypoints`` ``(frames, 12, 2)`` in the video's own pixels (NaN where not found) and
optionally ``confidence`` ``(frames, 12)``; :func:`write_keypoints` writes one atomically.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from jaxtrack._files import write_npz_atomically
from jaxtrack.body import SPM_MARKERS

__all__ = ["KeypointFileError", "NUM_KEYPOINTS", "check_keypoint_input", "check_keypoints",
           "read_keypoints", "write_keypoints"]

NUM_KEYPOINTS = len(SPM_MARKERS)
"""Keypoints per frame: the tracker's markers, in ``SPM_MARKERS`` order."""

class KeypointFileError(ValueError):
    """A keypoints file is missing, unreadable, or holds arrays that are not per-frame
    keypoints; the message names the file and what is wrong, in one line."""


def check_keypoints(keypoints, confidence=None, *, num_frames: int | None = None,
                    name: str = "keypoints") -> tuple[np.ndarray, np.ndarray]:
    """``(points, confidence)`` as float32 ``(frames, 12, 2)`` and ``(frames, 12)``, refused
    (ValueError, naming ``name``) unless ``keypoints`` are ``(frames, 12, 2)`` pixel positions
    (NaN where not found), ``confidence`` (default 1 where found) lies in ``[0, 1]``, and, given
    ``num_frames``, there is one row per frame. Positions not found, or of confidence 0, become
    0 with confidence 0."""
    points = np.asarray(keypoints, np.float64)
    if points.ndim != 3 or points.shape[1:] != (NUM_KEYPOINTS, 2):
        raise ValueError(f"{name} must be (frames, {NUM_KEYPOINTS}, 2) pixel positions in "
                         f"SPM_MARKERS order, got shape {points.shape}")
    if num_frames is not None and points.shape[0] != num_frames:
        raise ValueError(f"{name} hold {points.shape[0]} frames, the frames tracked are "
                         f"{num_frames}")
    found = np.all(np.isfinite(points), axis=-1)
    if confidence is None:
        confidence = found.astype(np.float64)
    confidence = np.asarray(confidence, np.float64)
    if confidence.shape != points.shape[:2]:
        raise ValueError(f"{name}' confidence must be (frames, {NUM_KEYPOINTS}), got shape "
                         f"{confidence.shape}")
    if not np.all(np.isfinite(confidence)) or confidence.min(initial=0) < 0 or \
            confidence.max(initial=0) > 1:
        raise ValueError(f"{name}' confidence must lie in [0, 1]")
    confidence = np.where(found, confidence, 0.0)
    points = np.where((confidence > 0)[..., None], np.nan_to_num(points), 0.0)
    if np.abs(points).max(initial=0) > 1e6:
        raise ValueError(f"{name} hold positions beyond 10^6 pixels")
    return points.astype(np.float32), confidence.astype(np.float32)


def check_keypoint_input(keypoints, *, num_frames: int | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`check_keypoints` of what a caller hands over: ``(points, confidence)``, or the
    points alone (confidence 1 where found)."""
    points, confidence = keypoints if isinstance(keypoints, tuple) else (keypoints, None)
    return check_keypoints(points, confidence, num_frames=num_frames)


def read_keypoints(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """The keypoints and confidences of a ``.npz`` (module docstring), checked.

    Raises:
        KeypointFileError: no such file, not a readable ``.npz``, no ``keypoints`` array, or
            arrays of the wrong shape or values.
    """
    path = Path(path)
    fail = lambda reason: KeypointFileError(f"{path}: {reason}")  # noqa: E731
    if not path.is_file():
        raise fail("no such keypoints file")
    try:
        with np.load(path, allow_pickle=False) as archive:
            if not hasattr(archive, "files"):
                raise fail("not a .npz file")
            if "keypoints" not in archive.files:
                raise fail(f"no array 'keypoints' (it has {', '.join(archive.files) or 'none'})")
            keypoints = archive["keypoints"]
            confidence = archive["confidence"] if "confidence" in archive.files else None
    except KeypointFileError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as error:
        raise fail(f"not a readable .npz ({type(error).__name__}: "
                   f"{' '.join(str(error).split())})") from None
    try:
        return check_keypoints(keypoints, confidence)
    except ValueError as error:
        raise fail(str(error)) from None


def write_keypoints(path: str | os.PathLike, keypoints: np.ndarray,
                    confidence: np.ndarray | None = None) -> Path:
    """Write keypoints (and their confidences) to a ``.npz`` atomically; return the path."""
    points, confidence = check_keypoints(keypoints, confidence)
    points = np.where((confidence > 0)[..., None], points, np.nan)
    return write_npz_atomically(path, {"keypoints": points, "confidence": confidence})
