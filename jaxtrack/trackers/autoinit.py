"""Automatic initialisation of the latent tracker: a face box, then a search of the prior.

Tian, Li & Sclaroff initialised by hand and left automatic initialisation as future work. Here:

1. Face boxes come from OpenCV's bundled Haar cascades (``jaxtrack.vision.face_candidates``:
   frontal and profile, permissive, so a blurred or turned face is still a candidate). When no
   face explains the frame (pixelated or turned-away faces are common in real footage), head
   boxes guessed from the top of the foreground blobs are tried too.
2. Under each box, every candidate pose is scored against the frame's foreground (a mask from
   ``jaxtrack.vision.foreground_mask``; no NCC templates exist before initialisation). Candidate
   poses are the GPLVM's own training latents decoded by μ: the search is over poses the prior
   says are feasible. Each is placed with its head at the face, at a grid of scales (torso length
   in face sizes) and small offsets.
3. A candidate's score is the Dice overlap, inside a window around the face (fixed in face
   sizes, so a body drawn too small leaves the rest of the person unexplained), between the
   foreground and the body drawn as thick line segments (one radius per link). The body is drawn
   once per latent and scale relative to the head; a placement only moves where the foreground
   is read, so each scale's search is one matrix product, ``(latents, window) @ (window,
   placements)``.

The best candidate's markers initialise the tracker (its NCC templates, placement and latent).
No face, or no face under which a pose explains the foreground, raises :class:`AutoInitError`
saying which.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from jaxtrack.body import MARKER_EDGES, UPPER_BODY_12, SPMTemplate, spm_forward
from jaxtrack.likelihoods import squared_segment_distances
from jaxtrack.priors.gplvm import GPLVM
from jaxtrack.priors.poses import states_from_features

__all__ = ["AutoInit", "AutoInitError", "auto_initialise", "search_poses"]

_EDGES = np.asarray(MARKER_EDGES[UPPER_BODY_12])
_NAMES = UPPER_BODY_12
_HEAD = _NAMES.index("head")
_HIPS = [_NAMES.index(name) for name in ("pelvis", "left_hip", "right_hip")]


def _edge_radius(edge: tuple[int, int]) -> float:
    """Half-width of a body part drawn along a marker edge, in torso lengths."""
    names = {_NAMES[edge[0]], _NAMES[edge[1]]}
    if "head" in names:
        return 0.22
    if names <= {"neck", "thorax", "pelvis"}:
        return 0.28  # the trunk
    if "neck" in names or "pelvis" in names:
        return 0.16  # shoulder girdle and hips
    return 0.09  # upper arms and forearms


_RADII = np.array([_edge_radius(tuple(edge)) for edge in _EDGES])

#: the window scored around a candidate, relative to the head, in torso lengths (x, then y down)
WINDOW_X = (-1.6, 1.6)
WINDOW_Y = (-1.3, 1.45)
#: weight of unexplained foreground below a candidate's hips (its legs)
LEG_WEIGHT = 0.3
#: the smallest foreground blob taken for a person, pixels: a person about 50 px tall (far-away
#: people in surveillance footage such as OpenCV's vtest.avi are about 80 px tall, 1 500-2 500 px
#: of foreground), whatever the frame's size
MIN_PERSON_PIXELS = 500
#: foreground blobs searched for a head, largest first
MAX_PEOPLE = 5


class AutoInitError(RuntimeError):
    """Automatic initialisation found no face, or no pose under a face that explains the frame."""


@dataclass(frozen=True)
class AutoInit:
    """The result of :func:`auto_initialise`.

    Attributes:
        markers: ``(12, 2)`` initial markers (``UPPER_BODY_12`` order), pixels.
        face: ``(4,)`` the face box ``(x, y, width, height)`` the pose hangs from.
        score: Dice overlap of the chosen pose with the foreground (0–1).
        torso: the chosen torso length, pixels.
        latent: ``(latent,)`` the training latent whose pose was chosen.
        faces: ``(faces, 4)`` every face box tried.
        face_scores: ``(faces,)`` the best score under each box.
        source: ``"face"`` (a Haar face box) or ``"foreground"`` (the top of a foreground blob).
    """

    markers: np.ndarray
    face: np.ndarray
    score: float
    torso: float
    latent: np.ndarray
    faces: np.ndarray
    face_scores: np.ndarray
    source: str = "face"


def _window_points(resolution: int) -> np.ndarray:
    u = np.linspace(*WINDOW_X, resolution)
    v = np.linspace(*WINDOW_Y, resolution)
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def _segment_distances(points: Array, starts: Array, ends: Array) -> Array:
    """``(points, segments)`` distance of each point to each segment."""
    return jnp.sqrt(squared_segment_distances(points, starts, ends))


@jax.jit
def _body_masks(shapes: Float[Array, "latents 12 2"], points: Float[Array, "window 2"],
                radii: Float[Array, " edges"]) -> tuple[Array, Array]:
    """``(latents, window)`` masks of a head-relative shape: 1 inside its thick-segment body,
    and the weight of unexplained foreground: 1 above its hips, ``LEG_WEIGHT`` below (legs,
    which the upper-body model lacks, count a little, so that a body drawn too small still
    leaves the rest of the person unexplained)."""
    def one(shape):
        distances = _segment_distances(points, shape[_EDGES[:, 0]], shape[_EDGES[:, 1]])
        inside = jnp.any(distances < radii[None], axis=-1)
        hips = jnp.max(shape[jnp.asarray(_HIPS), 1]) + 0.1
        counted = jnp.where(inside | (points[:, 1] <= hips), 1.0, LEG_WEIGHT)
        return inside.astype(points.dtype), counted.astype(points.dtype)

    return jax.lax.map(one, shapes, batch_size=64)


@jax.jit
def _read_foreground(foreground: Float[Array, "height width"], centres: Float[Array, "p 2"],
                     torsos: Float[Array, " p"], points: Float[Array, "window 2"]
                     ) -> Float[Array, "window p"]:
    """The foreground at the window points of each placement (nearest pixel; 0 outside)."""
    pixels = centres[None] + torsos[None, :, None] * points[:, None, :]
    column = jnp.round(pixels[..., 0]).astype(jnp.int32)
    row = jnp.round(pixels[..., 1]).astype(jnp.int32)
    height, width = foreground.shape
    inside = (column >= 0) & (column < width) & (row >= 0) & (row < height)
    values = foreground[jnp.clip(row, 0, height - 1), jnp.clip(column, 0, width - 1)]
    return jnp.where(inside, values, 0.0)


@jax.jit
def _dice(masks: tuple[Array, Array], reads: Float[Array, "window p"]) -> Float[Array, "latents p"]:
    inside, counted = masks
    overlap = inside @ reads
    return 2.0 * overlap / jnp.maximum(inside.sum(-1)[:, None] + counted @ reads, 1e-6)


def _candidate_latents(prior: GPLVM, max_latents: int) -> np.ndarray:
    latents = np.asarray(prior.latents, np.float64)
    if len(latents) > max_latents:
        picks = np.linspace(0, len(latents) - 1, max_latents).round().astype(int)
        latents = latents[picks]
    return latents


def _shapes(prior: GPLVM, template: SPMTemplate, latents: np.ndarray) -> np.ndarray:
    """Markers of μ(latents) with a unit torso, relative to the head: ``(latents, 12, 2)``."""
    model = prior.astype(jnp.float32)
    template32 = jax.tree.map(lambda leaf: jnp.asarray(np.asarray(leaf), jnp.float32), template)

    @jax.jit
    def decode(latents):
        features = jax.vmap(model.mean)(latents)
        states = states_from_features(features, jnp.zeros(3, jnp.float32), template32)
        markers = jax.vmap(spm_forward, in_axes=(0, None))(states, template32)
        return markers - markers[:, _HEAD:_HEAD + 1]

    return np.asarray(decode(jnp.asarray(latents, jnp.float32)))


def _masks(shapes: Array, points: np.ndarray, scales: np.ndarray) -> list:
    """The body masks (:func:`_body_masks`) of every shape drawn at each scale (torso lengths
    in face sizes) over the window points."""
    radii = jnp.asarray(_RADII, jnp.float32)
    return [_body_masks(shapes, jnp.asarray(points / scale), radii) for scale in scales]


def _scores(masks: list, reads: Array) -> np.ndarray:
    """``(scales, latents, placements)`` Dice scores of each scale's masks against the
    foreground read at each placement's window points."""
    return np.stack([np.asarray(_dice(scale_masks, reads)) for scale_masks in masks])


