"""What a tracker reads of a frame, as a pytree: image channels and, apart from them, a
detector's keypoints.

An image tracker's observation of one frame is an :class:`ImageObservation`:

- ``images``: the image channels the likelihood samples, ``(height, width)`` (a grey frame, for
  the limb-strip and NCC likelihoods) or ``(channels, height, width)`` (the grey frame, its edge
  distance map and the nearest edge's tangent direction, and the person's mask as a fourth
  channel where there is one: :func:`jaxtrack.vision.edge_observations`);
- ``keypoints``: a per-frame detector's keypoints (:class:`Keypoints`), or None;
- ``detections``: every person a per-frame detector found, with their keypoints and
  confidences (a ``jaxtrack.likelihoods.detections.DetectionsFrame``: ``(people, markers, 2)``
  points, ``(people, markers)`` confidences, the number of people and the frame's size), scored
  by the normalised detection density; or None. ``images`` is None where the tracker reads the
  detections alone.

Give every leaf a leading ``time`` axis for a chunk of frames (:func:`image_observations` makes
one from grey frames). Keypoints never ride inside an image channel: they are their own leaves,
so that the image channels stay images and a detector's output keeps its own shape.

Likelihoods take an :class:`ImageObservation` or, where there are no keypoints, the bare image
array (:func:`images_of`, :func:`keypoints_of`).
"""

from __future__ import annotations

import equinox as eqx
import numpy as np
from jaxtyping import Array, Float

__all__ = ["ImageObservation", "Keypoints", "detections_of", "image_observations", "images_of",
           "keypoints_of", "observation_at"]


class Keypoints(eqx.Module):
    """A detector's keypoints of a frame (or, with a leading ``time`` axis, of a chunk).

    Attributes:
        points: ``(markers, 2)`` pixel positions in ``jaxtrack.body.SPM_MARKERS`` order (0
            where not found).
        confidence: ``(markers,)`` in [0, 1]; 0 where not found (the position is then
            ignored).
    """

    points: Float[Array, "*time markers 2"]
    confidence: Float[Array, "*time markers"]


class ImageObservation(eqx.Module):
    """One frame's image channels and, optionally, a detector's keypoints or every person it
    detected (module docstring)."""

    images: Float[Array, "*time ..."] | None
    keypoints: Keypoints | None = None
    detections: object | None = None  # a DetectionsFrame (likelihoods layer, above this one)


def images_of(observation) -> Array:
    """The image channels of an observation: ``observation.images`` of an
    :class:`ImageObservation`, else the observation itself (a bare image array)."""
    if isinstance(observation, ImageObservation):
        return observation.images
    return observation


def keypoints_of(observation) -> Keypoints | None:
    """The keypoints an observation carries, or None."""
    if isinstance(observation, ImageObservation):
        return observation.keypoints
    return None


def detections_of(observation):
    """The detections (a ``DetectionsFrame``) an observation carries, or None."""
    if isinstance(observation, ImageObservation):
        return observation.detections
    return None


def observation_at(observations, index):
    """Frame ``index`` of a pytree of observations with a leading ``time`` axis (every leaf
    indexed; an array is indexed as it is)."""
    import jax

    return jax.tree.map(lambda leaf: leaf[index], observations)


def image_observations(frames: np.ndarray, *, edges: bool = True,
                       masks: np.ndarray | None = None,
                       keypoints: tuple[np.ndarray, np.ndarray] | np.ndarray | None = None,
                       out: np.ndarray | None = None) -> ImageObservation:
    """A chunk's :class:`ImageObservation` from its grey frames (NumPy, on the host).

    Args:
        frames: ``(time, height, width)`` grey frames (floats in [0, 1], or uint8).
        edges: add the edge maps (``(time, 3 or 4, height, width)`` images,
            :func:`jaxtrack.vision.edge_observations`); False: the grey frames alone.
        masks: ``(time, height, width)`` person masks, a fourth channel (needs ``edges``).
        keypoints: ``(points (time, 12, 2), confidence (time, 12))`` or the points alone
            (NaN where not found): :func:`jaxtrack.vision.keypoints.check_keypoint_input`.
        out: optional float32 buffer for the images.
    """
    from jaxtrack.vision.edges import edge_observations
    from jaxtrack.vision.keypoints import check_keypoint_input

    frames = np.asarray(frames)
    if edges:
        images = edge_observations(frames, masks=masks, out=out)
    else:
        if masks is not None:
            raise ValueError("masks are read by the 'limbs+edges' likelihood only (a fourth "
                             "image channel beside the edge maps)")
        if frames.ndim != 3:
            raise ValueError(f"frames must be (time, height, width) grey frames, got shape "
                             f"{frames.shape}")
        grey = (frames * np.float32(1 / 255) if frames.dtype == np.uint8
                else frames.astype(np.float32, copy=False))
        if out is None:
            images = np.ascontiguousarray(grey, np.float32)
        else:
            out[...] = grey
            images = out
    detected = None
    if keypoints is not None:
        points, confidence = check_keypoint_input(keypoints, num_frames=frames.shape[0])
        detected = Keypoints(points, confidence)
    return ImageObservation(images, detected)
