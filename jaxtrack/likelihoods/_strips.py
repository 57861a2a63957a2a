"""Where the limb strips lie: the segments, and the sample points of one pose's strips.

A strip is laid along a body segment, in the segment's own coordinates (Cham & Rehg 1999;
Ju, Black & Yacoob 1996): point ``[s, i, j]`` lies at fraction ``u_i`` along segment ``s``
(from ``−before`` to ``1 + after`` of :data:`LIMB_SEGMENTS`) and ``v_j ∈ [−1, 1]`` half widths
across it,

    p_sij = start_s + u_i (end_s − start_s) + v_j w_s n̂_s,

``n̂_s`` the segment's unit normal and the half width ``w_s`` a fraction of the pose's spine
length (neck to pelvis, :func:`spine_length`), so the strips turn, stretch and scale with the
body. Both the strips' NCC (:mod:`jaxtrack.likelihoods.limbs`) and their borders' edge term
(:mod:`jaxtrack.likelihoods.edges`) read these points.
"""

from __future__ import annotations

import functools

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.body import SPM_MARKERS
from jaxtrack.likelihoods._base import NUM_MARKERS, SPINE_MARKERS, check_markers
from jaxtrack.likelihoods._sampling import float_dtype

__all__ = ["LIMB_SEGMENTS", "PART_MARKERS", "STRIP_ENDS", "point_coordinates",
           "segment_axes", "select_segments", "spine_length", "squared_segment_distances",
           "strip_points"]

_marker = SPM_MARKERS.index

LIMB_SEGMENTS: tuple[tuple[str, int, int, float, float], ...] = (
    # name, start marker, end marker (SPM_MARKERS indices), extension before start and after
    # end as fractions of the segment's length
    ("head", _marker("head"), _marker("neck"), 0.3, 0.0),
    ("upper spine", _marker("neck"), _marker("thorax"), 0.0, 0.0),
    ("lower spine", _marker("thorax"), _marker("pelvis"), 0.0, 0.0),
    ("right upper arm", _marker("right_shoulder"), _marker("right_elbow"), 0.0, 0.0),
    ("right forearm and hand", _marker("right_elbow"), _marker("right_wrist"), 0.0, 0.35),
    ("left upper arm", _marker("left_shoulder"), _marker("left_elbow"), 0.0, 0.0),
    ("left forearm and hand", _marker("left_elbow"), _marker("left_wrist"), 0.0, 0.35),
    ("shoulders", _marker("right_shoulder"), _marker("left_shoulder"), 0.0, 0.0),
    ("hips", _marker("right_hip"), _marker("left_hip"), 0.0, 0.0),
)
"""The strips: the three spine segments, both arms (forearms carried over the hand), and the
shoulder and hip lines, which fix the torso's width and turn."""

STRIP_ENDS: tuple[tuple[int, int], ...] = tuple((segment[1], segment[2])
                                               for segment in LIMB_SEGMENTS)
"""The markers (``SPM_MARKERS`` indices) each strip reads other than through the spine length:
its two ends."""
PART_MARKERS: tuple[tuple[int, ...], ...] = tuple((*ends, *SPINE_MARKERS) for ends in STRIP_ENDS)
"""The markers (``SPM_MARKERS`` indices) each strip's terms depend on: its two ends, and the
neck and pelvis, whose distance sets its width. What the arm search and the refinement's
Gauss–Newton Jacobian use to touch only the strips a change reaches."""
_STARTS = tuple(segment[1] for segment in LIMB_SEGMENTS)
_ENDS = tuple(segment[2] for segment in LIMB_SEGMENTS)


def select_segments(segments: tuple[int, ...] | None) -> tuple[int, ...]:
    """The strips a static ``segments`` argument picks (None: all of :data:`LIMB_SEGMENTS`)."""
    if segments is None:
        return tuple(range(len(LIMB_SEGMENTS)))
    segments = tuple(int(index) for index in segments)
    if not segments or any(not 0 <= index < len(LIMB_SEGMENTS) for index in segments):
        raise ValueError(f"segments must be indices into LIMB_SEGMENTS (0 to "
                         f"{len(LIMB_SEGMENTS) - 1}), got {segments}")
    return segments


def segment_axes(markers: Float[Array, "markers 2"], segments: tuple[int, ...] | None = None
                 ) -> Float[Array, "segments 2"]:
    """Each picked strip's axis, its end marker minus its start marker."""
    chosen = select_segments(segments)
    return (markers[jnp.asarray([_ENDS[index] for index in chosen])]
            - markers[jnp.asarray([_STARTS[index] for index in chosen])])