_FINE_SCALES, _FINE_OFFSETS = np.geomspace(0.88, 1.12, 5), np.linspace(-0.12, 0.12, 5)


@dataclass(frozen=True)
class _Bodies:
    """The candidate poses of a search, drawn once at the coarse scales (reused for every set
    of boxes searched against the same prior)."""

    latents: np.ndarray
    shapes: Array
    scales: np.ndarray
    points: np.ndarray
    masks: list


def _bodies(prior: GPLVM, template: SPMTemplate, scales: np.ndarray, max_latents: int,
            resolution: int) -> _Bodies:
    scales = np.asarray(scales, np.float64)
    latents = _candidate_latents(prior, max_latents)
    shapes = jnp.asarray(_shapes(prior, template, latents))
    points = (_window_points(resolution) * scales.max() * _FINE_SCALES.max()).astype(np.float32)
    return _Bodies(latents, shapes, scales, points, _masks(shapes, points, scales))


def _search(bodies: _Bodies, foreground: Array, faces: np.ndarray, offsets: np.ndarray
            ) -> AutoInit:
    shapes, points, scales = bodies.shapes, bodies.points, bodies.scales
    size = faces[:, 2:].max(axis=1)
    centre = faces[:, :2] + faces[:, 2:] / 2

    def read(face_of, shifts):
        centres = centre[face_of] + shifts * size[face_of, None]
        return centres, _read_foreground(foreground, jnp.asarray(centres, jnp.float32),
                                         jnp.asarray(size[face_of], jnp.float32),
                                         jnp.asarray(points))

    # coarse: every face × offset, every scale
    grid = np.stack(np.meshgrid(np.arange(len(faces)), offsets, offsets, indexing="ij"),
                    axis=-1).reshape(-1, 3)
    face_of = grid[:, 0].astype(int)
    centres, reads = read(face_of, grid[:, 1:])
    scores = _scores(bodies.masks, reads)  # (scales, latents, placements)
    if not np.all(np.isfinite(scores)):
        raise AutoInitError("the pose search produced non-finite scores")
    per_face = np.array([scores[..., face_of == f].max() for f in range(len(faces))])
    coarse_scale, _, coarse_placement = np.unravel_index(np.argmax(scores), scores.shape)
    # fine: finer scales and offsets around the best placement, every latent
    face = face_of[coarse_placement]
    shifts = np.stack(np.meshgrid(_FINE_OFFSETS, _FINE_OFFSETS, indexing="ij"),
                      -1).reshape(-1, 2)
    shifts = shifts + grid[coarse_placement, 1:]
    fine_centres, fine_reads = read(np.full(len(shifts), face), shifts)
    fine_scales = scales[coarse_scale] * _FINE_SCALES
    fine = _scores(_masks(shapes, points, fine_scales), fine_reads)
    if fine.max() > scores.max():
        scale_index, best_latent, placement = np.unravel_index(np.argmax(fine), fine.shape)
        scale, centre_px, score = fine_scales[scale_index], fine_centres[placement], fine.max()
    else:
        scale_index, best_latent, placement = np.unravel_index(np.argmax(scores), scores.shape)
        scale, centre_px, score = scales[scale_index], centres[placement], scores.max()
    torso = float(scale * size[face])
    markers = centre_px + torso * np.asarray(shapes[best_latent], np.float64)
    return AutoInit(markers=markers, face=faces[face].astype(np.int64), score=float(score),
                    torso=torso, latent=bodies.latents[best_latent],
                    faces=faces.astype(np.int64), face_scores=per_face)


