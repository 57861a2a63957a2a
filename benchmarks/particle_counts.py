"""Bootstrap-filter throughput vs particle count: the engine, a straightforward JAX filter and
NumPy side by side (and pydpf's published figures).

The model is pydpf's linear-Gaussian benchmark (``--model pydpf``, the default): state 25,
observation 1, A_ij = 0.38^(|i−j|+1), Q = I, H = e₁, R = 1, T = 1000 frames, a batch of 128
sequences, float32, systematic resampling at every frame. ``--model random`` draws dense
random dynamics and covariances the way pydpf's data generator does.

Three filters run the same data in one process:

* the engine: ``smc.run_batch`` with ``smc.LinearGaussian`` (chunking ``--chunk``, ``"auto"``);
* the straightforward JAX filter a user would write in thirty lines
  (:func:`straightforward_filter`: particles as one ``(N, 25)`` array, ``x @ A.T`` plus
  ``jax.random.normal`` noise, ``cumsum`` + ``searchsorted`` systematic resampling, one
  ``lax.scan``, ``jit(vmap(...))`` over the whole batch);
* the same filter in NumPy on a few sequences;
* three peer libraries, each in its own venv (``make bench-peers-env``, skipped with a note
  where missing; :mod:`benchmarks._peers`): on the first ``--peer-sequences`` sequences, one
  at a time, ``particles`` (N. Chopin; ``SMC`` on ``Bootstrap``, systematic resampling at every
  frame) and ``cuthbert`` (JAX; ``smc.particle_filter``, compile timed apart); and pydpf
  (PyTorch; ``ParticleFilter`` with ``SystematicResampler``) on ``--pydpf-sequences`` of the
  batch (default all) in one call, as pydpf's own benchmark runs it, so that its published
  figure can be checked against a run on this machine.

The engine and the straightforward filter alternate (``--alternations``, E S E S …) and the
table prints medians and the median of the per-pair ratios; compile time is measured apart
(lowering and compiling, before any run). Every log-evidence is checked against the exact
Kalman value. A single-sequence sweep N = 10² … 10⁶ reports per-frame time and peak memory.

    python -m benchmarks.particle_counts            # full run (about an hour on 2 cores)
    python -m benchmarks.particle_counts --quick    # batch 8, 100 frames, for a smoke test

The trackers' error and ms/frame against N (latent, CONDENSATION, MHT on the demo's held-out
wave) is a study of the latent tracker's paper: ``python -m papers.tian2005.particle_sweep``.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax import lax
from tqdm import tqdm

from benchmarks._common import device_description, peak_rss_mb, print_table, time_call, write_json
from benchmarks._peers import run_peers
from jaxtrack import smc

PYDPF_SECONDS_PER_BATCH = {"cpu": {1_000: 19.1, 10_000: 258.0}, "gpu": {1_000: 0.64, 10_000: 4.87}}


def pydpf_style_model(seed: int = 0, state_dim: int = 25, observation_dim: int = 1):
    """Random model drawn like pydpf's Linear Gaussian data generator (NumPy, then float32)."""
    rng = np.random.default_rng(seed)

    def sparse(shape, low, high, density):
        return np.where(rng.random(shape) < density, rng.uniform(low, high, shape), 0.0)

    def spd(dim, max_variance, max_covariance):
        matrix = np.diag(rng.uniform(0, max_variance, dim)) + sparse(
            (dim, dim), -max_covariance, max_covariance, 1.0) * (1 - np.eye(dim))
        return matrix.T @ matrix + 1e-3 * np.eye(dim)

    dynamics = np.diag(rng.uniform(-0.7, 0.7, state_dim)) + sparse(
        (state_dim, state_dim), -0.8, 0.8, 0.8) * (1 - np.eye(state_dim))
    dynamics *= 0.99 / max(0.99, np.max(np.abs(np.linalg.eigvals(dynamics))))
    observation = sparse((observation_dim, state_dim), -1.0, 1.0, 0.6)
    observation[0, 0] = 1.0  # observe at least one coordinate
    arrays = (dynamics, spd(state_dim, 0.3, 0.1), observation, spd(observation_dim, 0.3, 0.2),
              np.zeros(state_dim), spd(state_dim, 1.0, 0.3))
    return smc.LinearGaussian(*(jnp.asarray(a, jnp.float32) for a in arrays))


