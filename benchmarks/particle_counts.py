"""Bootstrap-filter throughput vs particle count, against a NumPy reference (and pydpf's figures).

The model follows pydpf's linear-Gaussian benchmark generator: state dimension 25, observation
dimension 1, dense sparse-random dynamics with spectral radius < 1, random SPD noise covariances,
T = 1000 frames, a batch of 128 sequences. (pydpf's bias vectors are left out: they add one vector
addition per particle and change no cost.) float32, systematic resampling at every frame.

Two measurements, compile time apart from run time (median of repeats):
1. batch: 128 sequences at N in {100, 1 000, 10 000} through ``smc.run_batch`` (chunked);
2. sweep: one sequence at N = 10^2 ... 10^6.
The NumPy reference runs the same filter (same model, same observations) on a few sequences of
each configuration in the same process; the table prints JAX/NumPy speed ratios.

    python -m benchmarks.particle_counts            # full run (tens of minutes on 2 cores)
    python -m benchmarks.particle_counts --quick    # smaller batch and sweep, for a smoke test

``--tracking`` runs the other sweep instead: tracking error and ms/frame of the three trackers
(latent, CONDENSATION, MHT) on the demo's held-out wave vs N, see ``benchmarks/_tracking_sweep.py``:

    python -m benchmarks.particle_counts --tracking [--quick] [--seeds K]
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from tqdm import tqdm

from benchmarks._common import device_description, peak_rss_mb, print_table, time_call, write_json
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


def batch_benchmark(model, observations, particle_counts, numpy_sequences, chunk_size):
    rows = []
    batch, frames = observations.shape[:2]
    keys = jr.split(jr.key(1), batch)
    for num_particles in tqdm(particle_counts, desc="batch", leave=False):
        run = lambda k, y, n=num_particles: smc.run_batch(  # noqa: E731
            k, model, y, n, chunk_size=chunk_size).log_evidence
        compile_s, run_s, log_evidence = time_call(run, keys, observations, repeats=1)
        assert np.all(np.isfinite(np.asarray(log_evidence))), "non-finite log evidence"
        numpy_s = _numpy_seconds_per_sequence(model, observations, num_particles, numpy_sequences)
        reference = PYDPF_SECONDS_PER_BATCH["cpu"].get(num_particles)
        if reference is not None:  # pydpf timed 128 x 1000 frames: scale to this workload
            reference *= batch * frames / (128 * 1000)
        rows.append(dict(
            mode="batch", particles=num_particles, sequences=batch, frames=frames,
            compile_s=compile_s, run_s=run_s, per_sequence_s=run_s / batch,
            per_frame_ms=1e3 * run_s / (batch * frames),
            particle_frames_per_s=num_particles * frames * batch / run_s,
            numpy_per_sequence_s=numpy_s, speedup_vs_numpy=numpy_s / (run_s / batch),
            pydpf_cpu_s=reference,
            speedup_vs_pydpf_cpu=None if reference is None else reference / run_s,
            peak_rss_mb=peak_rss_mb(),
        ))
    return rows


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
    if "--tracking" in argv:  # the tracking sweep has its own options
        from benchmarks._tracking_sweep import main as tracking_main

        return tracking_main([argument for argument in argv if argument != "--tracking"])
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tracking", action="store_true",
                        help="run the trackers' error and speed sweep instead (its options: "
                             "--tracking --help)")
    parser.add_argument("--batch", type=int, default=128, help="sequences per batch (128)")
    parser.add_argument("--frames", type=int, default=1000, help="frames per sequence (1000)")
    parser.add_argument("--batch-particles", type=int, nargs="+", default=[100, 1_000, 10_000])
    parser.add_argument("--sweep-particles", type=int, nargs="+",
                        default=[100, 1_000, 10_000, 100_000, 1_000_000])
    parser.add_argument("--sweep-frames", type=int, default=100,
                        help="frames of the single-sequence sweep (100)")
    parser.add_argument("--numpy-sequences", type=int, default=2,
                        help="sequences the NumPy reference runs per batch configuration")
    parser.add_argument("--chunk-size", type=int, default=4,
                        help="sequences vmapped at once (4; 16 falls out of cache at N = 10^4)")
    parser.add_argument("--quick", action="store_true", help="batch 8, 100 frames, N <= 10^5")
    parser.add_argument("--json", default="benchmarks/results/particle_counts.json")
    args = parser.parse_args(argv)
    if args.quick:
        args.batch, args.frames = 8, 100
        args.sweep_particles = [n for n in args.sweep_particles if n <= 100_000]
    model = pydpf_style_model()
    _, observations = jax.vmap(lambda k: model.sample(k, args.frames))(
        jr.split(jr.key(0), args.batch))
    print(f"device: {device_description()}")
    print(f"model: linear-Gaussian, state 25, observation 1, float32; batch {args.batch} x "
          f"{args.frames} frames; sweep 1 x {args.sweep_frames} frames")
    rows = batch_benchmark(model, observations, args.batch_particles, args.numpy_sequences,
                           args.chunk_size)
    rows += sweep_benchmark(model, observations[0, :args.sweep_frames], args.sweep_particles,
                            numpy_limit=100_000)
    columns = [("mode", "mode", "s"), ("particles", "N", "d"), ("sequences", "seqs", "d"),
               ("compile_s", "compile s", ".2f"), ("run_s", "run s", ".3f"),
               ("per_sequence_s", "s/seq", ".4f"), ("per_frame_ms", "ms/frame", ".4f"),
               ("particle_frames_per_s", "particle-frames/s", ".3g"),
               ("numpy_per_sequence_s", "numpy s/seq", ".4f"),
               ("speedup_vs_numpy", "x numpy", ".1f"), ("pydpf_cpu_s", "pydpf cpu s*", ".1f"),
               ("speedup_vs_pydpf_cpu", "x pydpf", ".2f"), ("peak_rss_mb", "peak MB", ".0f")]
    print_table(rows, columns)
    write_json(args.json, {"benchmark": "particle_counts", "device": device_description(),
                           "arguments": vars(args), "rows": rows})
    print("* pydpf's published CPU time per 128 x 1000-frame batch, scaled to this batch x frames")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