def _checked_boxes(faces) -> np.ndarray:
    faces = np.asarray(faces, np.float64).reshape(-1, 4)
    if len(faces) == 0:
        raise AutoInitError("no face boxes to search under")
    return faces


def _checked_foreground(foreground) -> Array:
    foreground = jnp.asarray(np.asarray(foreground, np.float32))
    if foreground.ndim != 2:
        raise ValueError(f"foreground must be a (height, width) mask, got {foreground.shape}")
    return foreground


def search_poses(prior: GPLVM, template: SPMTemplate, foreground: np.ndarray,
                 faces: np.ndarray, *, scales: np.ndarray = np.geomspace(2.0, 5.0, 7),
                 offsets: np.ndarray = np.array([-0.25, 0.0, 0.25]), max_latents: int = 600,
                 resolution: int = 40) -> AutoInit:
    """Score every (face, training latent, scale, offset) candidate; return the best.

    The window is fixed in face sizes (the largest scale's body window), so a candidate drawn
    too small leaves the rest of the person unexplained and scores low.

    Args:
        prior: a trained GPLVM of SPM link features (``jaxtrack.priors.poses``).
        template: the SPM template of its poses.
        foreground: ``(height, width)`` foreground mask or probability (0–1).
        faces: ``(faces, 4)`` boxes ``(x, y, width, height)``.
        scales: torso lengths tried, in face-box sizes (``max(width, height)``).
        offsets: head positions tried, in face-box sizes from the box centre (x and y).
        max_latents: training latents tried (evenly spaced over the training set).
        resolution: window points per side.
    """
    faces, foreground = _checked_boxes(faces), _checked_foreground(foreground)
    bodies = _bodies(prior, template, scales, max_latents, resolution)
    return _search(bodies, foreground, faces, np.asarray(offsets))