def pydpf_benchmark_model(state_dim: int = 25) -> smc.LinearGaussian:
    """pydpf's linear-Gaussian benchmark: A_ij = 0.38^(|i−j|+1), Q = I, H = e₁, R = 1,
    x₀ ~ N(0, I)."""
    index = np.arange(state_dim)
    transition = 0.38 ** (np.abs(index[:, None] - index[None, :]) + 1.0)
    observation = np.zeros((1, state_dim))
    observation[0, 0] = 1.0
    arrays = (transition, np.eye(state_dim), observation, np.eye(1), np.zeros(state_dim),
              np.eye(state_dim))
    return smc.LinearGaussian(*(jnp.asarray(a, jnp.float32) for a in arrays))


def straightforward_filter(model: smc.LinearGaussian, num_particles: int):
    """The bootstrap filter a user writes in plain JAX, as ``(key, observations) -> log Z``.

    Particles are one ``(N, state)`` array; ``x @ A.T`` plus ``jax.random.normal`` noise
    (times chol(Q) unless Q = I), Gaussian log-weights, systematic resampling by ``cumsum`` and
    ``searchsorted``, one ``lax.scan`` over frames.
    """
    transition_t = jnp.asarray(model.transition_matrix).T
    observation_t = jnp.asarray(model.observation_matrix).T
    chol_q = np.linalg.cholesky(np.asarray(model.transition_covariance, np.float64))
    noise_t = None if np.allclose(chol_q, np.eye(len(chol_q))) else jnp.asarray(chol_q.T,
                                                                                 jnp.float32)
    r_inv = np.linalg.inv(np.linalg.cholesky(np.asarray(model.observation_covariance,
                                                        np.float64)))
    r_inv_t = jnp.asarray(r_inv.T, jnp.float32)
    log_norm = float(np.log(np.abs(np.linalg.det(r_inv)))
                     - 0.5 * r_inv.shape[0] * math.log(2 * math.pi))
    chol_p_t = jnp.asarray(np.linalg.cholesky(np.asarray(model.initial_covariance,
                                                         np.float64)).T, jnp.float32)
    mean0, dim, n = jnp.asarray(model.initial_mean), model.state_dim, num_particles
    dtype = transition_t.dtype  # the model's (float32 here, whatever JAX's default float)

    def log_likelihood(x, y):
        residual = (y[None] - x @ observation_t) @ r_inv_t
        return log_norm - 0.5 * jnp.sum(residual * residual, axis=1)

    def log_mean_weight(log_weights):
        top = jnp.max(log_weights)
        return top + jnp.log(jnp.sum(jnp.exp(log_weights - top))) - math.log(n)

    def filter_one(key, observations):
        key_init, key_frames = jr.split(key)
        x = mean0 + jr.normal(key_init, (n, dim), dtype) @ chol_p_t
        log_weights = log_likelihood(x, observations[0])

        def frame(carry, inputs):
            x, log_weights, log_evidence = carry
            key, y = inputs
            key_offset, key_noise = jr.split(key)
            log_evidence = log_evidence + log_mean_weight(log_weights)
            cumulative = jnp.cumsum(jnp.exp(log_weights - jnp.max(log_weights)))
            positions = (jnp.arange(n, dtype=dtype) + jr.uniform(key_offset, (), dtype)
                         ) / n * cumulative[-1]
            ancestors = jnp.minimum(jnp.searchsorted(cumulative, positions, side="right"), n - 1)
            noise = jr.normal(key_noise, (n, dim), dtype)
            if noise_t is not None:
                noise = noise @ noise_t
            x = x[ancestors] @ transition_t + noise
            return (x, log_likelihood(x, y), log_evidence), None

        frames = observations.shape[0]
        (x, log_weights, log_evidence), _ = lax.scan(
            frame, (x, log_weights, jnp.zeros((), dtype)),
            (jr.split(key_frames, frames - 1), observations[1:]))
        return log_evidence + log_mean_weight(log_weights)

    return filter_one


