"""Batches of sequences: ``vmap`` over sequences, optional chunking, and sharding over devices."""

from __future__ import annotations

import functools
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from jaxtyping import PRNGKeyArray, PyTree

from jaxtrack.smc._filter import FilterResult, _check_threshold, filter_sequence
from jaxtrack.smc._model import StateSpaceModel

_SEQUENCES = "sequences"


def _batch_size(keys, observations) -> int:
    sizes = {jnp.shape(leaf)[0] for leaf in jax.tree.leaves(observations)}
    if len(sizes) != 1:
        raise ValueError(f"observation leaves disagree on the batch size: {sorted(sizes)}")
    (size,) = sizes
    if jnp.shape(keys)[0] != size:
        raise ValueError(f"got {jnp.shape(keys)[0]} keys for a batch of {size} sequences")
    return size


def _vmapped(model, num_particles, options):
    run_one = functools.partial(
        filter_sequence, model=model, num_particles=num_particles, axis_name=_SEQUENCES, **options
    )
    return jax.vmap(
        lambda key, observations: run_one(key, observations=observations), axis_name=_SEQUENCES
    )


@eqx.filter_jit
def _run_chunk(keys, model, observations, num_particles, options):
    return _vmapped(model, num_particles, dict(options))(keys, observations)


@eqx.filter_jit
def _run_sharded(keys, model, observations, num_particles, options, mesh):
    axis = mesh.axis_names[0]
    spec = PartitionSpec(axis)
    inner = _vmapped(model, num_particles, dict(options))
    sharded = jax.shard_map(
        inner, mesh=mesh, in_specs=(spec, spec), out_specs=spec, check_vma=False
    )
    return sharded(keys, observations)


CHUNK_MEMORY_BYTES = 256 * 2**20
"""``chunk_size="auto"`` on the CPU: the largest chunk whose particle arrays (4 copies of the
particle state: parents, children, noise and temporaries) fit in this many bytes. On this
project's 2-core CPU the time per sequence falls from chunks of 1 to 8 sequences and is flat
beyond (N = 10³ and 10⁴, docs/engine.md), so the cap only matters for large N (10⁵ and up)."""

ACCELERATOR_MEMORY_FRACTION = 8
"""``chunk_size="auto"`` on a GPU or TPU: chunks fill at most 1/8 of the device's memory (its
``bytes_limit``). There no cache favours small chunks and each chunk is a launch in turn, so the
largest chunk wins: on an H100, N = 10⁴ × 128 sequences of the 25-d model took 0.78 s as one
chunk and 1.04 s as chunks of 67 (the CPU rule's; docs/engine.md)."""


def _chunk_memory_bytes(device: jax.Device | None = None) -> int:
    device = jax.devices()[0] if device is None else device
    if device.platform == "cpu":
        return CHUNK_MEMORY_BYTES
    try:
        limit = (device.memory_stats() or {}).get("bytes_limit")
    except Exception:  # memory_stats is optional for a backend; keep the CPU rule there
        limit = None
    if not limit:
        return CHUNK_MEMORY_BYTES
    return max(CHUNK_MEMORY_BYTES, int(limit) // ACCELERATOR_MEMORY_FRACTION)


def auto_chunk_size(
    model: StateSpaceModel, num_particles: int, batch_size: int, device: jax.Device | None = None
) -> int:
    """Sequences per chunk for ``chunk_size="auto"``: as many as fit four copies of their
    particle states in :data:`CHUNK_MEMORY_BYTES` on the CPU, or in
    1/:data:`ACCELERATOR_MEMORY_FRACTION` of an accelerator's memory (``device``: JAX's default
    device if None)."""
    particle = jax.eval_shape(model.init, jax.random.key(0))
    particle_bytes = sum(leaf.size * leaf.dtype.itemsize for leaf in jax.tree.leaves(particle))
    per_sequence = 4 * num_particles * max(particle_bytes, 1)
    budget = _chunk_memory_bytes(device)
    return int(min(max(budget // per_sequence, 1), batch_size))


def run_batch(
    keys: PRNGKeyArray,
    model: StateSpaceModel,
    observations: PyTree[Any],
    num_particles: int,
    *,
    mesh: Mesh | None = None,
    chunk_size: int | str | None = "auto",
    **options,
) -> FilterResult:
    """Filter a batch of sequences with one model: equal to a loop of ``run`` over the batch.

    Args:
        keys: (sequences,) PRNG keys, one per sequence.
        observations: pytree with leading ``(sequences, time)`` axes.
        mesh: shard the sequences over ``mesh.axis_names[0]`` (the batch size must be a
            multiple of that axis' size); each device filters its sequences independently.
        chunk_size: filter at most this many sequences at a time (without ``mesh``). "auto"
            (the default): from the particle state's size, :func:`auto_chunk_size`; None: the
            whole batch at once.
        **options: ``resampler``, ``ess_threshold``, ``iterations_per_frame``, ``keep_history``
            as in ``run``.

    Returns:
        ``FilterResult`` whose fields have a leading ``sequences`` axis.
    """
    _check_threshold(options.get("ess_threshold", 1.0))
    size = _batch_size(keys, observations)
    options = tuple(sorted(options.items()))
    if mesh is not None:
        axis_size = mesh.shape[mesh.axis_names[0]]
        if size % axis_size:
            raise ValueError(
                f"batch of {size} sequences does not split evenly over mesh axis "
                f"{mesh.axis_names[0]!r} of size {axis_size}"
            )
        sharding = NamedSharding(mesh, PartitionSpec(mesh.axis_names[0]))
        keys, observations = jax.device_put((keys, observations), sharding)
        return _run_sharded(keys, model, observations, num_particles, options, mesh)
    if chunk_size == "auto":
        chunk_size = auto_chunk_size(model, num_particles, size)
    elif chunk_size is not None and (not isinstance(chunk_size, int) or chunk_size < 1):
        raise ValueError(f"chunk_size must be a positive int, 'auto' or None, got {chunk_size!r}")
    if chunk_size is None or chunk_size >= size:
        return _run_chunk(keys, model, observations, num_particles, options)
    results = []
    for start in range(0, size, chunk_size):
        part = slice(start, min(start + chunk_size, size))
        results.append(_run_chunk(
            keys[part], model, jax.tree.map(lambda leaf, part=part: leaf[part], observations),
            num_particles, options,
        ))
    return jax.tree.map(lambda *parts: jnp.concatenate(parts), *results)
