"""Normalised cross-correlation of template patches at the body markers (Tian et al. 2005, eq. 7).

Tian, Li & Sclaroff (2005, §4) score a decoded pose by how well small image patches around its
12 Scaled Prismatic Model markers match template patches cut at the same markers in the first
frame:

    p(z | y) ∝ exp(−λ Σ_m (1 − NCC_m(y))),

where NCC_m is the normalised cross-correlation between the template of marker m and the patch
of the current frame centred on marker m of pose y. The patch side is a tenth of the spine
height (neck to pelvis), as in the paper.

Everything here is pure JAX for ONE pose (``(markers, 2)`` pixel positions); the filter vmaps
over particles. Patches are sampled by bilinear interpolation with gathers at the ``markers ×
side × side`` sample points only, so the cost per particle does not grow with the image size.
Images are ``(height, width)`` grey levels (``jaxtrack.vision.to_grey``); pixel centres are at
integer coordinates (OpenCV's convention, the renderer's too), x to the right, y down.

Dtypes follow the inputs: float32 images and markers give float32 results; integer inputs
are computed in float32; float64 only when a float64 array comes in.

Two samplers, same model:

* :func:`ncc_scores` / :func:`ncc_log_likelihood` sample the patches bilinearly at the exact
  marker positions: smooth in the markers (useful gradients), four gathers per sample point.
* :func:`ncc_scores_nearest` / :func:`ncc_log_likelihood_nearest` round each marker to the
  nearest pixel and cut the patch as one contiguous block, in a single fused pass that also
  forms the patch sums. For a particle filter, which only needs likelihood values, this is
  an order of magnitude faster on CPU and equal to the bilinear scores at integer marker
  positions (~1e-5 in float32). The price:
  ±0.5-pixel quantisation of the markers, zero gradients with respect to them, and patches
  near the border shifted inside the image instead of edge-replicated.

The nearest-pixel version needs no per-frame preprocessing: the patch sums are accumulated
from the gathered patch itself, relative to its centre pixel (see :func:`ncc_scores_nearest`),
which costs almost nothing on top of the gather and is exact for flat patches (integral images
were measured and rejected).

Timings, and why not integral images: see docs/likelihoods.md, "Marker patches (NCC)".
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.likelihoods._base import SPINE_MARKERS, PartTemplates, check_markers
from jaxtrack.likelihoods._correlation import correlation, normalise, template_residuals
from jaxtrack.likelihoods._sampling import bilinear_sample, float_dtype
from jaxtrack.vision.observations import images_of

__all__ = [
    "DEFAULT_NCC_SHARPNESS",
    "NCCTemplates",
    "bilinear_sample",
    "make_templates",
    "ncc_log_likelihood",
    "ncc_log_likelihood_nearest",
    "ncc_scores",
    "ncc_scores_nearest",
    "patch_half_size",
    "sample_patches",
    "sample_patches_nearest",
]

DEFAULT_NCC_SHARPNESS = 1.0
"""λ of :func:`ncc_log_likelihood`: nats lost per unit of summed NCC dissimilarity.

