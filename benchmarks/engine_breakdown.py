"""Where a bootstrap-filter step's time goes: one thing removed or swapped at a time.

On pydpf's linear-Gaussian benchmark model (state 25, observation 1, float32), a plain JAX
bootstrap filter (particles as one ``(N, 25)`` array, one ``lax.scan``, ``jit(vmap(...))`` over
sequences in chunks) is timed with each of its parts removed or swapped, side by side with the
engine (``smc.run_batch``) in one process, variants alternating, medians of ``--repeats``:

* noise: ``jax.random.normal`` (threefry), ``smc.fast_normal`` on the whole array (and with
  XLA's ``lax.erf_inv`` in place of its written-out erf⁻¹), per-particle
  keys (``jax.random.split`` or ``smc.particle_keys``) with ``fast_normal`` per particle,
  the hash bits alone, or none;
* resampling: ``searchsorted`` (the default ``scan`` method, ``sort``, ``compare_all``), the
  histogram search of ``smc.systematic_ancestors``, or none (no gather either);
* the dynamics' matmul, and the engine's per-frame records (weighted mean and best particle).

    python -m benchmarks.engine_breakdown [--particles 1000] [--batch 16] [--frames 300]
    python -m benchmarks.engine_breakdown --chunk-sweep 1 2 4 8 16 32 --batch 32 --frames 200

``--chunk-sweep`` times the engine alone over a batch vmapped in chunks of each size instead;
``--normals`` times the normal generators alone (M draws/s on a 32 x 1000 x 25 array).

Prints µs per sequence-frame and writes ``benchmarks/results/engine_breakdown.json``.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax import lax
from tqdm import tqdm

from benchmarks._common import device_description, print_table, write_json
from benchmarks.particle_counts import pydpf_benchmark_model
from jaxtrack import smc
from jaxtrack.smc import evenly_spaced_ancestors, fast_uniform_bits, particle_keys, split, uniform

VARIANTS = {
    # name: (noise, search, matmul, record)
    "threefry noise (the straightforward filter)": ("threefry", "scan", True, False),
    "fast_normal noise": ("fast", "scan", True, False),
    "fast_normal with XLA's lax.erf_inv": ("fast_xla", "scan", True, False),
    "fast_normal, per-particle keys by split": ("split", "scan", True, False),
    "fast_normal, per-particle keys by particle_keys": ("particle_keys", "scan", True, False),
    "fast_normal + per-frame mean and best": ("fast", "scan", True, True),
    "fast_normal, histogram search": ("fast", "histogram", True, False),
    "fast_normal, searchsorted method=sort": ("fast", "sort", True, False),
    "fast_normal, searchsorted method=compare_all": ("fast", "compare_all", True, False),
    "hash bits only (no erf⁻¹)": ("bits", "scan", True, False),
    "no noise": ("none", "scan", True, False),
    "no noise, no matmul": ("none", "scan", False, False),
    "no noise, no matmul, no resampling": ("none", None, False, False),
}


def plain_filter(model, num_particles, noise, search, matmul, record):
    """The bootstrap filter with the given parts, as ``(key, observations) -> log Z``."""
    transition_t = model.transition_matrix.T
    dim, n = model.state_dim, num_particles

    def log_likelihood(x, y):
        residual = y[0] - x[:, 0]
        return -0.5 * residual * residual - 0.5 * math.log(2 * math.pi)

    def draw(key):
        if noise == "threefry":
            return jr.normal(key, (n, dim))
        if noise == "fast":
            return smc.fast_normal(key, (n, dim))
        if noise in ("split", "particle_keys"):
            keys = split(key, n) if noise == "split" else particle_keys(key, n)
            return jax.vmap(lambda k: smc.fast_normal(k, (dim,)))(keys)
        if noise == "fast_xla":
            centred = (fast_uniform_bits(key, (n, dim)) >> 8).astype(jnp.float32) - 8388607.5
            return math.sqrt(2.0) * lax.erf_inv(centred * jnp.float32(1.0 / 8388608.0))
        if noise == "bits":
            return (fast_uniform_bits(key, (n, dim)) >> 8).astype(jnp.float32) * 1e-7
        return 0.0

    def resample(key, x, log_weights):
        if search is None:
            return x
        weights = jnp.exp(log_weights - jnp.max(log_weights))
        cumulative = jnp.cumsum(weights)
        offset = uniform(key)
        if search == "histogram":
            ancestors = evenly_spaced_ancestors(weights, cumulative, offset)
        else:
            positions = (jnp.arange(n) + offset) / n * cumulative[-1]
            ancestors = jnp.minimum(jnp.searchsorted(cumulative, positions, side="right",
                                                     method=search), n - 1)
        return x[ancestors]

    def filter_one(key, observations):
        key_init, key_frames = jr.split(key)
        x = jr.normal(key_init, (n, dim))

        def frame(carry, inputs):
            x, log_weights, log_evidence = carry
            key, y = inputs
            key_select, key_noise = split(key)
            top = jnp.max(log_weights)
            log_evidence += top + jnp.log(jnp.sum(jnp.exp(log_weights - top))) - math.log(n)
            x = resample(key_select, x, log_weights)
            if matmul:
                x = x @ transition_t
            x = x + draw(key_noise)
            log_weights = log_likelihood(x, y)
            summary = None
            if record:
                weights = jax.nn.softmax(log_weights)
                summary = (weights @ x, x[jnp.argmax(log_weights)])
            return (x, log_weights, log_evidence), summary

        (_, _, log_evidence), _ = lax.scan(
            frame, (x, log_likelihood(x, observations[0]), jnp.zeros((), jnp.float32)),
            (jr.split(key_frames, observations.shape[0] - 1), observations[1:]))
        return log_evidence

    return filter_one


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=1000)
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--chunk", type=int, default=16, help="sequences per vmapped chunk")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--chunk-sweep", type=int, nargs="+", default=None,
                        help="time the engine over the batch in chunks of these sizes instead")
    parser.add_argument("--normals", action="store_true",
                        help="time the normal generators alone instead")
    parser.add_argument("--json", default="benchmarks/results/engine_breakdown.json")
    args = parser.parse_args(argv)
    if args.chunk_sweep is not None and min(args.chunk_sweep) < 1:
        parser.error("--chunk-sweep sizes must be at least 1")
    for name in ("particles", "batch", "frames", "chunk", "repeats"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1")
    if args.normals:
        return normals(args)
    model = pydpf_benchmark_model()
    _, observations = jax.vmap(lambda k: model.sample(k, args.frames))(
        jr.split(jr.key(0), args.batch))
    keys = jr.split(jr.key(1), args.batch)
    if args.chunk_sweep is not None:
        return chunk_sweep(model, keys, observations, args)
    chunks = [slice(start, start + args.chunk) for start in range(0, args.batch, args.chunk)]

    def chunked(function):
        compiled = jax.jit(jax.vmap(function))
        return lambda: [compiled(keys[part], observations[part]) for part in chunks]

    functions = {name: chunked(plain_filter(model, args.particles, *parts))
                 for name, parts in VARIANTS.items()}
    functions["the engine (smc.run_batch)"] = lambda: smc.run_batch(
        keys, model, observations, args.particles, chunk_size=args.chunk).log_evidence
    for function in tqdm(functions.values(), desc="compile", leave=False):
        jax.block_until_ready(function())
    times = {name: [] for name in functions}
    for _ in tqdm(range(args.repeats), desc="repeats", leave=False):
        for name, function in functions.items():
            start = time.perf_counter()
            jax.block_until_ready(function())
            times[name].append(time.perf_counter() - start)
    reference = statistics.median(times["threefry noise (the straightforward filter)"])
    rows = [{"variant": name, "us": 1e6 * statistics.median(values)
             / (args.batch * args.frames),
             "ratio": reference / statistics.median(values), "times": values}
            for name, values in times.items()]
    print(f"device: {device_description()}")
    print(f"N = {args.particles}, batch {args.batch} in chunks of {args.chunk}, "
          f"{args.frames} frames; medians of {args.repeats}")
    print_table(rows, [("variant", "variant", "s"), ("us", "µs per sequence-frame", ".1f"),
                       ("ratio", "straightforward / this", ".2f")])
    write_json(args.json, {"benchmark": "engine_breakdown", "device": device_description(),
                           "arguments": vars(args), "rows": rows,
                           "numpy_version": np.__version__})
    return 0


def normals(args) -> int:
    """Throughput of threefry normals, ``fast_normal`` and ``fast_normal`` with XLA's erf⁻¹."""
    shape = (32, 1000, 25)

    def xla_erf_inv(key):
        centred = (fast_uniform_bits(key, shape) >> 8).astype(jnp.float32) - 8388607.5
        return math.sqrt(2.0) * lax.erf_inv(centred * jnp.float32(1.0 / 8388608.0))

    generators = {"jax.random.normal (threefry)": lambda key: jr.normal(key, shape),
                  "hash bits with XLA's lax.erf_inv": xla_erf_inv,
                  "smc.fast_normal": lambda key: smc.fast_normal(key, shape)}
    compiled = {name: jax.jit(function) for name, function in generators.items()}
    for function in compiled.values():
        jax.block_until_ready(function(jr.key(0)))
    times = {name: [] for name in compiled}
    for repeat in range(max(args.repeats, 5)):
        for name, function in compiled.items():
            start = time.perf_counter()
            jax.block_until_ready(function(jr.key(repeat)))
            times[name].append(time.perf_counter() - start)
    rows = [{"generator": name, "draws_per_s": math.prod(shape) / statistics.median(values),
             "times": values} for name, values in times.items()]
    print(f"device: {device_description()}")
    print(f"{math.prod(shape)} float32 normals per call; medians of {len(times[name])}")
    print_table(rows, [("generator", "generator", "s"), ("draws_per_s", "draws/s", ".3g")])
    write_json(args.json, {"benchmark": "normals", "device": device_description(),
                           "arguments": vars(args), "rows": rows})
    return 0


