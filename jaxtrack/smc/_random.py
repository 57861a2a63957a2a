"""Fast standard normals for per-particle noise: a keyed counter hash and the inverse normal CDF.

On CPU, ``jax.random.normal`` (threefry) runs at ~65 M draws/s on this 2-core machine and takes
about two thirds of a bootstrap-filter step; NumPy's ziggurat is as fast. ``fast_normal`` keys a
32-bit integer hash (Wellons' "lowbias32", two rounds, one per word of the 64-bit JAX key) with a
counter and maps 24 bits exactly to the open interval (−1, 1), then applies √2 erf⁻¹: ~3.5× the
throughput of threefry normals, still a pure function of (key, shape).

Statistical scope: counter-hash generators (as Philox/threefry, but with far fewer rounds) are
fine for Monte-Carlo noise; they are not cryptographic. Uniforms have 24-bit resolution, so
the largest draw is √2 erf⁻¹(1 − 2⁻²⁴) ≈ 5.4; float64 (and any other dtype) requests fall back to
``jax.random.normal``, so float64 numerics are unchanged.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import jax.random as jr
from jax import lax
from jaxtyping import Array, Float, PRNGKeyArray

_MULTIPLIER_1 = 0x7FEB352D
_MULTIPLIER_2 = 0x846CA68B


def _lowbias32(x):
    """Chris Wellons' 32-bit integer hash (bias 0.17): xorshift-multiply, twice."""
    x = x ^ (x >> 16)
    x = x * jnp.uint32(_MULTIPLIER_1)
    x = x ^ (x >> 15)
    x = x * jnp.uint32(_MULTIPLIER_2)
    return x ^ (x >> 16)


def _key_words(key: PRNGKeyArray) -> tuple[Array, Array]:
    data = jr.key_data(key) if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) else key
    data = data.astype(jnp.uint32).reshape(-1)
    if data.shape[0] < 2:
        raise ValueError("fast_normal needs a key with at least two 32-bit words")
    # Fold extra words (rbg keys have four) into the two used ones.
    words = [data[0], data[1]]
    for index in range(2, data.shape[0]):
        words[index % 2] = _lowbias32(words[index % 2] ^ data[index])
    return words[0], words[1]


def fast_uniform_bits(key: PRNGKeyArray, shape: tuple[int, ...]) -> Array:
    """uint32 hash of (key, position) for every position of ``shape``."""
    first, second = _key_words(key)
    size = math.prod(shape)
    counter = lax.iota(jnp.uint32, size).reshape(shape)
    # Two rounds, one key word each: streams of different keys never share inner values
    # unless both 32-bit words collide.
    return _lowbias32(_lowbias32(counter ^ first) ^ second)


def fast_normal(
    key: PRNGKeyArray, shape: tuple[int, ...] = (), dtype=jnp.float32
) -> Float[Array, "..."]:
    """Standard normal draws of ``shape``; fast path for float32/float16/bfloat16.

    Drop-in for ``jax.random.normal(key, shape, dtype)`` inside ``propagate``; float64 requests
    use ``jax.random.normal`` itself.
    """
    dtype = jnp.dtype(dtype)
    if dtype not in (jnp.dtype(jnp.float32), jnp.dtype(jnp.float16), jnp.dtype(jnp.bfloat16)):
        return jr.normal(key, shape, dtype)
    return bits_to_normal(fast_uniform_bits(key, tuple(shape))).astype(dtype)


def bits_to_normal(bits: Array) -> Float[Array, "..."]:
    """Map uint32 bits to float32 standard normals through √2 erf⁻¹(v), v in (−1, 1).

    v = (b − (2²³ − ½)) / 2²³ for the top 24 bits b: every step is exact in float32 (b < 2²⁴,
    half-integers below 2²³ are representable), so |v| ≤ 1 − 2⁻²⁴ and erf⁻¹ never sees ±1.
    (Forming u = (b + ½)/2²⁴ first rounds the top value to u = 1 and gives an infinite draw.)
    """
    centred = (bits >> 8).astype(jnp.float32) - jnp.float32(8388607.5)
    return jnp.float32(math.sqrt(2.0)) * lax.erf_inv(centred * jnp.float32(1.0 / 8388608.0))