def numpy_bootstrap_filter(model, observations: np.ndarray, num_particles: int, seed: int) -> float:
    """The same bootstrap filter in NumPy (systematic resampling every frame); returns log Z."""
    rng = np.random.default_rng(seed)
    F, Q, H, R, m0, P0 = (np.asarray(a, np.float32) for a in (
        model.transition_matrix, model.transition_covariance, model.observation_matrix,
        model.observation_covariance, model.initial_mean, model.initial_covariance))
    chol_q, chol_p = np.linalg.cholesky(Q), np.linalg.cholesky(P0)
    chol_r = np.linalg.cholesky(R)
    r_inv = np.linalg.inv(chol_r)
    log_norm = -np.log(np.diag(chol_r)).sum() - 0.5 * R.shape[0] * math.log(2 * math.pi)
    dim = F.shape[0]

    def log_likelihood(particles, y):
        residual = (y[None] - particles @ H.T) @ r_inv.T
        return log_norm - 0.5 * np.sum(residual * residual, axis=1)

    particles = m0 + rng.standard_normal((num_particles, dim), dtype=np.float32) @ chol_p.T
    log_weights = log_likelihood(particles, observations[0])
    log_evidence = 0.0
    for y in observations[1:]:
        top = log_weights.max()
        weights = np.exp(log_weights - top)
        total = weights.sum()
        log_evidence += top + math.log(total) - math.log(num_particles)
        cumulative = np.cumsum(weights)
        positions = (np.arange(num_particles) + rng.random()) / num_particles * cumulative[-1]
        ancestors = np.minimum(np.searchsorted(cumulative, positions, side="right"),
                               num_particles - 1)
        noise = rng.standard_normal((num_particles, dim), dtype=np.float32)
        particles = particles[ancestors] @ F.T + noise @ chol_q.T
        log_weights = log_likelihood(particles, y)
    top = log_weights.max()
    return log_evidence + top + math.log(np.exp(log_weights - top).sum()) - math.log(num_particles)


def _numpy_seconds_per_sequence(model, observations, num_particles, sequences):
    times = []
    for index in range(sequences):
        start = time.perf_counter()
        numpy_bootstrap_filter(model, np.asarray(observations[index]), num_particles, index)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def _compile(function, *args):
    """(seconds to lower and compile, the compiled function)."""
    start = time.perf_counter()
    compiled = jax.jit(function).lower(*args).compile()
    return time.perf_counter() - start, compiled


def _timed(function, *args):
    start = time.perf_counter()
    output = jax.block_until_ready(function(*args))
    return time.perf_counter() - start, output