def auto_initialise(prior: GPLVM, template: SPMTemplate, frame_rgb: np.ndarray,
                    foreground: np.ndarray, *, faces: np.ndarray | None = None,
                    min_score: float = 0.35, use_blob_heads: bool = True,
                    scales: np.ndarray = np.geomspace(2.0, 5.0, 7),
                    offsets: np.ndarray = np.array([-0.25, 0.0, 0.25]), max_latents: int = 600,
                    resolution: int = 40) -> AutoInit:
    """Find the face(s) in ``frame_rgb`` and the prior's pose that best explains the frame.

    Face boxes and, unless ``use_blob_heads`` is False, head boxes guessed from the top of the
    largest foreground blobs (``jaxtrack.vision.head_boxes``) are both searched, and the box
    under which a pose explains the foreground best wins: Haar faces in real footage are often
    missed (blurred, turned away) or false (faces on the background), and a false face rarely
    has a body below it. :attr:`AutoInit.source` says which kind of box won.

    Args:
        prior, template: the GPLVM and its SPM template.
        frame_rgb: ``(height, width, 3)`` uint8 RGB first frame.
        foreground: ``(height, width)`` its foreground mask (``jaxtrack.vision.foreground_mask``).
        faces: face boxes to use instead of detecting them (e.g. from another detector).
        min_score: the least Dice overlap accepted as "a person is there".
        use_blob_heads: also search head boxes from foreground blobs.
        scales, offsets, max_latents, resolution: as for :func:`search_poses`; the candidate
            bodies are drawn once and scored under both kinds of box.

    Raises:
        AutoInitError: no face or person blob was found, or no pose under any box reaches
            ``min_score``; the message says which and how many boxes were tried.
        FaceDetectorUnavailableError: this OpenCV has no Haar cascades.
    """
    from jaxtrack.vision import face_candidates, head_boxes

    frame_rgb = np.asarray(frame_rgb)
    foreground = np.asarray(foreground)
    if foreground.shape != frame_rgb.shape[:2]:
        raise ValueError(f"foreground {foreground.shape} and frame {frame_rgb.shape[:2]} differ "
                         f"in size")
    if faces is None:
        faces = face_candidates(frame_rgb)
    faces = np.asarray(faces).reshape(-1, 4)
    if not foreground.any():
        raise AutoInitError(
            f"{len(faces)} face candidate(s) found, but the first frame has no foreground "
            f"(nothing differs from the background), so there is no person to initialise on")
    # head_boxes' default smallest blob is a fraction of the frame: people far away in a large
    # frame fall below it, so the least blob is given in pixels
    blobs = (head_boxes(foreground, max_people=MAX_PEOPLE,
                        min_area=min(0.005, MIN_PERSON_PIXELS / foreground.size))
             if use_blob_heads else np.zeros((0, 4)))
    if not len(faces) and not len(blobs):
        raise AutoInitError(f"no face (OpenCV Haar cascades, frontal and profile) and no person-"
                            f"sized foreground blob (at least {MIN_PERSON_PIXELS} pixels) in the "
                            f"first frame; give the first pose by hand")
    bodies = _bodies(prior, template, scales, max_latents, resolution)
    weights = _checked_foreground(foreground)
    # the best box of each kind; a blob head must beat the faces outright
    results = [replace(_search(bodies, weights, _checked_boxes(boxes), np.asarray(offsets)),
                       source=source)
               for boxes, source in ((faces, "face"), (blobs, "foreground")) if len(boxes)]
    best = max(results, key=lambda result: result.score)
    if best.score < min_score:
        raise AutoInitError(
            f"{len(faces)} face candidate(s) found, but no pose under any face or foreground "
            f"blob explains the foreground (best overlap {best.score:.2f} < {min_score}); "
            f"give the first pose by hand")
    return best