λ = 1 is Tian et al.'s eq. 7 as written, ``exp(−Σ (1 − NCC))``: it keeps an effective sample
size of about a quarter of the particles under a few pixels of marker noise while still
down-weighting poses a few pixels off. Raise λ with many particles or a tight prior. The
measurement: see docs/likelihoods.md, "Marker patches (NCC)".
"""


def patch_half_size(markers_2d: Float[ArrayLike, "*batch markers 2"]) -> int:
    """Half the side of the NCC patches for a body of this size: a static Python int.

    Tian et al. (2005) take patches whose side is a tenth of the spine height (the neck–pelvis
    distance). The side is ``2 · half + 1`` pixels with ``half = round((spine / 10 − 1) / 2)``,
    at least 2 (a 5 × 5 patch).

    Args:
        markers_2d: ``(12, 2)`` pixel markers of one pose, or ``(..., 12, 2)`` of several (the
            median spine height is used). Must be concrete (not traced): the patch size is a
            shape.
    """
    if isinstance(markers_2d, jax.core.Tracer):
        raise ValueError("patch_half_size needs concrete markers (it decides an array shape); "
                         "call it outside jit, e.g. once on the first frame's markers")
    check_markers(markers_2d, batched=True)
    markers = np.asarray(markers_2d, np.float64)
    neck, pelvis = SPINE_MARKERS
    spine = np.linalg.norm(markers[..., pelvis, :] - markers[..., neck, :], axis=-1)
    spine = float(np.median(spine))
    if not np.isfinite(spine):
        raise ValueError("the neck or pelvis marker is not finite; cannot size the patches")
    return max(2, int(np.floor((spine / 10 - 1) / 2 + 0.5)))  # halves round up


def sample_patches(
    image: Float[ArrayLike, "height width"],
    centres: Float[ArrayLike, "markers 2"],
    half_size: int,
) -> Float[Array, "markers size size"]:
    """Square patches of ``image`` around each centre, by bilinear interpolation.

    Only the ``markers × size × size`` sample points are gathered (four neighbours each); no
    operation touches the whole image, so vmapping over particles stays cheap. Sample points
    outside the image are clamped to its border (the nearest edge pixel's value).

    Args:
        image: ``(height, width)`` grey levels.
        centres: ``(markers, 2)`` ``(x, y)`` pixel positions (pixel centres at integers).
        half_size: static; patches are ``size = 2 · half_size + 1`` pixels square.

    Returns:
        ``(markers, size, size)``; ``patches[m, i, j]`` is the image at
        ``(x_m + j − half_size, y_m + i − half_size)``.
    """
    image = jnp.asarray(images_of(image))
    centres = jnp.asarray(centres)
    if image.ndim != 2:
        raise ValueError(f"image must be (height, width) grey levels, got shape {image.shape}; "
                         f"convert colour frames with jaxtrack.vision.to_grey")
    if centres.ndim != 2 or centres.shape[-1] != 2:
        raise ValueError(f"centres must be (markers, 2) pixel positions, got {centres.shape}")
    dtype = float_dtype(image, centres)
    offsets = jnp.arange(-half_size, half_size + 1, dtype=dtype)
    centres = centres.astype(dtype)
    x = centres[:, None, None, 0] + offsets[None, None, :]
    y = centres[:, None, 1, None] + offsets[None, :, None]
    x, y = jnp.broadcast_arrays(x, y)  # (markers, size, size)
    return bilinear_sample(image.astype(dtype), x, y)


class NCCTemplates(PartTemplates):
    """Template patches, one per marker, for the NCC likelihood: a :class:`PartTemplates`
    whose parts are the patches, each reading its own marker.

    Attributes:
        patches: ``(markers, size, size)`` zero-mean, unit-norm patches (all zeros for a marker
            whose template was flat: that marker then always scores 0).
        half_size: static; ``size = 2 · half_size + 1``.
    """

    patches: Float[Array, "markers size size"]
    half_size: int = eqx.field(static=True)

    def __check_init__(self):
        size = 2 * self.half_size + 1
        if self.patches.ndim != 3 or self.patches.shape[1:] != (size, size):
            raise ValueError(f"template patches must be (markers, {size}, {size}) for "
                             f"half_size={self.half_size}, got {self.patches.shape}")

    @property
    def num_markers(self) -> int:
        return self.patches.shape[0]

    def log_likelihood(self, markers_2d, image, sharpness, nearest: bool = True) -> Array:
        """eq. 7 with nearest-pixel (fast) or bilinear patches (the interface trackers call)."""
        score = ncc_log_likelihood_nearest if nearest else ncc_log_likelihood
        return score(markers_2d, image, self, sharpness)

    def residuals(self, markers_2d, image, sharpness, spine=None) -> Array:
        """``√λ (p̂ − t̂)`` over all patches (bilinear): since ``‖p̂ − t̂‖² = 2 − 2 NCC``, half
        its squared norm is eq. 7's cost ``λ Σ_m (1 − NCC_m)``, a sum of squares for
        Gauss–Newton. ``spine`` must be None: the patches do not read the spine length."""
        _no_spine(spine)
        return template_residuals(sample_patches(image, markers_2d, self.half_size),
                                  self.patches, sharpness)

    @property
    def part_markers(self) -> tuple[tuple[int, ...], ...]:
        """The marker each part (patch) of the likelihood depends on: its own."""
        return tuple((marker,) for marker in range(self.num_markers))

    @property
    def spine_markers(self) -> None:
        """None: the patches' size is fixed, no part reads the spine length."""
        return None

    @property
    def direct_part_markers(self) -> tuple[tuple[int, ...], ...]:
        """:attr:`part_markers` (no part reads the spine length)."""
        return self.part_markers

    def part_log_likelihoods(self, markers_2d, image, sharpness, nearest: bool = True,
                             parts: tuple[int, ...] | None = None) -> Array:
        """``−λ (1 − NCC_m)`` of each patch ``parts`` picks (static marker indices; None:
        all): the terms :meth:`log_likelihood` sums, computed for the picked patches alone."""
        markers, templates = jnp.asarray(markers_2d), self
        if parts is not None:
            parts = tuple(int(part) for part in parts)
            if not parts or any(not 0 <= part < self.num_markers for part in parts):
                raise ValueError(f"parts must be marker indices (0 to {self.num_markers - 1}), "
                                 f"got {parts}")
            index = jnp.asarray(parts)
            markers, templates = markers[index], NCCTemplates(self.patches[index],
                                                              self.half_size)
        scores = (ncc_scores_nearest if nearest else ncc_scores)(markers, image, templates)
        return -jnp.asarray(sharpness, scores.dtype) * (1 - scores)

    def part_residuals(self, markers_2d, image, sharpness, spine=None) -> Array:
        """:meth:`residuals` grouped by patch, ``(markers, size²)``: each row depends only on
        its own marker. ``spine`` must be None, as in :meth:`residuals`."""
        return self.residuals(markers_2d, image, sharpness, spine).reshape(self.num_markers, -1)


def _no_spine(spine) -> None:
    if spine is not None:
        raise ValueError("the marker patches do not read the spine length (their "
                         "spine_markers is None); pass spine=None")


def make_templates(
    image: Float[ArrayLike, "height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
    half_size: int | None = None,
) -> NCCTemplates:
    """Cut the template patches at the markers of a reference frame (Tian et al.: the first).

    Args:
        image: ``(height, width)`` grey reference frame.
        markers_2d: ``(markers, 2)`` its pixel markers (``SPM_MARKERS`` order for the SPM body).
        half_size: patch half side; None sizes the patches from the spine with
            :func:`patch_half_size` (needs concrete markers).
    """
    if half_size is None:
        half_size = patch_half_size(markers_2d)
    if int(half_size) != half_size or half_size < 0:
        raise ValueError(f"half_size must be a non-negative integer, got {half_size}")
    patches, _ = normalise(sample_patches(image, markers_2d, int(half_size)))
    return NCCTemplates(patches=patches, half_size=int(half_size))


def ncc_scores(
    markers_2d: Float[ArrayLike, "markers 2"],
    image: Float[ArrayLike, "height width"],
    templates: NCCTemplates,
) -> Float[Array, " markers"]:
    """Normalised cross-correlation of each marker's patch in ``image`` with its template.

    Args:
        markers_2d: ``(markers, 2)`` pixel positions of one pose.
        image: ``(height, width)`` grey frame.
        templates: from :func:`make_templates`, with as many markers.

    Returns:
        ``(markers,)`` in [−1, 1]; 0 where the image patch or the template is flat (no variance),
        never NaN. Invariant to ``image → a · image + b`` for ``a > 0``.
    """
    markers = jnp.asarray(markers_2d)
    if markers.shape[0] != templates.num_markers:
        raise ValueError(f"{markers.shape[0]} markers but {templates.num_markers} templates")
    return correlation(sample_patches(image, markers, templates.half_size), templates.patches)


def ncc_log_likelihood(
    markers_2d: Float[ArrayLike, "markers 2"],
    image: Float[ArrayLike, "height width"],
    templates: NCCTemplates,
    sharpness: float | Float[ArrayLike, ""] = DEFAULT_NCC_SHARPNESS,
) -> Float[Array, ""]:
    """Log-likelihood of one pose under the NCC template model (Tian et al. 2005, eq. 7).

    ``log p(z | y) = −λ Σ_m (1 − NCC_m)`` up to a constant, with λ = ``sharpness``
    (:data:`DEFAULT_NCC_SHARPNESS`). The maximum, 0, is reached when every patch matches its
    template up to brightness and contrast; each marker costs at most 2λ.

    Args:
        markers_2d: ``(markers, 2)`` pixel positions of one pose (vmap over particles).
        image: ``(height, width)`` grey frame.
        templates: from :func:`make_templates`.
        sharpness: λ ≥ 0, nats per unit of summed dissimilarity; an array so that it can be
            learned or changed without recompiling.
    """
    scores = ncc_scores(markers_2d, image, templates)
    # Tian et al. (2005) eq. 7: likelihood ∝ exp(−Σ_m dissimilarity_m), dissimilarity 1 − NCC
    return -jnp.asarray(sharpness, scores.dtype) * jnp.sum(1 - scores)


# ------------------------------------------------------------------------------------------
# Nearest-pixel patches: one block gather and one fused pass per patch (particle filters)
# ------------------------------------------------------------------------------------------


def _check_image_and_centres(image: Array, centres: Array, half_size: int) -> None:
    if image.ndim != 2:
        raise ValueError(f"image must be (height, width) grey levels, got shape {image.shape}; "
                         f"convert colour frames with jaxtrack.vision.to_grey")
    if centres.ndim != 2 or centres.shape[-1] != 2:
        raise ValueError(f"centres must be (markers, 2) pixel positions, got {centres.shape}")
    size = 2 * half_size + 1
    if image.shape[0] < size or image.shape[1] < size:
        raise ValueError(f"image {image.shape} is smaller than the {size} × {size} patches")


def _patch_corners(centres: Array, shape: tuple[int, int], half_size: int,
                   dtype: jnp.dtype) -> tuple[Array, Array]:
    """Top-left ``(x, y)`` int32 pixel of each nearest-pixel patch, clamped inside the image."""
    height, width = shape
    size = 2 * half_size + 1
    # nearest pixel, halves rounding up (as in patch_half_size); clamp in floating point so
    # that huge or infinite coordinates cannot overflow the int32 conversion
    corner = jnp.floor(centres.astype(dtype) + 0.5) - half_size
    x = jnp.clip(corner[..., 0], 0, width - size).astype(jnp.int32)
    y = jnp.clip(corner[..., 1], 0, height - size).astype(jnp.int32)
    return x, y


def _blocks(image: Array, x: Array, y: Array, size: int) -> Array:
    """``(markers, size, size)`` blocks with top-left corners ``(x, y)`` (in bounds)."""
    # vmapped dynamic_slice: XLA makes it one gather of (size, size) slices, which it fuses
    # into the consumer; faster under vmap than a gather of flat pixel indices
    return jax.vmap(lambda row, col: jax.lax.dynamic_slice(image, (row, col), (size, size)))(
        y, x)


def sample_patches_nearest(
    image: Float[ArrayLike, "height width"],
    centres: Float[ArrayLike, "markers 2"],
    half_size: int,
) -> Float[Array, "markers size size"]:
    """Square patches of ``image`` at the pixel nearest each centre, kept inside the image.

    The patch of centre ``(x, y)`` is the block of pixels centred on ``(⌊x + ½⌋, ⌊y + ½⌋)``;
    a block that would cross the border is shifted inwards until it fits (so it no longer
    centres on the marker), unlike :func:`sample_patches`, which replicates the edge pixels.
    At integer centres at least ``half_size`` pixels from the border both give the same
    patch.

    Args:
        image: ``(height, width)`` grey levels, at least ``size`` pixels each way.
        centres: ``(markers, 2)`` ``(x, y)`` pixel positions (pixel centres at integers).
        half_size: static; patches are ``size = 2 · half_size + 1`` pixels square.

    Returns:
        ``(markers, size, size)`` in the promoted floating dtype of the inputs.
    """
    image = jnp.asarray(images_of(image))
    centres = jnp.asarray(centres)
    _check_image_and_centres(image, centres, half_size)
    dtype = float_dtype(image, centres)
    x, y = _patch_corners(centres, image.shape, half_size, dtype)
    return _blocks(image.astype(dtype), x, y, 2 * half_size + 1)


def _add3(a: tuple, b: tuple) -> tuple:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


def ncc_scores_nearest(
    markers_2d: Float[ArrayLike, "markers 2"],
    image: Float[ArrayLike, "height width"],
    templates: NCCTemplates,
) -> Float[Array, " markers"]:
    """:func:`ncc_scores` with each marker rounded to the nearest pixel: fast, for filters.

    The patch of each marker is :func:`sample_patches_nearest`'s block (one gather, shifted
    inside the image near the border); markers anywhere, even far outside the image, are
    accepted. With the zero-mean, unit-norm template ``t`` and the patch ``p`` taken
    relative to its centre pixel ``c`` (``q = p − c``, which changes neither the correlation
    nor the variance but keeps the sums small, so float32 does not lose low-contrast patches
    to cancellation),

        NCC = Σ q·t / sqrt(Σ q² − (Σ q)² / size²),

    where ``Σ q·t`` needs no mean subtraction because ``Σ t = 0``. The three sums come from
    one fused pass over each patch's rows (a variadic reduction, which XLA fuses with the
    gather, so the patches are never written to memory). No per-frame preprocessing is
    needed; the image is used as it is (converted to the compute dtype once, outside the
    particle vmap, since it is not batched).

    Same values as :func:`ncc_scores` at integer markers away from the border (to rounding:
    ~1e-6 in float32); in [−1, 1], 0 for a flat patch or template, never NaN; invariant to
    ``image → a · image + b`` for ``a > 0``. The gradient with respect to the markers is
    zero (rounding); use :func:`ncc_scores` where it matters.

    Args:
        markers_2d: ``(markers, 2)`` pixel positions of one pose (vmap over particles).
        image: ``(height, width)`` grey frame, any real dtype.
        templates: from :func:`make_templates`, with as many markers.

    Returns:
        ``(markers,)`` scores in the promoted floating dtype of ``markers_2d`` and ``image``.
    """
    markers = jnp.asarray(markers_2d)
    image = jnp.asarray(images_of(image))
    half = templates.half_size
    _check_image_and_centres(image, markers, half)
    if markers.shape[0] != templates.num_markers:
        raise ValueError(f"{markers.shape[0]} markers but {templates.num_markers} templates")
    dtype = float_dtype(image, markers)
    image = image.astype(dtype)
    size = 2 * half + 1
    x, y = _patch_corners(markers, image.shape, half, dtype)
    # the flat index y · width + x of each corner, as a matrix product: XLA materialises it
    # once per marker, where the elementwise corner arithmetic would be fused into the patch
    # gather and redone for every row of every patch (~10 % of the latent tracker's step)
    width = image.shape[1]
    corner = jnp.dot(jnp.stack([y, x], axis=-1), jnp.array([width, 1], jnp.int32))
    x, y = corner % width, corner // width
    # (a clipping take: a "promise_in_bounds" gather copies the image first, see
    # bilinear_sample)
    centre = jnp.take(image.reshape(-1), corner + half * width + half, mode="clip")
    patches = _blocks(image, x, y, size) - centre[:, None, None]
    template = templates.patches.astype(dtype)
    zero = jnp.zeros((), dtype)
    # reducing the rows first (keeping the columns) is ~2× faster on CPU than summing each
    # patch whole: short independent chains of additions instead of one long one
    rows = jax.lax.reduce((patches * template, patches, patches * patches), (zero,) * 3,
                          _add3, (1,))
    cross, total, squares = jax.lax.reduce(rows, (zero,) * 3, _add3, (1,))
    energy = squares - total * total / (size * size)
    # the centre pixel has q = 0, so energy ≥ squares / (size² + 1) for any patch that is not
    # flat, and exactly 0 (squares = 0) for a flat one: this test only separates those two
    textured = energy > jnp.finfo(dtype).eps * squares
    scores = jnp.where(textured, cross * jax.lax.rsqrt(jnp.where(textured, energy, 1)), 0)
    return jnp.clip(scores, -1, 1)  # Cauchy–Schwarz, up to rounding


def ncc_log_likelihood_nearest(
    markers_2d: Float[ArrayLike, "markers 2"],
    image: Float[ArrayLike, "height width"],
    templates: NCCTemplates,
    sharpness: float | Float[ArrayLike, ""] = DEFAULT_NCC_SHARPNESS,
) -> Float[Array, ""]:
    """:func:`ncc_log_likelihood` on :func:`ncc_scores_nearest`: ``−λ Σ_m (1 − NCC_m)``.

    The drop-in fast likelihood for particle filters (vmap over particles, image unbatched);
    markers are rounded to the nearest pixel, so it is piecewise constant in them.
    """
    scores = ncc_scores_nearest(markers_2d, image, templates)
    return -jnp.asarray(sharpness, scores.dtype) * jnp.sum(1 - scores)