def chunk_sweep(model, keys, observations, args) -> int:
    """The engine's time per sequence-frame over the batch in chunks of each size."""
    def run(size):
        return smc.run_batch(keys, model, observations, args.particles,
                             chunk_size=size).log_evidence

    for size in tqdm(args.chunk_sweep, desc="compile", leave=False):
        jax.block_until_ready(run(size))
    times = {size: [] for size in args.chunk_sweep}
    for _ in tqdm(range(args.repeats), desc="repeats", leave=False):
        for size in args.chunk_sweep:
            start = time.perf_counter()
            jax.block_until_ready(run(size))
            times[size].append(time.perf_counter() - start)
    rows = [{"chunk": size, "us": 1e6 * statistics.median(values) / (args.batch * args.frames),
             "times": values} for size, values in times.items()]
    print(f"device: {device_description()}")
    print(f"engine, N = {args.particles}, batch {args.batch}, {args.frames} frames; medians of "
          f"{args.repeats}; auto chunk: "
          f"{smc.auto_chunk_size(model, args.particles, args.batch)}")
    print_table(rows, [("chunk", "chunk", "d"), ("us", "µs per sequence-frame", ".1f")])
    write_json(args.json, {"benchmark": "engine_chunks", "device": device_description(),
                           "arguments": vars(args), "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
