"""Normalised cross-correlation of limb-aligned strips: the likelihood that separates poses.

Tian et al.'s eq. 7 (:mod:`jaxtrack.likelihoods.ncc`) correlates small square patches cut at the
12 markers; a patch at a joint sees a few pixels of sleeve that slide and turn under it as the
limb moves, so those patches barely tell poses apart on rendered frames.

Here the templates are strips laid along the body's segments, in the segment's own coordinates
(as Cham & Rehg's 1999 Scaled Prismatic Model tracker and Ju, Black & Yacoob's 1996 cardboard
people warp a template per limb): ``along × across`` sample points from the segment's start to
its end (the forearm carried on past the wrist over the hand, the neck past the head's marker),
``across`` points spanning ``±half_width`` pixels either side of the axis. The strip turns,
stretches and foreshortens with its segment, so the frame-0 template keeps matching the limb in
any orientation, and a limb that is a few degrees off puts half its strip on background:

    log p(z | y) = −λ Σ_s (1 − NCC_s(y)),

the form of eq. 7 with one term per strip. The half width is a fixed fraction of the spine (neck
to pelvis) of the pose being scored, so the strips scale with the body. One pose reads
``segments × along × across`` pixels (9 × 12 × 7 = 756 by default), with gathers only.

How much better the strips separate poses than the patches, and what they cost: see
docs/likelihoods.md, "Limb strips".
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.likelihoods._base import SPINE_MARKERS, PartTemplates, check_markers
from jaxtrack.likelihoods._correlation import correlation, normalise, template_residuals
from jaxtrack.likelihoods._sampling import float_dtype, sample_points
from jaxtrack.likelihoods._strips import (
    LIMB_SEGMENTS,
    PART_MARKERS,
    STRIP_ENDS,
    point_coordinates,
    select_segments,
    spine_length,
    strip_points,
)
from jaxtrack.vision.observations import images_of

__all__ = [
    "DEFAULT_LIMB_SHARPNESS",
    "DEFAULT_STRIP_WIDTH",
    "LIMB_SEGMENTS",
    "LimbTemplates",
    "PART_MARKERS",
    "STRIP_ENDS",
    "limb_ncc_log_likelihood",
    "limb_ncc_scores",
    "limb_points",
    "make_limb_templates",
    "spine_length",
]

DEFAULT_STRIP_WIDTH = 0.1
"""Half width of a strip as a fraction of the spine (neck–pelvis) length: about an arm's
width; strips much wider are dominated by background (see docs/likelihoods.md, "Limb
strips")."""

DEFAULT_LIMB_SHARPNESS = 4.0
"""λ for the 9 strips: between weights spread too evenly and too few effective particles
(see docs/likelihoods.md, "Limb strips")."""


def limb_points(
    markers_2d: Float[ArrayLike, "markers 2"],
    *,
    along: int = 12,
    across: int = 7,
    width: float | Float[ArrayLike, ""] = DEFAULT_STRIP_WIDTH,
) -> Float[Array, "segments along across 2"]:
    """The ``(x, y)`` sample points of every strip of one pose.

    Point ``[s, i, j]`` lies at fraction ``u_i`` along segment ``s`` (from ``−before`` to
    ``1 + after`` of :data:`LIMB_SEGMENTS`) and ``v_j ∈ [−1, 1]`` half widths across it, the
    half width being ``width ×`` the pose's neck–pelvis distance (the strips' geometry:
    :mod:`jaxtrack.likelihoods._strips`).

    Args:
        markers_2d: ``(12, 2)`` pixel markers in ``SPM_MARKERS`` order.
        along: static sample count along each strip.
        across: static sample count across each strip.
        width: half width over spine length.
    """
    points = point_coordinates(jnp.asarray(markers_2d), along, across, width)
    return points.T.reshape(len(LIMB_SEGMENTS), along, across, 2)


def _strips(image: Array, markers: Array, along: int, across: int, width, nearest: bool,
            segments: tuple[int, ...] | None = None, spine: Array | None = None) -> Array:
    """The grey frame at the strips' sample points, ``(segments, along, across)`` (the strips
    ``segments`` picks; ``spine`` the length the width is a fraction of, None: the markers'
    own), at the nearest pixel or bilinearly."""
    image = jnp.asarray(images_of(image))
    if image.ndim != 2:
        raise ValueError(f"image must be (height, width) grey levels, got shape {image.shape}; "
                         f"convert colour frames with jaxtrack.vision.to_grey")
    markers = jnp.asarray(markers)
    dtype = float_dtype(image, markers)
    x, y = strip_points(markers.astype(dtype), along, across, width, segments, spine)
    return sample_points(image.astype(dtype), x, y, nearest)


class LimbTemplates(PartTemplates):
    """Limb-strip templates for :func:`limb_ncc_scores`: a :class:`PartTemplates` whose parts
    are the strips.

    Attributes:
        strips: ``(segments, along, across)`` zero-mean, unit-norm strips of the reference frame
            (all zeros for a flat one: that segment then always scores 0).
        width: half width over spine length (an array: it may be learned or changed).
    """

    strips: Float[Array, "segments along across"]
    width: Float[Array, ""]

    def __check_init__(self):
        if self.strips.ndim != 3 or self.strips.shape[0] != len(LIMB_SEGMENTS):
            raise ValueError(f"strips must be ({len(LIMB_SEGMENTS)}, along, across), got "
                             f"{self.strips.shape}")

    @property
    def along(self) -> int:
        return self.strips.shape[1]

    @property
    def across(self) -> int:
        return self.strips.shape[2]

    def log_likelihood(self, markers_2d, image, sharpness, nearest: bool = True) -> Array:
        """:func:`limb_ncc_log_likelihood` (the interface the trackers call)."""
        return limb_ncc_log_likelihood(markers_2d, image, self, sharpness, nearest=nearest)

    def residuals(self, markers_2d, image, sharpness, spine=None) -> Array:
        """``√λ (ŝ − t̂)`` over all strips (bilinear): half its squared norm is
        ``λ Σ_s (1 − NCC_s)``, the cost as a sum of squares for Gauss–Newton. ``spine``: the
        length the strips' widths are fractions of, None: the markers' own."""
        strips = _strips(image, markers_2d, self.along, self.across, self.width, nearest=False,
                         spine=spine)
        return template_residuals(strips, self.strips, sharpness)

    @property
    def part_markers(self) -> tuple[tuple[int, ...], ...]:
        """The markers each part (strip) of the likelihood depends on: :data:`PART_MARKERS`."""
        return PART_MARKERS

    @property
    def spine_markers(self) -> tuple[int, int]:
        """Neck and pelvis: every part also reads their distance (the strips' widths)."""
        return SPINE_MARKERS

    @property
    def direct_part_markers(self) -> tuple[tuple[int, ...], ...]:
        """The markers each part reads other than through the spine length
        (:data:`STRIP_ENDS`): with ``spine`` given, row p of :meth:`part_residuals` depends
        only on these and on ``spine``."""
        return STRIP_ENDS

    def part_log_likelihoods(self, markers_2d, image, sharpness, nearest: bool = True,
                             parts: tuple[int, ...] | None = None) -> Array:
        """``−λ (1 − NCC_s)`` of each strip ``parts`` picks (static indices into
        :data:`LIMB_SEGMENTS`; None: all): the terms :meth:`log_likelihood` sums, computed
        for the picked strips alone."""
        strips = _strips(image, markers_2d, self.along, self.across, self.width, nearest, parts)
        scores = correlation(strips, self.strips[jnp.asarray(select_segments(parts))])
        return -jnp.asarray(sharpness, scores.dtype) * (1 - scores)

    def part_residuals(self, markers_2d, image, sharpness, spine=None) -> Array:
        """:meth:`residuals` grouped by strip, ``(segments, along · across)``: each row
        depends only on the markers :attr:`part_markers` names for it (with ``spine`` given:
        on those :attr:`direct_part_markers` names, and on ``spine``)."""
        return self.residuals(markers_2d, image, sharpness, spine).reshape(len(LIMB_SEGMENTS),
                                                                            -1)


def make_limb_templates(
    image: Float[ArrayLike, "height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
    *,
    along: int = 12,
    across: int = 7,
    width: float = DEFAULT_STRIP_WIDTH,
) -> LimbTemplates:
    """Cut the strips of a reference frame (bilinearly) at its known markers.

    Args:
        image: ``(height, width)`` grey reference frame.
        markers_2d: ``(12, 2)`` its markers in ``SPM_MARKERS`` order.
        along: sample count along each strip (at least 2).
        across: sample count across each strip (at least 3).
        width: half width over spine length.
    """
    if int(along) != along or int(across) != across or along < 2 or across < 3:
        raise ValueError(f"along must be an integer ≥ 2 and across ≥ 3, got {along}, {across}")
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"width must be a positive fraction of the spine, got {width}")
    markers = jnp.asarray(markers_2d)
    check_markers(markers, name="the reference markers", finite=True)
    strips = _strips(image, markers, int(along), int(across), width, nearest=False)
    strips, _ = normalise(strips)
    return LimbTemplates(strips=strips, width=jnp.asarray(width, strips.dtype))


def limb_ncc_scores(
    markers_2d: Float[ArrayLike, "markers 2"],
    image: Float[ArrayLike, "height width"],
    templates: LimbTemplates,
    *,
    nearest: bool = True,
) -> Float[Array, " segments"]:
    """NCC of each strip of one pose in ``image`` with its template.

    Args:
        markers_2d: ``(12, 2)`` pixel markers of one pose (vmap over particles).
        image: ``(height, width)`` grey frame.
        templates: from :func:`make_limb_templates`.
        nearest: read the nearest pixel of each sample point (fast, for filters) rather than
            interpolating bilinearly (smooth in the markers, for gradients).

    Returns:
        ``(segments,)`` in [−1, 1]; 0 for a flat strip; never NaN; invariant to
        ``image → a · image + b`` for ``a > 0``.
    """
    strips = _strips(image, markers_2d, templates.along, templates.across, templates.width,
                     nearest)
    return correlation(strips, templates.strips)


def limb_ncc_log_likelihood(
    markers_2d: Float[ArrayLike, "markers 2"],
    image: Float[ArrayLike, "height width"],
    templates: LimbTemplates,
    sharpness: float | Float[ArrayLike, ""] = DEFAULT_LIMB_SHARPNESS,
    *,
    nearest: bool = True,
) -> Float[Array, ""]:
    """``−λ Σ_s (1 − NCC_s)``: eq. 7's form over limb strips (see the module docstring)."""
    scores = limb_ncc_scores(markers_2d, image, templates, nearest=nearest)
    return -jnp.asarray(sharpness, scores.dtype) * jnp.sum(1 - scores)