def batch_benchmark(model, observations, particle_counts, numpy_sequences, alternations,
                    peer_sequences=0, chunk_option="auto", pydpf_sequences=None):
    """Engine and straightforward filter alternating on the whole batch; NumPy and the peer
    libraries (particles, cuthbert: :mod:`benchmarks._peers`) on a few sequences, pydpf on
    ``pydpf_sequences`` of the batch in one call (None: the whole batch).

    ``chunk_option``: the engine's ``chunk_size`` ("auto", None for the whole batch, or a
    count)."""
    rows = []
    batch, frames = observations.shape[:2]
    keys = jr.split(jr.key(1), batch)
    exact = np.asarray(jax.vmap(lambda y: smc.kalman_filter(model, y).log_evidence)(observations))
    peers = {}
    if peer_sequences > 0:
        peers = run_peers(model, observations, particle_counts, sequences=peer_sequences,
                          batched_sequences=pydpf_sequences)
    for num_particles in tqdm(particle_counts, desc="batch", leave=False):
        chunk = _chunk_size(chunk_option, model, num_particles, batch)
        engine_compile, _ = _compile(lambda k, y, c=min(chunk, batch), n=num_particles:
                                     smc.run_batch(k[:c], model, y[:c], n,
                                                   chunk_size=None).log_evidence,
                                     keys, observations)
        engine = lambda k, y, n=num_particles, c=chunk: smc.run_batch(  # noqa: E731
            k, model, y, n, chunk_size=c).log_evidence
        simple_compile, simple = _compile(jax.vmap(straightforward_filter(model, num_particles)),
                                          keys, observations)
        _timed(engine, keys, observations)  # warm: the chunk's compiled function is cached
        engine_times, simple_times = [], []
        for _ in tqdm(range(alternations), desc=f"N={num_particles}", leave=False):
            seconds, engine_evidence = _timed(engine, keys, observations)
            engine_times.append(seconds)
            seconds, simple_evidence = _timed(simple, keys, observations)
            simple_times.append(seconds)
        engine_s, simple_s = statistics.median(engine_times), statistics.median(simple_times)
        ratio = statistics.median(s / e for s, e in zip(simple_times, engine_times, strict=True))
        numpy_s = _numpy_seconds_per_sequence(model, observations, num_particles, numpy_sequences)
        peer_columns = {}
        for library, result in peers.items():
            peer_columns.update(_peer_columns(library, result, num_particles, exact,
                                              engine_s / batch))
        reference = PYDPF_SECONDS_PER_BATCH[_pydpf_platform()].get(num_particles)
        if reference is not None:  # pydpf timed 128 x 1000 frames: scale to this workload
            reference *= batch * frames / (128 * 1000)
        rows.append(dict(
            mode="batch", particles=num_particles, sequences=batch, frames=frames, chunk=chunk,
            compile_s=engine_compile, run_s=engine_s, per_sequence_s=engine_s / batch,
            per_frame_ms=1e3 * engine_s / (batch * frames),
            particle_frames_per_s=num_particles * frames * batch / engine_s,
            engine_error=_evidence_error(engine_evidence, exact),
            simple_compile_s=simple_compile, simple_run_s=simple_s,
            simple_per_sequence_s=simple_s / batch,
            simple_error=_evidence_error(simple_evidence, exact),
            speedup_vs_simple=ratio, engine_times=engine_times, simple_times=simple_times,
            numpy_per_sequence_s=numpy_s, speedup_vs_numpy=numpy_s / (engine_s / batch),
            pydpf_platform=_pydpf_platform(), pydpf_published_s=reference,
            speedup_vs_pydpf_published=None if reference is None else reference / engine_s,
            **peer_columns, peak_rss_mb=peak_rss_mb(),
        ))
    return rows


def _pydpf_platform() -> str:
    """Which of pydpf's published figures compare with this run: its GPU one on a GPU."""
    return "gpu" if jax.default_backend() in ("gpu", "cuda", "rocm") else "cpu"


def _chunk_size(option, model, num_particles, batch) -> int:
    if option == "auto":
        return smc.auto_chunk_size(model, num_particles, batch)
    return batch if option is None else min(int(option), batch)


def _chunk_argument(text: str):
    if text in ("auto", "none"):
        return None if text == "none" else text
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"--chunk must be auto, none or a positive count, "
                                         f"got {text!r}")
    return value


