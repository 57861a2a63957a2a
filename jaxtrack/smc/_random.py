"""Fast standard normals for per-particle noise: a keyed counter hash and the inverse normal CDF.

On CPU, ``jax.random.normal`` (threefry) runs at ~80 M draws/s on this 2-core machine and takes
about two thirds of a bootstrap-filter step; NumPy's ziggurat is as fast. ``fast_normal`` keys a
32-bit integer hash (Wellons' "lowbias32", two rounds, one per word of the 64-bit JAX key) with a
counter and maps 24 bits exactly to the open interval (−1, 1), then applies √2 erf⁻¹ (Giles'
single-precision polynomials, written out: :func:`erf_inv`): ~4× the throughput of threefry
normals and 1.6× XLA's own erf⁻¹ (313, 78 and 198 M draws/s, ``python -m
benchmarks.engine_breakdown --normals``, 2026-11-26), still a pure function of (key, shape).

Statistical scope: counter-hash generators (as Philox/threefry, but with far fewer rounds) are
fine for Monte-Carlo noise; they are not cryptographic. Uniforms have 24-bit resolution, so
the largest draw is √2 erf⁻¹(1 − 2⁻²⁴) ≈ 5.4; float64 (and any other dtype) requests fall back to
``jax.random.normal``, so float64 numerics are unchanged.

``split`` and ``uniform`` are ``jax.random.split`` and ``jax.random.uniform`` bit for bit, written
out so that XLA on CPU runs them as one kernel instead of a loop (see below); the engine uses
them for its per-frame keys and the resampling draws.
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


def particle_keys(key: PRNGKeyArray, num: int) -> PRNGKeyArray:
    """``num`` keys for the particles' own draws (``init``, ``propagate``), from one key.

    For threefry keys (the default) each key is the counter hash of (key, particle index) with
    two more rounds for the second word, instead of ``split``'s threefry block per key
    (``python -m benchmarks.engine_breakdown``: 12 against 20 µs per sequence-frame at N = 10³,
    docs/engine.md).
    A model drawing with ``jax.random`` from these keys gets threefry streams as from any key;
    ``fast_normal`` gets streams that share no inner value unless both 32-bit words collide.
    Other key implementations use ``split``.
    """
    if not _is_default_threefry(key):
        return split(key, num)
    first, second = _key_words(key)
    index = lax.iota(jnp.uint32, num)
    high = _lowbias32(_lowbias32(index ^ first) ^ second)
    low = _lowbias32(_lowbias32(high ^ second) ^ first ^ jnp.uint32(0x9E3779B9))
    data = jnp.stack([high, low], axis=-1)
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return jr.wrap_key_data(data, impl="threefry2x32")
    return data


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
    return jnp.float32(math.sqrt(2.0)) * erf_inv(centred * jnp.float32(1.0 / 8388608.0))


# Giles, "Approximating the erfinv function" (GPU Computing Gems Jade, 2011), single precision:
# erf⁻¹(x) = x·p(w) with w = −log(1 − x²), one polynomial for w < 5 (|x| < 0.9966) and one in √w
# beyond. Over all 2²⁴ inputs of ``bits_to_normal`` its largest relative error is 2.9e-7 against
# float64 (XLA's float32 ``lax.erf_inv``: 5.8e-6), at 1.6x the throughput on this CPU (tests/smc/
# test_random.py checks the error; ``python -m benchmarks.engine_breakdown --normals`` the speed).
_ERF_INV_CENTRAL = (2.81022636e-08, 3.43273939e-07, -3.5233877e-06, -4.39150654e-06,
                    0.00021858087, -0.00125372503, -0.00417768164, 0.246640727, 1.50140941)
_ERF_INV_TAIL = (-0.000200214257, 0.000100950558, 0.00134934322, -0.00367342844,
                 0.00573950773, -0.0076224613, 0.00943887047, 1.00167406, 2.83297682)


def erf_inv(x: Float[Array, "..."]) -> Float[Array, "..."]:
    """float32 erf⁻¹ on (−1, 1) as one fused elementwise kernel (Giles 2011)."""
    w = -jnp.log((jnp.float32(1.0) - x) * (jnp.float32(1.0) + x))

    def horner(coefficients, t):
        value = jnp.full_like(t, coefficients[0])
        for coefficient in coefficients[1:]:
            value = value * t + jnp.float32(coefficient)
        return value

    central = horner(_ERF_INV_CENTRAL, w - jnp.float32(2.5))
    tail = horner(_ERF_INV_TAIL, jnp.sqrt(w) - jnp.float32(3.0))
    return jnp.where(w < jnp.float32(5.0), central, tail) * x


# ------------------------------------------------------------------------------------------
# jax.random.split and jax.random.uniform for threefry keys, without XLA CPU's rolled loop
# ------------------------------------------------------------------------------------------
#
# On CPU, JAX lowers the threefry2x32 hash as a loop of its five four-round blocks (to keep
# compile times down), and XLA runs that loop thunk by thunk: ~60 tiny thunks per call, which a
# particle filter pays for every frame (splitting the frame key, one key per particle, the
# resampling offset). Written out, the same hash is one fused elementwise kernel. These are
# bit-for-bit jax.random.split and jax.random.uniform for threefry2x32 keys under
# ``jax_threefry_partitionable`` (JAX's default): same keys, same draws, same filter output.
# Any other key implementation or setting falls back to jax.random itself.

_THREEFRY_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))


def _threefry2x32(key1: Array, key2: Array, count1: Array, count2: Array) -> tuple[Array, Array]:
    """The Threefry-2x32 block cipher (20 rounds, Salmon et al. 2011), unrolled."""
    def rotate_left(value, distance):
        return (value << jnp.uint32(distance)) | (value >> jnp.uint32(32 - distance))

    schedule = (key1, key2, key1 ^ key2 ^ jnp.uint32(0x1BD11BDA))
    x0, x1 = count1 + schedule[0], count2 + schedule[1]
    for block in range(5):
        for rotation in _THREEFRY_ROTATIONS[block % 2]:
            x0 = x0 + x1
            x1 = x0 ^ rotate_left(x1, rotation)
        x0 = x0 + schedule[(block + 1) % 3]
        x1 = x1 + schedule[(block + 2) % 3] + jnp.uint32(block + 1)
    return x0, x1


def _is_default_threefry(key: PRNGKeyArray) -> bool:
    if not jax.config.jax_threefry_partitionable:
        return False
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return key.ndim == 0 and jr.key_impl(key) == "threefry2x32"
    return (key.shape == (2,) and key.dtype == jnp.uint32
            and jax.config.jax_default_prng_impl == "threefry2x32")


def _threefry_bits(key: PRNGKeyArray, shape: tuple[int, ...]) -> tuple[Array, Array]:
    """The two uint32 words of threefry(key, i) for the flat index i of every position."""
    if math.prod(shape) >= 2**32:
        raise ValueError(f"shape {shape} has more than 2³² elements")
    first, second = _key_words(key)
    counter = lax.iota(jnp.uint32, math.prod(shape)).reshape(shape)
    return _threefry2x32(first, second, jnp.zeros_like(counter), counter)


def split(key: PRNGKeyArray, num: int = 2) -> PRNGKeyArray:
    """``jax.random.split(key, num)`` (bit-for-bit), as one fused kernel for threefry keys."""
    if not _is_default_threefry(key):
        return jr.split(key, num)
    high, low = _threefry_bits(key, (num,))
    data = jnp.stack([high, low], axis=-1)
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return jr.wrap_key_data(data, impl="threefry2x32")
    return data


def uniform(key: PRNGKeyArray, shape: tuple[int, ...] = (), dtype=jnp.float32
            ) -> Float[Array, "..."]:
    """``jax.random.uniform(key, shape, dtype)`` on [0, 1) (bit-for-bit), one fused kernel for
    threefry keys and float32."""
    if jnp.dtype(dtype) != jnp.dtype(jnp.float32) or not _is_default_threefry(key):
        return jr.uniform(key, shape, dtype)
    high, low = _threefry_bits(key, tuple(shape))
    # JAX's construction: 23 random mantissa bits under the exponent of 1.0, minus 1
    mantissa = ((high ^ low) >> jnp.uint32(9)) | jnp.uint32(0x3F800000)
    return jnp.maximum(lax.bitcast_convert_type(mantissa, jnp.float32) - jnp.float32(1.0), 0.0)
