"""Reading an image at sample points: bilinearly, or at the nearest pixel.

Every likelihood here reads a frame only at a pose's sample points (a patch's pixels, a strip's
grid, a border's points), with gathers, so the cost per particle does not grow with the image
size. Pixel centres are at integer coordinates (OpenCV's convention, the renderer's too), x to
the right, y down; points outside the image are clamped to its border.

Dtypes follow the inputs (:func:`float_dtype`): float32 images and markers give float32
results; integer inputs are computed in float32; float64 only when a float64 array comes in.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float, Int

__all__ = ["bilinear_sample", "float_dtype", "nearest_pixels", "sample_points"]


def float_dtype(*arrays: Array) -> jnp.dtype:
    """The promoted floating dtype of the floating inputs (float32 if there are none)."""
    floating = [a.dtype for a in arrays if jnp.issubdtype(a.dtype, jnp.floating)]
    return jnp.result_type(*floating) if floating else jnp.dtype(jnp.float32)


def bilinear_sample(image: Float[Array, "*channels height width"], x: Float[Array, "*points"],
                    y: Float[Array, "*points"], *, channel: int | None = None
                    ) -> Float[Array, "*points"]:
    """``image`` interpolated bilinearly at the points ``(x, y)`` (any matching shapes), points
    outside clamped to the border; one gather per neighbour, in ``x``'s dtype.

    ``image`` is ``(height, width)``, or ``(channels, height, width)`` with the static
    ``channel`` to read: the gather then reads that channel in place, where slicing it out
    first can make XLA copy it.
    """
    if channel is None:
        if image.ndim != 2:
            raise ValueError(f"image must be (height, width), or (channels, height, width) with "
                             f"a channel, got shape {image.shape}")
        offset = 0
    else:
        if image.ndim != 3 or not 0 <= channel < image.shape[0]:
            raise ValueError(f"channel {channel} of an image of shape {image.shape}")
        offset = channel * image.shape[1] * image.shape[2]
    height, width = image.shape[-2:]
    x = jnp.clip(x, 0, width - 1)
    y = jnp.clip(y, 0, height - 1)
    x0 = jnp.floor(x)
    y0 = jnp.floor(y)
    fx, fy = x - x0, y - y0
    x0 = x0.astype(jnp.int32)
    y0 = y0.astype(jnp.int32)
    x1 = jnp.minimum(x0 + 1, width - 1)
    y1 = jnp.minimum(y0 + 1, height - 1)
    flat = image.reshape(-1).astype(x.dtype)
    # four gathers, one per neighbour, each with its index arithmetic fused into it: one
    # gather of the four stacked indices made XLA on CPU write the stacked indices out first
    # (~0.4 ms per frame in the arm search, 33 000 points per arm). The indices are in bounds
    # by construction, but a "promise_in_bounds" (or "fill") gather makes XLA on CPU copy the
    # whole image first (~55 µs for 640 × 480 float32, 4× the gather of one pose's strips); a
    # clipping take reads it in place
    top = y0 * width + offset
    bottom = y1 * width + offset
    top_left, top_right, bottom_left, bottom_right = (
        jnp.take(flat, index, mode="clip")
        for index in (top + x0, top + x1, bottom + x0, bottom + x1))
    top = top_left + fx * (top_right - top_left)
    bottom = bottom_left + fx * (bottom_right - bottom_left)
    return top + fy * (bottom - top)


def nearest_pixels(x: Float[Array, "*points"], y: Float[Array, "*points"], height: int,
                   width: int) -> Int[Array, "*points"]:
    """Flat index ``row · width + column`` of the pixel nearest each point, clamped to the
    image (halves round up)."""
    # clamp in floating point so that far-off points cannot overflow the int32 conversion
    column = jnp.clip(jnp.floor(x + 0.5), 0, width - 1).astype(jnp.int32)
    row = jnp.clip(jnp.floor(y + 0.5), 0, height - 1).astype(jnp.int32)
    return row * width + column


def sample_points(image: Float[Array, "*channels height width"], x: Float[Array, "*points"],
                  y: Float[Array, "*points"], nearest: bool, channel: int | None = None
                  ) -> Float[Array, "*points"]:
    """``image`` at the points ``x, y`` (any matching shapes): the nearest pixel's value, or
    :func:`bilinear_sample`'s; ``channel`` as there (one channel of a ``(channels, height,
    width)`` image, read in place)."""
    if not nearest:
        return bilinear_sample(image, x, y, channel=channel)
    height, width = image.shape[-2:]
    offset = 0 if channel is None else channel * height * width
    # a clipping take: a "promise_in_bounds" gather copies the image first (bilinear_sample)
    return jnp.take(image.reshape(-1), nearest_pixels(x, y, height, width) + offset,
                    mode="clip")