def squared_segment_distances(points: Float[Array, "points 2"], starts: Float[Array, "segments 2"],
                              ends: Float[Array, "segments 2"]) -> Float[Array, "points segments"]:
    """The squared distance from each point to each segment ``starts[s]``–``ends[s]`` (a
    degenerate segment is its start point)."""
    direction = ends - starts
    offset = points[:, None, :] - starts[None]
    length2 = jnp.maximum(jnp.sum(direction * direction, axis=-1), 1e-12)
    along = jnp.clip(jnp.sum(offset * direction[None], axis=-1) / length2, 0.0, 1.0)
    closest = starts[None] + along[..., None] * direction[None]
    difference = points[:, None, :] - closest
    return jnp.sum(difference * difference, axis=-1)


def spine_length(markers: Float[Array, "markers 2"], ends: tuple[int, int] = SPINE_MARKERS
                 ) -> Float[Array, ""]:
    """The neck–pelvis distance of ``(12, 2)`` markers (``ends``: the two markers, neck and
    pelvis by default): the length the strips' widths (and the edge term's scale) are
    fractions of."""
    return jnp.sqrt(jnp.sum((markers[ends[1]] - markers[ends[0]]) ** 2))


@functools.cache
def _point_matrix(along: int, across: int, dtype: str, segments: tuple[int, ...] | None = None
                  ) -> np.ndarray:
    """The constant ``(markers + segments, points)`` matrix of :func:`point_coordinates`.

    Its first :data:`NUM_MARKERS` rows put each point at its fraction of its segment,
    ``start + u (end − start)`` (linear in the markers); the last rows add ``v ×`` the
    segment's scaled normal. Points are ordered ``(segments, along, across)``; ``segments``
    (indices into :data:`LIMB_SEGMENTS`, None for all) picks the strips.
    """
    chosen = select_segments(segments)
    fraction = np.linspace(0, 1, along)
    v = np.linspace(-1, 1, across)
    matrix = np.zeros((NUM_MARKERS + len(chosen), len(chosen), along, across))
    for row, index in enumerate(chosen):
        _, start, end, before, after = LIMB_SEGMENTS[index]
        u = -before + fraction * (1 + before + after)
        matrix[start, row] += (1 - u)[:, None]
        matrix[end, row] += u[:, None]
        matrix[NUM_MARKERS + row, row] = v[None, :]
    return matrix.reshape(NUM_MARKERS + len(chosen), -1).astype(dtype)


def point_coordinates(markers: Float[Array, "markers 2"], along: int, across: int,
                      width: Float[ArrayLike, "*segments"],
                      segments: tuple[int, ...] | None = None,
                      spine: Float[ArrayLike, ""] | None = None) -> Float[Array, "2 points"]:
    """x and y of the strips' sample points (of the strips ``segments`` picks), ordered
    ``(segments, along, across)``.

    ``width`` is a scalar or one half width per picked strip, as fractions of ``spine`` (None:
    the markers' own :func:`spine_length`). One ``(2, 21) @ (21, points)`` matrix product per
    pose (:func:`_point_matrix`), which XLA on CPU runs several times faster than the same
    points broadcast elementwise into ``(segments, along, across, 2)`` (a trailing axis of 2
    defeats its vectorisation).
    """
    check_markers(markers)
    dtype = float_dtype(markers)
    markers = markers.astype(dtype)
    axis = segment_axes(markers, segments)  # (segments, 2)
    spine = spine_length(markers) if spine is None else jnp.asarray(spine, dtype)
    length = jnp.sqrt(jnp.sum(axis**2, axis=-1))
    # the unit normal times the half width; a segment of zero length gets a zero normal (its
    # strip collapses to a line, still a valid, if uninformative, sample)
    scale = jnp.asarray(width, dtype) * spine / jnp.where(length > 0, length, jnp.inf)
    normal = jnp.stack([-axis[:, 1] * scale, axis[:, 0] * scale])  # (2, segments)
    coefficients = jnp.concatenate([markers.T, normal], axis=1)
    matrix = _point_matrix(along, across, jnp.dtype(dtype).name, segments)
    return coefficients @ jnp.asarray(matrix)


def strip_points(markers: Float[Array, "markers 2"], along: int, across: int,
                 width: Float[ArrayLike, "*segments"], segments: tuple[int, ...] | None = None,
                 spine: Float[ArrayLike, ""] | None = None
                 ) -> tuple[Float[Array, "segments along across"],
                            Float[Array, "segments along across"]]:
    """x and y of :func:`point_coordinates`, each ``(segments, along, across)``."""
    x, y = point_coordinates(markers, along, across, width, segments, spine)
    shape = (len(select_segments(segments)), along, across)
    return x.reshape(shape), y.reshape(shape)
