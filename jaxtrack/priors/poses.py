"""Training poses for pose priors: real motion capture seen from several viewpoints.

Tian, Li & Sclaroff (2005) train their GPLVM on SPM states of upper-body poses projected "from
different viewpoints on the view-sphere". :func:`pose_set` does that with the body layer: each
motion is sampled at ``fps``, viewed by ``views`` cameras spread over an azimuth range in front
of the subject, projected to the 12 upper-body markers and converted to 25-d SPM states.

A GPLVM models the **articulation**, the 11 links' angles and lengths, as wrap-free link vectors
in torso units (:func:`pose_features`, 22 numbers); scale and image position (``states[:, :3]``)
are where the person is in the frame, not what pose they hold, and the tracker handles them
apart. :func:`states_from_features` goes back to SPM states.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.body import (
    SPM_MARKERS,
    UPPER_BODY_12,
    Motion,
    SPMTemplate,
    build_template,
    frontal_camera,
    marker_positions,
    spm_forward,
    spm_initial_state,
)
from jaxtrack.body._staging import project_numpy
from jaxtrack.body.spm import spm_chain

__all__ = ["PLACEMENT_SIZE", "PoseSet", "clip_motions", "markers_from_features", "markers_of",
           "pose_features", "pose_set", "states_from_features"]

PLACEMENT_SIZE = 3  # log scale, translation x, translation y


@dataclass(frozen=True)
class PoseSet:
    """Upper-body training poses.

    Attributes:
        states: ``(n, 25)`` SPM states (float64).
        markers_2d: ``(n, 12, 2)`` the projected markers they were fitted to, pixels.
        sequence_ids: ``(n,)`` one id per (clip, view); rows of an id are consecutive frames.
        sequences: ``(clip name, view azimuth in radians)`` of each id.
        template: the SPM template (given, or built from these poses).
        fps: frame rate of the rows of one sequence.
        image_size: ``(width, height)`` of the cameras.
    """

    states: np.ndarray
    markers_2d: np.ndarray
    sequence_ids: np.ndarray
    sequences: tuple[tuple[str, float], ...]
    template: SPMTemplate
    fps: float
    image_size: tuple[int, int]

    @property
    def clip_names(self) -> np.ndarray:
        """``(n,)`` the clip of every row."""
        return np.array([self.sequences[i][0] for i in self.sequence_ids])

    def torso_lengths(self) -> np.ndarray:
        """``(n,)`` neck–pelvis distance of every row, pixels."""
        neck, pelvis = SPM_MARKERS.index("neck"), SPM_MARKERS.index("pelvis")
        return np.linalg.norm(self.markers_2d[:, pelvis] - self.markers_2d[:, neck], axis=-1)


def _view_azimuths(views: int, azimuth_range: tuple[float, float]) -> np.ndarray:
    if views < 1:
        raise ValueError(f"views must be at least 1, got {views}")
    if views == 1:
        return np.array([0.5 * (azimuth_range[0] + azimuth_range[1])])
    return np.linspace(azimuth_range[0], azimuth_range[1], views)


def pose_set(
    motions: Mapping[str, Motion],
    *,
    views: int = 5,
    azimuth_range: tuple[float, float] = (-np.pi / 4, np.pi / 4),
    elevation: float = 0.1,
    fps: float = 30.0,
    image_size: tuple[int, int] = (640, 480),
    template: SPMTemplate | None = None,
) -> PoseSet:
    """Project named motions from ``views`` viewpoints and fit SPM states to every frame.

    Args:
        motions: clip name → real motion (e.g. ``jaxtrack.data.load_clip``).
        views: cameras per clip, azimuths evenly spread over ``azimuth_range`` (radians, 0 is
            straight in front of the subject) at ``elevation``.
        fps: frames are taken at this rate (nearest frames of the capture).
        template: SPM template to fit with; default: built from all the projected markers.
    """
    if not motions:
        raise ValueError("pose_set needs at least one motion")
    markers, ids, sequences = [], [], []
    for name, motion in motions.items():
        if not isinstance(motion, Motion):
            raise TypeError(f"motions[{name!r}] is a {type(motion).__name__}, not a Motion")
        step = max(motion.fps / fps, 1.0)
        frames = np.round(np.arange(0.0, motion.num_frames - 0.5, step)).astype(int)
        joints = marker_positions(motion, UPPER_BODY_12)[frames]
        for azimuth in _view_azimuths(views, azimuth_range):
            camera = frontal_camera(motion, image_size, elevation=elevation, azimuth=azimuth)
            pixels, _ = project_numpy(camera, joints)
            ids.append(np.full(len(frames), len(sequences)))
            sequences.append((name, float(azimuth)))
            markers.append(pixels)
    markers_2d = np.concatenate(markers)
    if template is None:
        template = build_template(jnp.asarray(markers_2d))
    # the closed form is exact for projected (noise-free) markers
    states = np.asarray(spm_initial_state(jnp.asarray(markers_2d), template))
    return PoseSet(states=states, markers_2d=markers_2d, sequence_ids=np.concatenate(ids),
                   sequences=tuple(sequences), template=template, fps=float(fps),
                   image_size=tuple(image_size))


def pose_features(states: Float[ArrayLike, "... 25"], template: SPMTemplate
                  ) -> Float[Array, "... 22"]:
    """The pose part of SPM states as link vectors in torso units: ``(..., 11 × 2)``.

    Link k contributes ``L_k e^ℓ_k (cos(φ_k + θ_k), sin(φ_k + θ_k))``, its image vector divided
    by the neck–pelvis distance. Unlike the raw angles this has no 2π wrap (a forearm circling
    its elbow stays continuous, and one pose has one feature vector whatever the unwrapping
    history), and a Euclidean distance between features is a marker displacement in torso
    lengths, the unit trackers are judged in.
    """
    states = jnp.asarray(states)
    dtype = jnp.result_type(states, float)
    angles = states[..., 3::2] + template.reference_angles.astype(dtype)
    lengths = template.reference_lengths.astype(dtype) * jnp.exp(states[..., 4::2])
    vectors = lengths[..., None] * jnp.stack([jnp.cos(angles), jnp.sin(angles)], axis=-1)
    return vectors.reshape(*vectors.shape[:-2], -1)


def states_from_features(features: Float[ArrayLike, "... 22"], placement: Float[ArrayLike, "... 3"],
                         template: SPMTemplate, minimum_length: float = 1e-3
                         ) -> Float[Array, "... 25"]:
    """SPM states from link-vector features and (log scale, x, y) placements (broadcasting).

    The inverse of :func:`pose_features`; a link shorter than ``minimum_length`` torso lengths
    is lengthened to it (its log length would otherwise be −∞).
    """
    features, placement = jnp.asarray(features), jnp.asarray(placement)
    dtype = jnp.result_type(features, placement, float)
    vectors = features.astype(dtype).reshape(*features.shape[:-1], -1, 2)
    angles = jnp.arctan2(vectors[..., 1], vectors[..., 0]) - template.reference_angles.astype(dtype)
    angles = jnp.arctan2(jnp.sin(angles), jnp.cos(angles))
    norms = jnp.maximum(jnp.linalg.norm(vectors, axis=-1), minimum_length)
    log_lengths = jnp.log(norms / template.reference_lengths.astype(dtype))
    links = jnp.stack([angles, log_lengths], axis=-1).reshape(*angles.shape[:-1], -1)
    shape = jnp.broadcast_shapes(links.shape[:-1], placement.shape[:-1])
    return jnp.concatenate([jnp.broadcast_to(placement.astype(dtype), (*shape, PLACEMENT_SIZE)),
                            jnp.broadcast_to(links, (*shape, links.shape[-1]))], axis=-1)


def markers_from_features(features: Float[ArrayLike, "22"], placement: Float[ArrayLike, "3"],
                          minimum_length: float = 1e-3) -> Float[Array, "markers 2"]:
    """``spm_forward(states_from_features(features, placement, template), template)`` for ONE
    pose (vmap over particles), without the detour through angles and log lengths.

    A feature is a link's image vector in torso units, so its markers are the neck plus the
    summed link vectors times the scale, whatever the template: no atan2, cos, sin, log or
    exp, only the lengthening
    of links shorter than ``minimum_length`` (along their own direction; a zero link along the
    image x axis, where ``states_from_features`` puts it). Equal to the two-step conversion up
    to float rounding (~1e-6 relative), and several times faster for a particle filter.
    """
    features, placement = jnp.asarray(features), jnp.asarray(placement)
    if features.shape != (22,) or placement.shape != (PLACEMENT_SIZE,):
        raise ValueError(f"expected (22,) features and ({PLACEMENT_SIZE},) placement of one pose, "
                         f"got {features.shape} and {placement.shape}")
    dtype = jnp.result_type(features, placement, float)
    features, placement = features.astype(dtype), placement.astype(dtype)
    x, y = features[0::2], features[1::2]
    norms = jnp.sqrt(x * x + y * y)  # written out: a reduction over an axis of 2 is slow on CPU
    short = norms < minimum_length
    # the factor that stretches a short link to minimum_length (1 for every other link)
    stretch = jnp.where(short, minimum_length / jnp.where(norms > 0, norms, 1), 1)
    x = jnp.where(norms > 0, x * stretch, minimum_length)
    y = y * stretch
    vectors = jnp.exp(placement[0]) * jnp.stack([x, y], axis=-1)
    return spm_chain(placement[1:3], vectors)


def markers_of(states: Float[ArrayLike, "n 25"], template: SPMTemplate) -> np.ndarray:
    """``(n, 12, 2)`` markers of SPM states (NumPy, for evaluation)."""
    return np.asarray(jax.vmap(spm_forward, in_axes=(0, None))(jnp.asarray(states), template))


def clip_motions(names: Sequence[str], *, asf: str | os.PathLike | None = None
                 ) -> dict[str, Motion]:
    """``{name: load_clip(name)}`` for catalogue clip names or paths to ``.bvh``/``.amc`` files
    (``asf``: the skeleton of every ``.amc`` path; by default the one beside each)."""
    from jaxtrack.data import load_clip

    return {name: load_clip(name, asf=asf) for name in names}
