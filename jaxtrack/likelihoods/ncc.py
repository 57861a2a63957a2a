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
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

__all__ = [
    "DEFAULT_NCC_SHARPNESS",
    "NCCTemplates",
    "make_templates",
    "ncc_log_likelihood",
    "ncc_scores",
    "patch_half_size",
    "sample_patches",
]

DEFAULT_NCC_SHARPNESS = 1.0
"""λ of :func:`ncc_log_likelihood`: nats lost per unit of summed NCC dissimilarity.

λ = 1 is Tian et al.'s eq. 7 as written, ``exp(−Σ (1 − NCC))``, and it is also the value that
measurements favour. On frames rendered from the bundled wave clip (640 × 480, 13-pixel patches,
templates from frame 0), moving each of the 12 markers 3 pixels in a random direction raises the
summed dissimilarity by about 1.5–4, and a cloud of particles with 3-pixel marker noise spreads
it with a standard deviation of about 1.1–1.5. With λ = 1 those particles keep log-weights
spread by ~1.3 nats, an effective sample size of roughly a quarter of the particles (for
log-normal weights ESS/N ≈ exp(−σ²)), while poses a few pixels off are still down-weighted by
several-fold. λ = 4 would spread them by ~5 nats and leave a handful of particles (ESS/N ≈
e⁻²⁵); it also over-trusts fixed templates whose dissimilarity at the true pose already drifts
by 2–3 within half a second as the body turns. Raise λ with many particles or a tight prior.
"""

_SPINE = (1, 3)  # neck, pelvis in SPM_MARKERS order


def _float_dtype(*arrays: Array) -> jnp.dtype:
    """The promoted floating dtype of the floating inputs (float32 if there are none)."""
    floating = [a.dtype for a in arrays if jnp.issubdtype(a.dtype, jnp.floating)]
    return jnp.result_type(*floating) if floating else jnp.dtype(jnp.float32)


def patch_half_size(markers_2d: Float[ArrayLike, "*batch markers 2"]) -> int:
    """Half the side of the NCC patches for a body of this size: a static Python int.

    Tian et al. (2005) take patches whose side is a tenth of the spine height (the neck–pelvis
    distance, markers 1 and 3 of ``SPM_MARKERS``). The side is ``2 · half + 1`` pixels with
    ``half = round((spine / 10 − 1) / 2)``, at least 2 (a 5 × 5 patch).

    Args:
        markers_2d: ``(12, 2)`` pixel markers of one pose, or ``(..., 12, 2)`` of several (the
            median spine height is used). Must be concrete (not traced): the patch size is a
            shape.
    """
    if isinstance(markers_2d, jax.core.Tracer):
        raise ValueError("patch_half_size needs concrete markers (it decides an array shape); "
                         "call it outside jit, e.g. once on the first frame's markers")
    markers = np.asarray(markers_2d, np.float64)
    if markers.ndim < 2 or markers.shape[-1] != 2 or markers.shape[-2] <= max(_SPINE):
        raise ValueError(f"markers must be (..., 12, 2) in SPM_MARKERS order, got {markers.shape}")
    spine = np.linalg.norm(markers[..., _SPINE[1], :] - markers[..., _SPINE[0], :], axis=-1)
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
    image = jnp.asarray(image)
    centres = jnp.asarray(centres)
    if image.ndim != 2:
        raise ValueError(f"image must be (height, width) grey levels, got shape {image.shape}; "
                         f"convert colour frames with jaxtrack.vision.to_grey")
    if centres.ndim != 2 or centres.shape[-1] != 2:
        raise ValueError(f"centres must be (markers, 2) pixel positions, got {centres.shape}")
    dtype = _float_dtype(image, centres)
    height, width = image.shape
    offsets = jnp.arange(-half_size, half_size + 1, dtype=dtype)
    centres = centres.astype(dtype)
    x = jnp.clip(centres[:, None, None, 0] + offsets[None, None, :], 0, width - 1)
    y = jnp.clip(centres[:, None, 1, None] + offsets[None, :, None], 0, height - 1)
    x, y = jnp.broadcast_arrays(x, y)  # (markers, size, size)
    x0 = jnp.floor(x)
    y0 = jnp.floor(y)
    fx, fy = x - x0, y - y0
    x0 = x0.astype(jnp.int32)
    y0 = y0.astype(jnp.int32)
    x1 = jnp.minimum(x0 + 1, width - 1)
    y1 = jnp.minimum(y0 + 1, height - 1)
    flat = image.reshape(-1).astype(dtype)
    # one gather of the four neighbours; the indices are in bounds by construction
    index = jnp.stack([y0 * width + x0, y0 * width + x1, y1 * width + x0, y1 * width + x1])
    top_left, top_right, bottom_left, bottom_right = flat.at[index].get(
        mode="promise_in_bounds")
    top = top_left + fx * (top_right - top_left)
    bottom = bottom_left + fx * (bottom_right - bottom_left)
    return top + fy * (bottom - top)


def _normalise(patches: Array) -> tuple[Array, Array]:
    """Zero-mean, unit-norm patches and whether each had any variance at all."""
    centred = patches - jnp.mean(patches, axis=(-2, -1), keepdims=True)
    energy = jnp.sum(centred**2, axis=(-2, -1), keepdims=True)
    # "flat" is judged relative to the patch's magnitude, so rounding residue of a constant
    # patch (mean subtraction is inexact) is not mistaken for texture, at any brightness
    size = patches.shape[-1] * patches.shape[-2]
    magnitude = jnp.max(jnp.abs(patches), axis=(-2, -1), keepdims=True)
    floor = size * (16 * jnp.finfo(patches.dtype).eps * magnitude) ** 2
    textured = energy > floor
    norm = jnp.sqrt(jnp.where(textured, energy, 1))
    return jnp.where(textured, centred / norm, 0), textured[..., 0, 0]


class NCCTemplates(eqx.Module):
    """Template patches, one per marker, for the NCC likelihood.

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
    patches, _ = _normalise(sample_patches(image, markers_2d, int(half_size)))
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
    patches, _ = _normalise(sample_patches(image, markers, templates.half_size))
    scores = jnp.sum(patches * templates.patches.astype(patches.dtype), axis=(-2, -1))
    return jnp.clip(scores, -1, 1)  # Cauchy–Schwarz, up to rounding


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
