"""Ong & Gong's hybrid vector: 2-D contour, hands and 3-D skeleton in one shape vector.

Ong & Gong (2002, §5.1) track a "hybrid" point-distribution model whose every sample stacks

    v = [ contour − head (2·Nc),  hands − head (2·2),  skeleton (3·Ns) ],

the silhouette's contour points and the two hand positions in image coordinates relative to the
head, and the 3-D skeleton, so that one global PCA couples image evidence (contour, hands) with the
body's 3-D configuration. The head offset is removed so the model is translation invariant; it is
tracked separately and passed back in to recover image coordinates.

Layout of the vector (row-major flattening, so point i of the contour is entries 2i, 2i+1)::

    [0, 2·Nc)                 contour x0, y0, x1, y1, ... relative to the head
    [2·Nc, 2·Nc + 4)          right hand x, y, left hand x, y relative to the head
    [2·Nc + 4, 2·Nc + 4 + 3·Ns) skeleton x0, y0, z0, x1, ... (as given, e.g. root-relative metres)

The parts have different units (pixels against metres); scale them before a PCA if their
variances should count equally.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

__all__ = ["HybridLayout", "HybridParts", "make_hybrid", "split_hybrid"]


class HybridLayout(eqx.Module):
    """Sizes of the hybrid vector's parts (static; a layout has no arrays)."""

    num_contour: int = eqx.field(static=True, default=100)
    num_skeleton: int = eqx.field(static=True, default=12)

    @property
    def contour_slice(self) -> slice:
        return slice(0, 2 * self.num_contour)

    @property
    def hands_slice(self) -> slice:
        return slice(2 * self.num_contour, 2 * self.num_contour + 4)

    @property
    def skeleton_slice(self) -> slice:
        start = 2 * self.num_contour + 4
        return slice(start, start + 3 * self.num_skeleton)

    @property
    def size(self) -> int:
        """Length of the vector, ``2·Nc + 4 + 3·Ns``."""
        return 2 * self.num_contour + 4 + 3 * self.num_skeleton


class HybridParts(NamedTuple):
    """The parts of a hybrid vector (leading batch axes allowed on every field)."""

    contour: Float[Array, "*batch contour 2"]
    hands: Float[Array, "*batch 2 2"]
    skeleton_3d: Float[Array, "*batch joints 3"]


def make_hybrid(
    contour: Float[ArrayLike, "*batch contour 2"],
    hands: Float[ArrayLike, "*batch 2 2"],
    head: Float[ArrayLike, "*batch 2"],
    skeleton_3d: Float[ArrayLike, "*batch joints 3"],
) -> Float[Array, "*batch vector"]:
    """Stack one (or a batch of) sample(s) into hybrid vectors ``(..., 2·Nc + 4 + 3·Ns)``.

    Args:
        contour: ``(..., Nc, 2)`` contour points, pixels.
        hands: ``(..., 2, 2)`` right then left hand, pixels.
        head: ``(..., 2)`` head position, pixels; subtracted from contour and hands
            (Ong & Gong 2002, §5.1: positions relative to the head).
        skeleton_3d: ``(..., Ns, 3)`` skeleton joints, kept as given.
    """
    contour, hands, head, skeleton = (
        jnp.asarray(part) for part in (contour, hands, head, skeleton_3d)
    )
    if contour.shape[-1] != 2 or hands.shape[-2:] != (2, 2) or head.shape[-1] != 2:
        raise ValueError(
            f"expected contour (..., Nc, 2), hands (..., 2, 2), head (..., 2); got "
            f"{contour.shape}, {hands.shape}, {head.shape}"
        )
    if skeleton.shape[-1] != 3:
        raise ValueError(f"skeleton_3d must have shape (..., Ns, 3), got {skeleton.shape}")
    batch = head.shape[:-1]
    dtype = jnp.result_type(contour, hands, head, skeleton, float)
    relative_contour = (contour - head[..., None, :]).reshape(*batch, -1)
    relative_hands = (hands - head[..., None, :]).reshape(*batch, -1)
    parts = [relative_contour, relative_hands, skeleton.reshape(*batch, -1)]
    return jnp.concatenate([part.astype(dtype) for part in parts], axis=-1)


def split_hybrid(
    vector: Float[ArrayLike, "*batch vector"],
    layout: HybridLayout,
    head: Float[ArrayLike, "*batch 2"] | None = None,
) -> HybridParts:
    """Split hybrid vectors back into parts; the inverse of :func:`make_hybrid`.

    Args:
        vector: ``(..., layout.size)``.
        layout: the part sizes.
        head: ``(..., 2)`` head position to add back to contour and hands; without it they stay
            relative to the head.
    """
    vector = jnp.asarray(vector)
    if vector.shape[-1] != layout.size:
        raise ValueError(
            f"hybrid vector has length {vector.shape[-1]} but the layout (num_contour="
            f"{layout.num_contour}, num_skeleton={layout.num_skeleton}) needs {layout.size}"
        )
    batch = vector.shape[:-1]
    contour = vector[..., layout.contour_slice].reshape(*batch, layout.num_contour, 2)
    hands = vector[..., layout.hands_slice].reshape(*batch, 2, 2)
    skeleton = vector[..., layout.skeleton_slice].reshape(*batch, layout.num_skeleton, 3)
    if head is not None:
        offset = jnp.asarray(head, vector.dtype)[..., None, :]
        contour, hands = contour + offset, hands + offset
    return HybridParts(contour=contour, hands=hands, skeleton_3d=skeleton)