def _peer_columns(library, result, num_particles, exact, engine_per_sequence_s) -> dict:
    """A peer's median s/seq, its ratio to the engine's s/seq, mean |log Z − exact| (and
    cuthbert's compile time) at ``num_particles``; ``None`` where the peer was skipped."""
    run = next((entry for entry in result.get("runs", ())
                if entry["particles"] == num_particles), None)
    if run is None:
        return {f"{library}_per_sequence_s": None, f"speedup_vs_{library}": None,
                f"{library}_error": None}
    seconds = statistics.median(run["seconds"])
    log_evidence = np.asarray(run["log_evidence"], np.float64)
    columns = {
        f"{library}_per_sequence_s": seconds,
        f"speedup_vs_{library}": seconds / engine_per_sequence_s,
        f"{library}_error": float(np.mean(np.abs(log_evidence - exact[:len(log_evidence)]))),
        f"{library}_times": run["seconds"], f"{library}_log_evidence": run["log_evidence"],
        f"{library}_version": result.get("version"),
    }
    if "compile_s" in run:
        columns[f"{library}_compile_s"] = run["compile_s"]
    if "batch_seconds" in run:  # a batched peer: its whole call, and how many sequences
        columns[f"{library}_batch_s"] = run["batch_seconds"]
        columns[f"{library}_sequences"] = len(run["log_evidence"])
    return columns


def _evidence_error(log_evidence, exact) -> float:
    """Mean |log Z − exact| over the sequences; a non-finite estimate fails the benchmark."""
    log_evidence = np.asarray(log_evidence, np.float64)
    assert np.all(np.isfinite(log_evidence)), "non-finite log evidence"
    return float(np.mean(np.abs(log_evidence - exact)))


