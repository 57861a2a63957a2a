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


def run_batch(
    keys: PRNGKeyArray,
    model: StateSpaceModel,
    observations: PyTree[Any],
    num_particles: int,
    *,
    mesh: Mesh | None = None,
    chunk_size: int | None = None,
    **options,
) -> FilterResult:
    """Filter a batch of sequences with one model: equal to a loop of ``run`` over the batch.

    Args:
        keys: (sequences,) PRNG keys, one per sequence.
        observations: pytree with leading ``(sequences, time)`` axes.
        mesh: shard the sequences over ``mesh.axis_names[0]`` (the batch size must be a
            multiple of that axis' size); each device filters its sequences independently.
        chunk_size: filter at most this many sequences at a time (per device with ``mesh``);
            the per-sequence cost grows with the vmapped batch on CPU (cache), so large batches
            run faster in chunks. Default: the whole batch at once.
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
