"""Limb strips plus their outlines: NCC of the strips and the distance of their borders to edges
that run along the limb.

The limb strips of :mod:`jaxtrack.likelihoods.limbs` match frame-0 templates, which drift as a
limb turns in depth; a limb's outline does not. Here each strip's two long borders (``v = ±1``,
``along − 2`` points each, the ends left out where limbs meet) are scored by their distance to
the nearest Canny edge of the frame, a truncated quadratic as in chamfer matching, and a border
point whose nearest edge does not run along the limb (its tangent more than ``edge_tolerance``
from the strip's axis) counts as on no edge at all (oriented chamfer matching); the form of
Tian et al.'s eq. 7 plus an edge term:

    log p(z | y) = −λ Σ_s (1 − NCC_s(y)) − κ Σ_s mean_i e_i(y)²,
    e_i = min(d_i / σ, 2) if |sin(φ_i − θ_s)| ≤ sin(tolerance) else 2,

``d_i`` the distance from border point i to the nearest edge pixel, ``φ_i`` that pixel's
tangent direction, ``θ_s`` the strip's axis, σ a fixed fraction of the pose's spine (neck to
pelvis), like the strips' width. The edge term needs no template, so it cannot drift.

The borders are scored where the limb's outline is, not where the strip ends: at
initialisation each strip's border half width is fitted to the reference frame's edges at its
known pose (:func:`fit_border_widths`: 0.5–1.5 × the strips' half width, taken where it lowers
the strip's mean ``e_i²`` by at least 0.5; the spine, whose borders lie on no outline, keeps
its width); the NCC strips keep theirs, so that each still holds the limb's outline against its
surroundings.

**The foreground term** (given a ``background``, a static camera's grey background: the
video's median, :func:`jaxtrack.vision.median_grey_background`). The strips and the edges still
match a limb's frame-0 place after the limb has left it; a median background has no arm where
the arm moves about, so the place it left looks like the background and the place it is does
not:

    log p(z | y) = … − μ Σ_{s ∈ arms} b_s,
    b_s = the fraction of strip s's centre line (its middle sample across, ``along`` points)
          where |y − background| ≤ ``foreground_threshold``,

on the four arm strips only (:data:`FOREGROUND_SEGMENTS`). ``b_s`` is piecewise constant in
the pose; Gauss–Newton sees it in the cost, not in the Jacobian. Without a background there is
no term. Where the person never leaves their place the median holds them; a person segmenter's
mask per frame then says what the background cannot: an observation with a fourth channel, the
mask (:func:`jaxtrack.vision.edge_observations` ``masks=``), makes ``b_s`` the fraction of the
centre line where the mask is below one half, frame by frame, with or without a background.

**The coverage term** (``coverage_weight`` ν > 0, with a mask channel; off by default). The
foreground term says where the arms must not be — off the person — but not where they must: a
pose whose arms lie inside the silhouette, on the chest, is not charged for leaving the real
arms unexplained. The coverage term charges the person's mask for what the body does not
explain, as silhouette trackers' two-sided terms do:

    log p(z | y) = … − ν Σ_g m_g c_g(y)² / max(Σ_g m_g, 1),
    c_g = min(d_g / (ρ · spine), 2),

over a fixed grid of points g across the frame (:data:`COVERAGE_GRID` along its longer side),
``m_g`` the mask there (0 or 1; 0 beyond :data:`COVERAGE_DEPTH` spines from the neck along
the spine, the legs, which an upper-body pose does not explain), ``d_g`` the distance from g
to the nearest limb segment (the strips' axes, the head's and the hands' extensions
included), ρ = :data:`COVERAGE_SCALE`. Off by default: it did not keep the real videos'
person tracked (docs/likelihoods.md). It
depends on the whole pose, not on one strip, so it is no part's term:
:meth:`EdgeLimbTemplates.whole_pose_log_likelihood` scores it, :meth:`log_likelihood` and
:meth:`residuals` include it (the residuals with their gradient), the part functions leave it
out, and the refinement solves with the whole residual vector where it is on.

**The keypoint term** (``keypoint_weight`` η > 0, with keypoints; off by default). A
per-frame detector's keypoints (:mod:`jaxtrack.vision.keypoints`: the 12 markers' positions
``k_j`` and confidences ``w_j`` in [0, 1]) say where the joints are. The term is the
detector's error model: a bivariate Cauchy (Student's t with one degree of freedom) about each
keypoint, a Gaussian core whose tails let a wrong detection cost only logarithmically, so a
tracker keeps a pull towards the keypoints however far it is and is not dragged by one wrong
keypoint. A detector may also swap the person's left and right (seen from behind, or
turning); the tracker, which knows which side was which a frame ago, should not follow it, so
the term scores the better of the two assignments, the keypoints as given and with left and
right exchanged (``π``, :data:`MIRRORED_MARKERS`):

    log p(z | y) = … − η min_{π ∈ {id, mirror}} Σ_j w_π(j) log(1 + q_j(y)²),
    q_j = ‖m_j − k_π(j)‖ / (τ_j · s · spine),

``τ_j`` = :data:`KEYPOINT_SCALES` (the detector's scale per marker, fitted on validation
subjects), ``s`` = ``keypoint_scale`` (a factor on them, 1 by default); η = 3/2 is the
bivariate Cauchy density's own exponent (:data:`CAUCHY_KEYPOINT_WEIGHT`). The assignment is
piecewise constant in the pose (its choice carries no gradient). Like the coverage term, the
keypoint term is no part's (:meth:`EdgeLimbTemplates.whole_pose_log_likelihood`; the
refinement takes its 12 residuals apart from the parts').

Observations are ``(3, height, width)``: the grey frame, its edge distance map and the
nearest edge's tangent direction (:func:`jaxtrack.vision.edge_observations` makes them for a
sequence), or ``(4, height, width)`` with the person's mask as the fourth; the keypoint term
reads a detector's keypoints, which travel beside the image channels in an
:class:`jaxtrack.vision.ImageObservation` (:func:`jaxtrack.vision.image_observations`). Trackers
observe grey frames themselves (``Tracker.observe``), chunk by chunk in
``jaxtrack.trackers.track``.

Why, and the measurements behind each choice: see docs/likelihoods.md, "Edges".
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.body import SPM_MARKERS
from jaxtrack.likelihoods._base import SPINE_MARKERS, PartTemplates, check_markers
from jaxtrack.likelihoods._correlation import correlation, template_residuals
from jaxtrack.likelihoods._sampling import (
    bilinear_sample,
    float_dtype,
    nearest_pixels,
    sample_points,
)
from jaxtrack.likelihoods._strips import (
    LIMB_SEGMENTS,
    PART_MARKERS,
    STRIP_ENDS,
    segment_axes,
    select_segments,
    spine_length,
    squared_segment_distances,
    strip_points,
)
from jaxtrack.likelihoods.limbs import DEFAULT_STRIP_WIDTH, LimbTemplates, make_limb_templates
from jaxtrack.vision.observations import images_of, keypoints_of

__all__ = ["COVERAGE_DEPTH", "COVERAGE_GRID", "COVERAGE_SCALE", "DEFAULT_BORDER_MARGIN",
           "DEFAULT_BORDER_SCALES", "DEFAULT_EDGE_SCALE", "DEFAULT_EDGE_TOLERANCE",
           "DEFAULT_EDGE_WEIGHT", "DEFAULT_FOREGROUND_THRESHOLD", "DEFAULT_FOREGROUND_WEIGHT",
           "CAUCHY_KEYPOINT_WEIGHT", "EdgeLimbTemplates", "FOREGROUND_SEGMENTS", "KEYPOINT_SCALES",
           "MIRRORED_MARKERS",
           "fit_border_widths", "limb_edge_distances", "make_edge_limb_templates"]

DEFAULT_EDGE_WEIGHT = 1.0
"""κ: nats per strip whose border lies on no edge at all (the penalty saturates at 4κ · 9).
First chosen against 0.5 and 2 on the test subject's takes (cmu_1006; see docs/likelihoods.md,
"Edges"), then kept against them on the validation subjects (docs/trackers.md, "Why the
defaults are what they are")."""

DEFAULT_EDGE_SCALE = 0.025
"""σ as a fraction of the spine (neck–pelvis) length: ~3 px for a 130-px spine."""

DEFAULT_EDGE_TOLERANCE = 45.0
"""Largest angle in degrees between a strip's axis and the nearest edge's tangent for a border
point to count as on the limb's outline (90: any edge); first chosen on the test subject's takes
(cmu_1006), where ±45° lost the fewest runs against ±30° and 90° (see docs/likelihoods.md,
"Edges"); kept against both on the validation subjects
(docs/trackers.md, "Why the defaults are what they are")."""

DEFAULT_BORDER_SCALES = (0.5, 0.6, 0.7, 0.8, 0.9, 1.1, 1.2, 1.3, 1.4, 1.5)
"""Scales of the strips' half width tried for each strip's scored borders at initialisation
(:func:`fit_border_widths`)."""

DEFAULT_BORDER_MARGIN = 0.5
"""How much lower (in mean ``e_i²``, which saturates at 4) a strip's border cost must be at a
fitted half width than at the strips' own for the fitted one to be taken."""

DEFAULT_FOREGROUND_WEIGHT = 2.0
"""μ: nats per arm strip whose centre line lies wholly on the background (the foreground term,
module docstring); chosen on the Bandai validation splits (docs/likelihoods.md, "Edges") and
kept against 1 and 4 on the validation subjects (docs/trackers.md)."""

DEFAULT_FOREGROUND_THRESHOLD = 20 / 255
"""How far (grey levels in [0, 1]) a pixel must differ from the background to be foreground."""

FOREGROUND_SEGMENTS = tuple(index for index, segment in enumerate(LIMB_SEGMENTS)
                            if "arm" in segment[0])
"""The strips the foreground term scores (indices into ``LIMB_SEGMENTS``): the four arm strips.
The torso of a subject who stands still is part of a median background, so the spine's,
shoulders' and hips' strips would be scored against nothing."""

COVERAGE_GRID = 48
"""Grid points of the coverage term along the frame's longer side (the other side in
proportion): about 1 300 points on a 544 × 960 frame."""

COVERAGE_SCALE = 0.25
"""ρ: the coverage term's distance scale as a fraction of the spine (neck–pelvis): a mask
point a quarter of the spine from the nearest limb axis costs one unit, twice that or more
four (the cap)."""

COVERAGE_DEPTH = 1.1
"""The coverage term counts mask points down to this far along the spine from the neck (1: the
pelvis): below that are the legs, which an upper-body pose does not explain."""

KEYPOINT_SCALES = (0.082, 0.037, 0.018, 0.051, 0.051, 0.027, 0.039, 0.028, 0.049, 0.029, 0.033,
                   0.047)
"""τ_j: the keypoint term's scale per marker (``SPM_MARKERS`` order) as a fraction of the spine
(neck–pelvis), the detector's error scale: the median distance between MediaPipe Pose's
keypoints and the true markers over √3 (a bivariate Cauchy's median radius is √3 times its
scale), on the validation subjects' rendered gesture clips (``python -m
papers.tian2005.keypoint_term``, 2026-11-27: 3 Bandai clips × 2 views × 2 backgrounds, 60
frames each; papers/tian2005/history.md). The head is the least sure: MediaPipe has no such
marker, and it is placed from the shoulders and ears (``jaxtrack/vision/mediapipe.py``)."""

CAUCHY_KEYPOINT_WEIGHT = 1.5
"""η = 3/2, the exponent of the bivariate Cauchy density ``(1 + q²)^(−3/2)``: the keypoint term
as the detector's error model. The weight the command line and the benchmarks give the term
when keypoints are given; kept against 5 and 15 on the validation subjects by the refined
trackers' mean error (``python -m papers.tian2005.keypoint_term --estimates refined
--keypoint-weights 1.5 5 15``, 2026-11-27; papers/tian2005/history.md)."""

MIRRORED_MARKERS = tuple(SPM_MARKERS.index(name.replace("left", "@").replace("right", "left")
                                           .replace("@", "right")) for name in SPM_MARKERS)
"""``SPM_MARKERS`` with the person's left and right exchanged (the keypoint term's second
assignment)."""

_CHANNELS = 3
MASK_CHANNEL = 3
"""The observation channel that holds the person's mask, where there is one."""


def _check_observation(observation, keypoints: bool = False) -> Array:
    """The image channels of ``observation`` (an :class:`jaxtrack.vision.ImageObservation` or
    a bare ``(3 or 4, height, width)`` array), refused unless they are the grey frame and its
    edge maps (with the person's mask or not) and, when ``keypoints``, the observation carries
    a detector's keypoints."""
    images = jnp.asarray(images_of(observation))
    if images.ndim != 3 or images.shape[0] not in (_CHANNELS, _CHANNELS + 1):
        raise ValueError("observation must be (3, height, width): the grey frame, its edge "
                         "distance map and the edges' orientation (edge_observations), or "
                         "(4, height, width) with the person's mask, got shape "
                         f"{images.shape}")
    if keypoints and keypoints_of(observation) is None:
        raise ValueError("the keypoint term (keypoint_weight > 0) reads a detector's keypoints: "
                         "give an ImageObservation with keypoints "
                         "(jaxtrack.vision.image_observations(..., keypoints=...))")
    return images


def _edge_maps_of(observation) -> Array:
    """The grey frame and its edge maps, the first three channels of an observation with or
    without a mask (all a reference frame is read for)."""
    images = jnp.asarray(images_of(observation))
    if images.ndim != 3 or not _CHANNELS <= images.shape[0] <= _CHANNELS + 1:
        raise ValueError(f"observation must be (3, height, width): the grey frame, its edge "
                         f"distance map and the edges' orientation (edge_observations), with "
                         f"the person's mask after them or not, got shape {images.shape}")
    return images[:_CHANNELS]


def _borders(values: Array) -> Array:
    """Per-point values of the strips, ``(segments, along, across)``, on their two long borders
    (the first and last point across) without the end points along: ``(segments, 2 (along −
    2))``."""
    return values[:, 1:-1, :: values.shape[2] - 1].reshape(values.shape[0], -1)


def _axis_angles(markers: Array, segments: tuple[int, ...] | None = None) -> Array:
    """Direction of each strip's axis (start to end marker), ``(segments,)`` radians."""
    axis = segment_axes(markers, segments)
    return jnp.arctan2(axis[:, 1], axis[:, 0])


def limb_edge_distances(
    markers_2d: Float[ArrayLike, "markers 2"],
    distance_map: Float[ArrayLike, "height width"],
    *,
    along: int = 12,
    width: float | Float[ArrayLike, ""] = DEFAULT_STRIP_WIDTH,
    nearest: bool = True,
) -> Float[Array, "segments points"]:
    """Distance to the nearest edge at each border point of each strip of one pose (pixels)."""
    markers = jnp.asarray(markers_2d)
    distance_map = jnp.asarray(distance_map)
    dtype = float_dtype(distance_map, markers)
    x, y = strip_points(markers.astype(dtype), along, 2, width)
    return sample_points(distance_map.astype(dtype), _borders(x), _borders(y), nearest)


class EdgeLimbTemplates(PartTemplates):
    """Limb-strip templates plus the edge term's weight, scale and angular tolerance (see the
    module docstring): a :class:`PartTemplates` whose parts are the strips with their borders
    (and their foreground terms).

    Attributes:
        strips: the :class:`LimbTemplates` (NCC part).
        edge_weight: κ.
        edge_scale: σ over the spine length.
        edge_tolerance: largest angle (degrees) between a strip's axis and the nearest edge's
            tangent for its border point to count as on an edge (90: any edge).
        border_widths: ``(segments,)`` half width of each strip's scored borders over the
            spine length: the limb's own half width where the reference frame shows its
            outline (:func:`fit_border_widths`), else the strips' half width.
        background: ``(height, width)`` grey background of a static camera (the video's
            median, ``jaxtrack.vision.median_grey_background``), or None: no foreground term.
        foreground_weight: μ, nats per arm strip whose centre line lies on the background.
        foreground_threshold: grey-level difference from the background above which a pixel
            is foreground.
        coverage_weight: ν, the coverage term's weight (0: off).
        keypoint_weight, keypoint_scale: η of the keypoint term and ``s``, the factor on its
            scales :data:`KEYPOINT_SCALES` (η = 0: off; then the observations carry no keypoint
            channel).
    """

    strips: LimbTemplates
    edge_weight: Float[Array, ""]
    edge_scale: Float[Array, ""]
    edge_tolerance: Float[Array, ""]
    border_widths: Float[Array, " segments"]
    background: Float[Array, "height width"] | None = None
    foreground_weight: Float[Array, ""] = DEFAULT_FOREGROUND_WEIGHT
    foreground_threshold: Float[Array, ""] = DEFAULT_FOREGROUND_THRESHOLD
    coverage_weight: float = eqx.field(static=True, default=0.0)
    keypoint_weight: float = eqx.field(static=True, default=0.0)
    keypoint_scale: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        for name in ("coverage_weight", "keypoint_weight"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {value}")
        if not (np.isfinite(self.keypoint_scale) and self.keypoint_scale > 0):
            raise ValueError(f"keypoint_scale must be a positive factor on KEYPOINT_SCALES, "
                             f"got {self.keypoint_scale}")
        if self.border_widths.shape != (len(LIMB_SEGMENTS),):
            raise ValueError(f"border_widths must be ({len(LIMB_SEGMENTS)},), got "
                             f"{self.border_widths.shape}")
        if self.background is not None and jnp.ndim(self.background) != 2:
            raise ValueError(f"background must be a (height, width) grey image, got shape "
                             f"{jnp.shape(self.background)}")

    @property
    def part_markers(self) -> tuple[tuple[int, ...], ...]:
        """The markers each part (strip and its borders) depends on:
        :data:`jaxtrack.likelihoods.limbs.PART_MARKERS`."""
        return PART_MARKERS

    @property
    def spine_markers(self) -> tuple[int, int]:
        """Neck and pelvis: every part also reads their distance (the strips' widths, σ)."""
        return SPINE_MARKERS

    @property
    def direct_part_markers(self) -> tuple[tuple[int, ...], ...]:
        """The markers each part reads other than through the spine length (its two ends,
        :data:`jaxtrack.likelihoods.limbs.STRIP_ENDS`): with ``spine`` given, row p of
        :meth:`part_residuals` depends only on these and on ``spine``."""
        return STRIP_ENDS

    def _read(self, markers_2d, observation, nearest: bool,
              segments: tuple[int, ...] | None = None, spine: Array | None = None
              ) -> tuple[Array, Array, Array | None]:
        """The strips' samples ``(segments, along, across)``, ``e_i`` of their border points
        ``(segments, points)``: ``min(d/σ, 2)`` where the nearest edge runs along the strip,
        else 2, and (with a background; else None) the foreground term's ``b_s`` per strip
        (the strips ``segments`` picks, None: all).

        Both read the flattened observation in place (the maps at offsets of a channel).
        Samples and distances are read bilinearly unless ``nearest``; orientations always at
        the nearest pixel (angles do not interpolate). ``spine``: the length the widths and σ
        are fractions of, None: the markers' own.
        """
        observation = _check_observation(observation)
        markers = jnp.asarray(markers_2d)
        dtype = float_dtype(observation, markers)
        markers, observation = markers.astype(dtype), observation.astype(dtype)
        strips = self.strips
        x, y = strip_points(markers, strips.along, strips.across, strips.width, segments,
                             spine)
        samples = sample_points(observation, x, y, nearest, channel=0)
        widths = self.border_widths.astype(dtype)
        if segments is not None:
            widths = widths[jnp.asarray(select_segments(segments))]
        borders = _border_values(markers, observation, widths, self, nearest, segments, spine)
        return samples, borders, self._off_foreground(observation, samples, x, y, nearest,
                                                      segments)

    def _off_foreground(self, observation: Array, samples: Array, x: Array, y: Array,
                        nearest: bool, segments: tuple[int, ...] | None) -> Array | None:
        """``b_s``: the fraction of each arm strip's centre line (its middle sample across)
        that is background: where the observation's mask channel is below one half, else where
        the grey level is within ``foreground_threshold`` of the background's; 0 for the other
        strips; None with neither. Piecewise constant in the pose, so its gradient is taken as
        0."""
        has_mask = self._has_mask(observation)
        if self.background is None and not has_mask:
            return None
        dtype = samples.dtype
        off = jnp.zeros(samples.shape[0], dtype)
        # only the arm strips' centre lines are read (a hot path: every particle, every frame)
        arms = np.flatnonzero(np.isin(select_segments(segments), FOREGROUND_SEGMENTS))
        if arms.size == 0:
            return off
        centre = samples.shape[-1] // 2
        x, y = x[arms, :, centre], y[arms, :, centre]
        if has_mask:
            still = sample_points(observation, x, y, nearest, channel=MASK_CHANNEL) < 0.5
        else:
            background = sample_points(self.background.astype(dtype), x, y, nearest)
            still = jnp.abs(samples[arms, :, centre] - background) <= self.foreground_threshold
        return jax.lax.stop_gradient(off.at[arms].set(jnp.mean(still.astype(dtype), axis=-1)))

    @property
    def reads_keypoints(self) -> bool:
        """Whether the keypoint term is on: its observations carry a detector's keypoints."""
        return self.keypoint_weight > 0

    def _has_mask(self, images: Array) -> bool:
        """Whether the image channels (static shape) carry the person's mask."""
        return images.shape[0] > MASK_CHANNEL

    @property
    def has_whole_pose_terms(self) -> bool:
        """Whether :meth:`log_likelihood` holds a term no part holds (the coverage term, the
        keypoint term)."""
        return self.coverage_weight > 0 or self.reads_keypoints

    def _keypoint_costs(self, markers_2d, observation, spine=None) -> tuple[Array, Array] | None:
        """``(log(1 + q_j²), w_π(j))`` of the keypoint term's better assignment (module
        docstring), or None without the term; the first is differentiable in the markers."""
        if not self.reads_keypoints:
            return None
        images = _check_observation(observation, True)
        markers = jnp.asarray(markers_2d)
        dtype = float_dtype(images, markers)
        markers = markers.astype(dtype)
        detected = keypoints_of(observation)
        points = jnp.asarray(detected.points).astype(dtype)
        confidence = jnp.asarray(detected.confidence).astype(dtype)
        spine = spine_length(markers) if spine is None else jnp.asarray(spine, dtype)
        scales = jnp.asarray(KEYPOINT_SCALES, dtype) * self.keypoint_scale * spine

        def costs(order):
            squared = jnp.sum((markers - points[order]) ** 2, axis=-1)
            return jnp.log1p(squared / scales**2), confidence[order]

        given, given_weight = costs(np.arange(len(SPM_MARKERS)))
        mirrored, mirrored_weight = costs(np.asarray(MIRRORED_MARKERS))
        swap = jax.lax.stop_gradient(jnp.sum(mirrored_weight * mirrored)
                                     < jnp.sum(given_weight * given))
        return (jnp.where(swap, mirrored, given),
                jax.lax.stop_gradient(jnp.where(swap, mirrored_weight, given_weight)))

    def _coverage(self, markers_2d, observation, spine=None) -> tuple[Array, Array] | None:
        """``(c_g, m_g / max(Σ m, 1))`` of the coverage term's grid points (module
        docstring), or None without the term or a mask channel. ``c_g`` is differentiable in
        the markers; the mask is read at the nearest pixel."""
        observation = _check_observation(observation)
        if not self.coverage_weight > 0 or not self._has_mask(observation):
            return None
        markers = jnp.asarray(markers_2d)
        dtype = float_dtype(observation, markers)
        markers = markers.astype(dtype)
        height, width = observation.shape[1:]
        step = max(height, width) / COVERAGE_GRID
        rows, columns = max(1, round(height / step)), max(1, round(width / step))
        gy, gx = np.meshgrid((np.arange(rows) + 0.5) * height / rows - 0.5,
                             (np.arange(columns) + 0.5) * width / columns - 0.5, indexing="ij")
        points = jnp.asarray(np.stack([gx.ravel(), gy.ravel()], axis=1), dtype)
        mask = sample_points(observation.astype(dtype), points[:, 0], points[:, 1], True,
                             channel=MASK_CHANNEL) >= 0.5
        # the upper body explains the mask down to its hips: points beyond the pelvis along
        # the spine (the legs) are no term's
        neck, pelvis = markers[SPINE_MARKERS[0]], markers[SPINE_MARKERS[1]]
        spine_axis = pelvis - neck
        depth = jnp.sum((points - neck) * spine_axis, -1) / jnp.maximum(
            jnp.sum(spine_axis**2), 1e-12)
        mask = jax.lax.stop_gradient((mask & (depth <= COVERAGE_DEPTH)).astype(dtype))
        nearest_squared = jnp.min(squared_segment_distances(points, *_segment_ends(markers)),
                                  axis=1)
        scale = COVERAGE_SCALE * (spine_length(markers) if spine is None
                                  else jnp.asarray(spine, dtype))
        # sqrt at 0 has no derivative: a grid point on an axis is given a floor of 1e-12
        distance = jnp.sqrt(jnp.maximum(nearest_squared, 1e-12))
        return jnp.minimum(distance / scale, 2.0), mask / jnp.maximum(jnp.sum(mask), 1.0)

    def whole_pose_log_likelihood(self, markers_2d, observation) -> Array:
        """The coverage term ``−ν Σ_g m_g c_g² / max(Σ m, 1)`` and the keypoint term ``−η
        Σ_j w_j log(1 + q_j²)`` of one pose (module docstring); 0 without them."""
        value = jnp.zeros((), float_dtype(jnp.asarray(images_of(observation)),
                                          jnp.asarray(markers_2d)))
        coverage = self._coverage(markers_2d, observation)
        if coverage is not None:
            cost, weight = coverage
            value = value - self.coverage_weight * jnp.sum(weight * cost**2)
        keypoints = self._keypoint_costs(markers_2d, observation)
        if keypoints is not None:
            cost, weight = keypoints
            value = value - self.keypoint_weight * jnp.sum(weight * cost)
        return value

    def whole_pose_residuals(self, markers_2d, observation, spine=None) -> Array:
        """The residuals of the whole-pose terms, after the parts' in :meth:`residuals`:
        ``√(2ν m_g / Σ m) c_g`` per grid point (coverage), then ``√(2η w_j log(1 + q_j²))``
        per marker (keypoints); empty without them."""
        residuals = [jnp.zeros((0,), float_dtype(jnp.asarray(images_of(observation)),
                                                 jnp.asarray(markers_2d)))]
        coverage = self._coverage(markers_2d, observation, spine)
        if coverage is not None:
            cost, weight = coverage  # differentiable in the pose
            residuals.append(jnp.sqrt(2.0 * self.coverage_weight * weight) * cost)
        keypoints = self._keypoint_costs(markers_2d, observation, spine)
        if keypoints is not None:
            cost, weight = keypoints
            # √ has no derivative at 0: a marker on its keypoint is given a floor of 1e-12
            residuals.append(jnp.sqrt(2.0 * self.keypoint_weight * weight
                                      * jnp.maximum(cost, 1e-12)))
        return jnp.concatenate([residual.astype(residuals[0].dtype) for residual in residuals])

    def log_likelihood(self, markers_2d, observation, sharpness, nearest: bool = True
                       ) -> Array:
        """``−λ Σ (1 − NCC_s) − κ Σ_s mean_i e_i² (− μ Σ_arms b_s)`` for one pose, plus the
        whole-pose terms where they are on (:meth:`whole_pose_log_likelihood`: coverage,
        keypoints)."""
        samples, scaled, off = self._read(markers_2d, observation, nearest)
        scores = correlation(samples, self.strips.strips)
        appearance = -jnp.asarray(sharpness, scores.dtype) * jnp.sum(1 - scores)
        edges = jnp.sum(jnp.mean(scaled**2, axis=-1))
        value = appearance - self.edge_weight.astype(appearance.dtype) * edges
        if off is not None:
            value = value - jnp.asarray(self.foreground_weight, value.dtype) * jnp.sum(off)
        if self.has_whole_pose_terms:
            value = value + self.whole_pose_log_likelihood(markers_2d, observation)
        return value

    def residuals(self, markers_2d, observation, sharpness, spine=None) -> Array:
        """The strips' residuals, then ``√(2κ / n) e_i`` per border point (bilinear samples
        and distances), then ``√(2μ b_s)`` per strip with a background, then the whole-pose
        terms' (:meth:`whole_pose_residuals`: coverage, keypoints): half the squared norm is
        the negative log-likelihood. ``spine``: as in :meth:`part_residuals`."""
        residuals = self._part_terms_residuals(markers_2d, observation, sharpness, spine)
        if not self.has_whole_pose_terms:
            return residuals
        return jnp.concatenate([residuals, self.whole_pose_residuals(markers_2d, observation,
                                                                     spine)])

    def _part_terms_residuals(self, markers_2d, observation, sharpness, spine=None) -> Array:
        """:meth:`residuals` without the whole-pose terms (the parts' terms alone)."""
        samples, scaled, off = self._read(markers_2d, observation, nearest=False, spine=spine)
        appearance = template_residuals(samples, self.strips.strips, sharpness)
        weight = jnp.sqrt(2.0 * self.edge_weight.astype(scaled.dtype) / scaled.shape[-1])
        residuals = [appearance, (weight * scaled).reshape(-1)]
        if off is not None:  # √(2μ b_s), constant in the pose (no root's derivative at 0)
            residuals.append(jax.lax.stop_gradient(
                jnp.sqrt(2.0 * jnp.asarray(self.foreground_weight, off.dtype) * off)))
        return jnp.concatenate(residuals)

    def part_log_likelihoods(self, markers_2d, observation, sharpness, nearest: bool = True,
                             parts: tuple[int, ...] | None = None) -> Array:
        """``−λ (1 − NCC_s) − κ mean_i e_i²`` of each strip ``parts`` picks (static indices
        into ``LIMB_SEGMENTS``; None: all): the terms :meth:`log_likelihood` sums, computed
        for the picked strips alone (the whole-pose terms, no part's, left out:
        :meth:`whole_pose_log_likelihood`)."""
        samples, scaled, off = self._read(markers_2d, observation, nearest, parts)
        scores = correlation(samples, self.strips.strips[jnp.asarray(select_segments(parts))])
        appearance = -jnp.asarray(sharpness, scores.dtype) * (1 - scores)
        value = appearance - self.edge_weight.astype(scores.dtype) * jnp.mean(scaled**2, axis=-1)
        if off is not None:
            value = value - jnp.asarray(self.foreground_weight, value.dtype) * off
        return value

    def part_residuals(self, markers_2d, observation, sharpness, spine=None) -> Array:
        """:meth:`residuals` grouped by strip, ``(segments, along · across + points)`` (``+ 1``
        with a background): each row (a strip's samples, then its border points, then its
        foreground residual) depends only on the markers :attr:`part_markers` names for it.
        With ``spine`` (the length the widths and σ are fractions of; None: the markers' own)
        given, a row depends only on the markers :attr:`direct_part_markers` names and on
        ``spine``. The whole-pose terms, no part's, are left out."""
        residuals = self._part_terms_residuals(markers_2d, observation, sharpness, spine)
        segments = len(LIMB_SEGMENTS)
        split = segments * self.strips.along * self.strips.across
        borders = segments * 2 * (self.strips.along - 2)
        return jnp.concatenate([residuals[:split].reshape(segments, -1),
                                residuals[split:split + borders].reshape(segments, -1),
                                residuals[split + borders:].reshape(segments, -1)], axis=1)


def _segment_ends(markers: Array) -> tuple[Array, Array]:
    """``(segments, 2)`` start and end points of every limb strip's axis, with the head's and
    the hands' extensions (``LIMB_SEGMENTS``)."""
    start = markers[np.array([segment[1] for segment in LIMB_SEGMENTS])]
    end = markers[np.array([segment[2] for segment in LIMB_SEGMENTS])]
    before = jnp.asarray([segment[3] for segment in LIMB_SEGMENTS], markers.dtype)[:, None]
    after = jnp.asarray([segment[4] for segment in LIMB_SEGMENTS], markers.dtype)[:, None]
    axis = end - start
    return start - before * axis, end + after * axis


def _border_values(markers: Array, observation: Array, widths: Array,
                   templates: EdgeLimbTemplates, nearest: bool,
                   segments: tuple[int, ...] | None = None, spine: Array | None = None
                   ) -> Array:
    """``e_i`` of the border points ``(segments, 2 (along − 2))`` of one pose's strips at half
    widths ``widths`` (``(segments,)``, over the spine): ``min(d/σ, 2)`` where the nearest
    edge runs along the strip, else 2 (the strips ``segments`` picks, None: all; ``spine``
    the length widths and σ are fractions of, None: the markers' own)."""
    dtype = observation.dtype
    height, width = observation.shape[1:]
    border_x, border_y = (_borders(values) for values in
                          strip_points(markers, templates.strips.along, 2, widths, segments,
                                        spine))
    border = nearest_pixels(border_x, border_y, height, width)
    flat = observation.reshape(-1)  # grey, distances, tangents: offsets of height · width
    if nearest:
        distances = jnp.take(flat, border + height * width, mode="clip")
    else:
        distances = bilinear_sample(observation, border_x, border_y, channel=1)
    tangents = jnp.take(flat, border + 2 * height * width, mode="clip")
    # |sin(φ − θ)| ≤ sin(tolerance), as the angle between the two lines (mod π) within the
    # tolerance of 0 or of π: no sine per point
    difference = tangents - _axis_angles(markers, segments)[:, None]
    difference = difference - jnp.pi * jnp.floor(difference / jnp.pi)  # [0, π)
    tolerance = jnp.deg2rad(templates.edge_tolerance.astype(dtype)) + 1e-6
    along_limb = (difference <= tolerance) | (difference >= jnp.pi - tolerance)
    spine = spine_length(markers) if spine is None else jnp.asarray(spine, dtype)
    sigma = jnp.maximum(templates.edge_scale.astype(dtype) * spine, 1e-3)
    return jnp.where(along_limb, jnp.minimum(distances / sigma, 2.0), 2.0)


@eqx.filter_jit
def _border_costs(templates: EdgeLimbTemplates, markers: Array, observation: Array,
                  scales: Array) -> Array:
    """``(scales, segments)``: mean ``e_i²`` of each strip's borders at ``scales ×`` the
    strips' half width (bilinear distances)."""
    observation = observation.astype(scales.dtype)
    markers = markers.astype(scales.dtype)
    widths = scales[:, None] * templates.strips.width.astype(scales.dtype) * jnp.ones(
        len(LIMB_SEGMENTS), scales.dtype)
    values = jax.vmap(lambda w: _border_values(markers, observation, w, templates, False))(
        widths)
    return jnp.mean(values**2, axis=-1)


def fit_border_widths(
    templates: EdgeLimbTemplates,
    observation: Float[ArrayLike, "3 height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
    *,
    scales: Sequence[float] = DEFAULT_BORDER_SCALES,
    margin: float = DEFAULT_BORDER_MARGIN,
) -> EdgeLimbTemplates:
    """``templates`` with each strip's border half width fitted to the limb's outline in a
    reference observation at known markers.

    For each strip, the scale of the strips' half width among ``scales`` whose borders lie
    best on edges along the limb (least mean ``e_i²``) is taken if it beats the strips' own
    half width by ``margin``; a strip whose outline the frame does not show (the spine, a limb
    across the body) keeps the strips' half width.
    """
    observation = _edge_maps_of(observation)
    scales = np.asarray(scales, np.float64)
    if scales.ndim != 1 or scales.size == 0 or not np.all(np.isfinite(scales) & (scales > 0)):
        raise ValueError(f"scales must be positive numbers, got {scales}")
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a non-negative number, got {margin}")
    markers = jnp.asarray(markers_2d)
    check_markers(markers, name="markers_2d", finite=True)
    dtype = templates.strips.strips.dtype
    costs = np.asarray(_border_costs(templates, markers, observation,
                                     jnp.asarray(np.append(scales, 1.0), dtype)))
    own, costs = costs[-1], costs[:-1]
    best = np.argmin(costs, axis=0)
    gain = own - costs[best, np.arange(costs.shape[1])]
    factor = np.where(gain >= margin, scales[best], 1.0)
    widths = jnp.asarray(factor * float(templates.strips.width), dtype)
    return eqx.tree_at(lambda t: t.border_widths, templates, widths)


def make_edge_limb_templates(
    image: Float[ArrayLike, "height width"] | Float[ArrayLike, "3 height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
    *,
    edge_weight: float = DEFAULT_EDGE_WEIGHT,
    edge_scale: float = DEFAULT_EDGE_SCALE,
    edge_tolerance: float = DEFAULT_EDGE_TOLERANCE,
    border_scales: Sequence[float] | None = DEFAULT_BORDER_SCALES,
    background: Float[ArrayLike, "height width"] | None = None,
    foreground_weight: float = DEFAULT_FOREGROUND_WEIGHT,
    foreground_threshold: float = DEFAULT_FOREGROUND_THRESHOLD,
    coverage_weight: float = 0.0,
    keypoint_weight: float = 0.0,
    keypoint_scale: float = 1.0,
    **strip_options,
) -> EdgeLimbTemplates:
    """Strip templates cut from the reference grey frame (or the grey channel of its
    ``(3, height, width)`` observation), with κ, σ and the angular tolerance. The edge term
    has no template, but each strip's scored borders are fitted to the limb's outline in the
    reference frame (:func:`fit_border_widths` over ``border_scales``; the edge maps of a grey
    frame are made with ``jaxtrack.vision.edge_observations``); ``border_scales=None`` scores
    every strip's borders at the strips' own half width. With a ``background`` (a static
    camera's grey background, the frame's size and grey scale:
    ``jaxtrack.vision.median_grey_background``) the arm strips are also scored by the
    foreground term (μ = ``foreground_weight``, module docstring); with ``coverage_weight``
    ν > 0, observations with a mask are also scored by the coverage term; with
    ``keypoint_weight`` η > 0, observations carry a detector's keypoints
    (:class:`jaxtrack.vision.ImageObservation`), scored by the keypoint term with its scales
    :data:`KEYPOINT_SCALES` times ``keypoint_scale``."""
    image = jnp.asarray(images_of(image))
    observation = None
    if image.ndim == 3:
        observation = _edge_maps_of(image)
        image = observation[0]
    elif image.ndim != 2:
        raise ValueError(f"the reference frame must be (height, width) grey levels or a (3, "
                         f"height, width) observation, got shape {image.shape}")
    if not (np.isfinite(edge_weight) and edge_weight >= 0):
        raise ValueError(f"edge_weight must be a non-negative number, got {edge_weight}")
    if not (np.isfinite(edge_scale) and edge_scale > 0):
        raise ValueError(f"edge_scale must be a positive fraction of the spine, got {edge_scale}")
    if not (np.isfinite(edge_tolerance) and 0 < edge_tolerance <= 90):
        raise ValueError(f"edge_tolerance must be an angle in (0, 90] degrees, got "
                         f"{edge_tolerance}")
    if not (np.isfinite(foreground_weight) and foreground_weight >= 0):
        raise ValueError(f"foreground_weight must be a non-negative number, got "
                         f"{foreground_weight}")
    if not (np.isfinite(foreground_threshold) and foreground_threshold > 0):
        raise ValueError(f"foreground_threshold must be a positive grey-level difference, got "
                         f"{foreground_threshold}")
    if background is not None:
        background = np.asarray(background)
        if background.shape != tuple(image.shape):
            raise ValueError(f"background must be a grey image of the frame's size "
                             f"{tuple(image.shape)}, got shape {background.shape}")
        if not np.all(np.isfinite(background)):
            raise ValueError("background holds non-finite values")
    strips = make_limb_templates(image, markers_2d, **strip_options)
    dtype = strips.strips.dtype
    templates = EdgeLimbTemplates(
        strips=strips, edge_weight=jnp.asarray(edge_weight, dtype),
        edge_scale=jnp.asarray(edge_scale, dtype),
        edge_tolerance=jnp.asarray(edge_tolerance, dtype),
        border_widths=jnp.full(len(LIMB_SEGMENTS), strips.width, dtype),
        background=None if background is None else jnp.asarray(background, dtype),
        foreground_weight=jnp.asarray(foreground_weight, dtype),
        foreground_threshold=jnp.asarray(foreground_threshold, dtype),
        coverage_weight=float(coverage_weight), keypoint_weight=float(keypoint_weight),
        keypoint_scale=float(keypoint_scale))
    if border_scales is None:
        return templates
    if observation is None:
        from jaxtrack.vision import edge_observations

        observation = edge_observations(np.asarray(image, np.float32)[None])[0]
    return fit_border_widths(templates, observation, markers_2d, scales=border_scales)
