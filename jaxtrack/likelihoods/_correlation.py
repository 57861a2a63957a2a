"""Normalised cross-correlation of sampled blocks with zero-mean, unit-norm templates.

Tian et al. (2005, eq. 7) score a pose by ``−λ Σ_p (1 − NCC_p)``, NCC_p the normalised
cross-correlation of block p (a patch or a strip, its last two axes) sampled from the frame
with the same block cut from the reference frame:

    NCC = Σ (s − s̄) t̂ / |s − s̄|,    t̂ = (t − t̄) / |t − t̄|,

in [−1, 1], invariant to ``image → a · image + b`` for ``a > 0``; 0 for a flat block (one
with no variance), never NaN. Since ``‖ŝ − t̂‖² = 2 − 2 NCC``, the same cost is half the squared
norm of ``√λ (ŝ − t̂)``: :func:`template_residuals`, for Gauss–Newton.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

__all__ = ["correlation", "normalise", "template_residuals"]


def normalise(blocks: Float[Array, "*blocks rows columns"]
              ) -> tuple[Float[Array, "*blocks rows columns"], Bool[Array, "*blocks"]]:
    """Zero-mean, unit-norm blocks (all zeros for a flat one) and whether each had any
    variance at all."""
    centred = blocks - jnp.mean(blocks, axis=(-2, -1), keepdims=True)
    energy = jnp.sum(centred**2, axis=(-2, -1), keepdims=True)
    # "flat" is judged relative to the block's magnitude, so rounding residue of a constant
    # block (mean subtraction is inexact) is not mistaken for texture, at any brightness
    size = blocks.shape[-1] * blocks.shape[-2]
    magnitude = jnp.max(jnp.abs(blocks), axis=(-2, -1), keepdims=True)
    floor = size * (16 * jnp.finfo(blocks.dtype).eps * magnitude) ** 2
    textured = energy > floor
    norm = jnp.sqrt(jnp.where(textured, energy, 1))
    return jnp.where(textured, centred / norm, 0), textured[..., 0, 0]


def correlation(samples: Float[Array, "*blocks rows columns"],
                templates: Float[Array, "*blocks rows columns"]) -> Float[Array, "*blocks"]:
    """NCC of each sample block (last two axes) with its zero-mean, unit-norm template.

    ``Σ (s − s̄) t̂ / |s − s̄|``, 0 for a flat block, as :func:`normalise` then a dot product,
    but without materialising the centred and normalised blocks: XLA on CPU runs each pass
    over the particles' samples as a loop of its own, and this makes one for the mean and
    reads the samples once more for the energy and the dot product.
    A block is flat when its energy is within the rounding residue of its magnitude, judged
    with ``|s̄| + |s − s̄|`` ≥ max |s| in place of :func:`normalise`'s max |s|.
    """
    axes = (-2, -1)
    size = samples.shape[-1] * samples.shape[-2]
    mean = jnp.mean(samples, axis=axes, keepdims=True)
    centred = samples - mean
    energy = jnp.sum(centred**2, axis=axes)
    dot = jnp.sum(centred * templates.astype(samples.dtype), axis=axes)
    magnitude = jnp.abs(mean[..., 0, 0]) + jnp.sqrt(energy)
    textured = energy > size * (16 * jnp.finfo(samples.dtype).eps * magnitude) ** 2
    scores = jnp.where(textured, dot * jax.lax.rsqrt(jnp.where(textured, energy, 1)), 0)
    return jnp.clip(scores, -1, 1)  # Cauchy–Schwarz, up to rounding


def template_residuals(samples: Float[Array, "*blocks rows columns"],
                       templates: Float[Array, "*blocks rows columns"],
                       sharpness: Float[ArrayLike, ""]) -> Float[Array, " residuals"]:
    """``√λ (ŝ − t̂)`` flattened: half its squared norm is ``λ Σ (1 − NCC)`` (textured blocks),
    the NCC cost as a sum of squares for Gauss–Newton."""
    samples, _ = normalise(samples)
    return jnp.sqrt(jnp.asarray(sharpness, samples.dtype)) * (
        samples - templates.astype(samples.dtype)).reshape(-1)