def sweep_benchmark(model, observations, particle_counts, numpy_limit):
    rows = []
    frames = observations.shape[0]
    for num_particles in tqdm(particle_counts, desc="sweep", leave=False):
        run = lambda k, n=num_particles: smc.run(k, model, observations, n).log_evidence  # noqa: E731
        repeats = 3 if num_particles <= 100_000 else 1
        compile_s, run_s, log_evidence = time_call(run, jr.key(2), repeats=repeats)
        assert np.isfinite(float(log_evidence)), "non-finite log evidence"
        numpy_s = None
        if num_particles <= numpy_limit:
            numpy_s = _numpy_seconds_per_sequence(model, observations[None], num_particles, 1)
        rows.append(dict(
            mode="single", particles=num_particles, sequences=1, frames=frames,
            compile_s=compile_s, run_s=run_s, per_sequence_s=run_s,
            per_frame_ms=1e3 * run_s / frames, particle_frames_per_s=num_particles * frames / run_s,
            numpy_per_sequence_s=numpy_s,
            speedup_vs_numpy=None if numpy_s is None else numpy_s / run_s,
            peak_rss_mb=peak_rss_mb(),
        ))
    return rows


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batch", type=int, default=128, help="sequences per batch (128)")
    parser.add_argument("--frames", type=int, default=1000, help="frames per sequence (1000)")
    parser.add_argument("--batch-particles", type=int, nargs="+", default=[100, 1_000, 10_000])
    parser.add_argument("--sweep-particles", type=int, nargs="+",
                        default=[100, 1_000, 10_000, 100_000, 1_000_000])
    parser.add_argument("--sweep-frames", type=int, default=100,
                        help="frames of the single-sequence sweep (100)")
    parser.add_argument("--numpy-sequences", type=int, default=2,
                        help="sequences the NumPy reference runs per batch configuration")
    parser.add_argument("--peer-sequences", type=int, default=2,
                        help="sequences the peer libraries (particles, cuthbert; make "
                             "bench-peers-env) run one at a time per particle count; 0 "
                             "disables every peer, pydpf included (2)")
    parser.add_argument("--pydpf-sequences", type=int, default=None,
                        help="sequences of the batch pydpf filters in one call, as its own "
                             "benchmark does (default: the whole batch)")
    parser.add_argument("--alternations", type=int, default=3,
                        help="engine / straightforward filter runs, alternating (3)")
    parser.add_argument("--chunk", type=_chunk_argument, default="auto",
                        help="the engine's sequences per chunk: auto (from the particle "
                             "state's size, smc.auto_chunk_size), none (the whole batch) or a "
                             "count (auto)")
    parser.add_argument("--model", choices=("pydpf", "random"), default="pydpf",
                        help="pydpf's benchmark model (default) or pydpf-style random dynamics")
    parser.add_argument("--quick", action="store_true", help="batch 8, 100 frames, N <= 10^5")
    parser.add_argument("--json", default="benchmarks/results/particle_counts.json")
    args = parser.parse_args(argv)
    if args.quick:
        args.batch, args.frames, args.alternations = 8, 100, 1
        args.sweep_particles = [n for n in args.sweep_particles if n <= 100_000]
    model = pydpf_benchmark_model() if args.model == "pydpf" else pydpf_style_model()
    _, observations = jax.vmap(lambda k: model.sample(k, args.frames))(
        jr.split(jr.key(0), args.batch))
    print(f"device: {device_description()}")
    print(f"model: {args.model} linear-Gaussian, state 25, observation 1, float32; batch "
          f"{args.batch} x {args.frames} frames; sweep 1 x {args.sweep_frames} frames")
    rows = batch_benchmark(model, observations, args.batch_particles, args.numpy_sequences,
                           args.alternations, args.peer_sequences, args.chunk,
                           args.pydpf_sequences)
    rows += sweep_benchmark(model, observations[0, :args.sweep_frames], args.sweep_particles,
                            numpy_limit=100_000)
    columns = [("mode", "mode", "s"), ("particles", "N", "d"), ("sequences", "seqs", "d"),
               ("chunk", "chunk", "d"), ("compile_s", "compile s", ".2f"),
               ("run_s", "run s", ".3f"), ("per_sequence_s", "s/seq", ".4f"),
               ("per_frame_ms", "ms/seq-frame", ".4f"),
               ("particle_frames_per_s", "particle-frames/s", ".3g"),
               ("simple_compile_s", "simple compile s", ".2f"),
               ("simple_run_s", "simple run s", ".3f"),
               ("simple_per_sequence_s", "simple s/seq", ".4f"),
               ("speedup_vs_simple", "x simple", ".2f"),
               ("numpy_per_sequence_s", "numpy s/seq", ".4f"),
               ("speedup_vs_numpy", "x numpy", ".1f"), ("pydpf_published_s", "pydpf s*", ".2f"),
               ("speedup_vs_pydpf_published", "x pydpf*", ".2f"),
               ("pydpf_per_sequence_s", "pydpf here s/seq", ".4f"),
               ("speedup_vs_pydpf", "x pydpf here", ".2f"),
               ("pydpf_error", "|logZ err| pydpf", ".2f"),
               ("engine_error", "|logZ err| engine", ".2f"),
               ("simple_error", "|logZ err| simple", ".2f"),
               ("particles_per_sequence_s", "particles s/seq", ".4f"),
               ("speedup_vs_particles", "x particles", ".1f"),
               ("particles_error", "|logZ err| particles", ".2f"),
               ("cuthbert_compile_s", "cuthbert compile s", ".2f"),
               ("cuthbert_per_sequence_s", "cuthbert s/seq", ".4f"),
               ("speedup_vs_cuthbert", "x cuthbert", ".1f"),
               ("cuthbert_error", "|logZ err| cuthbert", ".2f"), ("peak_rss_mb", "peak MB", ".0f")]
    print_table(rows, columns)
    write_json(args.json, {"benchmark": "particle_counts", "device": device_description(),
                           "arguments": vars(args), "rows": rows})
    print("x simple: the straightforward JAX filter's time over the engine's (median of the "
          "alternating pairs); * pydpf's published time per 128 x 1000-frame batch on this "
          f"backend ({_pydpf_platform()}), scaled to this batch x frames; particles, cuthbert: "
          "the peer libraries in their own venvs (make bench-peers-env) on the first "
          "--peer-sequences sequences, median s/seq, x = "
          "their s/seq over the engine's, log Z errors over those sequences; pydpf here: "
          "pydpf run on this machine, --pydpf-sequences of the batch in one call, its "
          "batch time per sequence")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
