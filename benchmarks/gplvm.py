"""GPLVM pose prior: training time, held-out reconstruction, μ⁻¹ and μ, with GPy side by side.

Training poses are real upper-body gestures of the *training subjects* (the ten AnimatedDrawings
clips of :mod:`jaxtrack.data.splits`' training split) seen from several views (``pose_set``), as
GPLVM features (``pose_features``: 11 link vectors in torso units, 22 numbers). The held-out
poses are whole clips of people no training clip shows: the test subject's two waves, or with
``--validation`` three clips of the validation subject (the Bandai actors), on which settings
are chosen; projected with the training template. Training sets
of ~1 000 and ~5 000 poses are taken evenly from every (clip, view) sequence of the 30 fps pool.

Measured, compile time apart from run time:
(a) ``fit_gplvm`` wall time and final eq. 1 objective (active set 200, 4 outer iterations). A
    warm-up fit with one outer iteration and the same shapes and step caps compiles every stage
    first; it runs exactly the first iteration of the timed fit, so compile ≈ warm-up − that
    iteration.
(b) held-out error of y → μ(μ⁻¹(y)) → SPM states (held-out placement) → markers, in pixels and in
    torso lengths, against PCA with the same latent dimension on the same training features and
    against the mean training pose.
(c) μ⁻¹ of 10 000 poses (float64, jitted): compiled ahead (``lower().compile()``, timed on its
    own), then the median of a few runs.
(d) μ(x) per 1 000 particles: float32 model, ``jit(vmap(model.mean))`` compiled ahead, median of
    many calls (each call's dispatch included, as a tracker calling it per frame would see).
Wall times on a shared machine move with the other jobs on it: the load average is printed and
CPU seconds (all threads of the process, or of the GPy subprocess) are reported beside them.
(e) GPy's SparseGPLVM (``--gpy-model full``: its exact GPLVM, eq. 1 over all N poses) (own
    venv, ``benchmarks/_gpy.py``) on the same ~1 000 training poses and the
    same held-out poses, from the same Isomap start: train + infer_newX wall time, held-out error,
    ratios GPy/jaxtrack. GPy runs with OpenBLAS on one thread (``--gpy-blas-threads``), as
    ``fit_gplvm`` does: on this 2-core machine OpenBLAS's threads wait on each other at every
    small factorisation, and GPy on 1 000 poses took 162–183 s with the default threads and
    17–33 s with one; the setting is in the JSON. GPy's objective (the negative log marginal
    likelihood of its sparse model on all N poses) and jaxtrack's (eq. 1 on the 200 active
    poses) are different quantities; both are printed, neither is a ratio.
(f) (a), (b) and (e) again on further training subsets of the first size (``--subsets``, 5: the
    same number of frames per sequence at other phases), jaxtrack then GPy on each in the same
    run; held-out error moves by ±0.5 px between subsets for both, so the verdict is taken on
    the medians over subsets (time, error and their ratios).

(g) ``--inverse reconstruction``: jaxtrack's held-out error through μ⁻¹ = argmin ½|y − μ(x)|²
    instead of eq. 5. With ``--gpy-model full`` GPy's trained model (its latents, α, γ and
    noise: the same kernel as eq. 1) is also loaded into a jaxtrack ``GPLVM`` (μ equal to
    GPy's to ~1e-5) and its held-out poses inverted by the same μ⁻¹ as jaxtrack's, so the
    two learned manifolds are compared through one inverse as well as each through its own.

    python -m benchmarks.gplvm                 # full run (~4 minutes on 2 cores, GPy ~1 of them)
    python -m benchmarks.gplvm --skip-gpy      # without the GPy reference
    python -m benchmarks.gplvm --quick         # small sizes, no GPy: a 1–2 minute smoke test
"""

from __future__ import annotations

import argparse
import inspect
import os
import resource
import statistics
import threading
import time
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from tqdm import tqdm

from benchmarks._common import (
    device_description,
    peak_rss_mb,
    print_table,
    time_compiled,
    write_json,
)
from benchmarks._gpy import run_gpy_reference
from jaxtrack.body import SPM_MARKERS, marker_edges
from jaxtrack.data.clip_sets import GESTURE_CLIPS, PRIOR_CLIPS
from jaxtrack.data.splits import check_disjoint
from jaxtrack.priors.gplvm import (
    GPLVM,
    INVERSE_OBJECTIVES,
    OPTIMISERS,
    KernelParameters,
    fit_gplvm,
    initial_latents,
    plot_latent_space,
)
from jaxtrack.priors.poses import (
    PoseSet,
    clip_motions,
    markers_of,
    pose_features,
    pose_set,
    states_from_features,
)

TRAINING_CLIPS = PRIOR_CLIPS["gestures"]
"""The training subjects' upper-body gestures (four people; :mod:`jaxtrack.data.splits`)."""
HELD_OUT_CLIPS = GESTURE_CLIPS["test"]
"""The test subject's two waves (cmu_1006): only ever reported."""
VALIDATION_CLIPS = GESTURE_CLIPS["validation"]
"""``--validation``: settings are chosen on these clips of a validation subject (the Bandai
actors) instead, so that the held-out clips above only report. The clips of
:mod:`papers.tian2005.tracking`'s comparison, so that both choose on the same people."""


def split(validation: bool) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(training clips, held-out clips) of the benchmark, or of its validation split: split by
    subject, never by take (:func:`jaxtrack.data.splits.check_disjoint`)."""
    held_out = VALIDATION_CLIPS if validation else HELD_OUT_CLIPS
    check_disjoint(TRAINING_CLIPS, held_out)
    return TRAINING_CLIPS, held_out


# ---------------------------------------------------------------------------------- data


def even_rows(sequence_ids: np.ndarray, count: int) -> np.ndarray:
    """``count`` row indices spread evenly over every sequence, in proportion to its length.

    Rows of one id are consecutive; each keeps ``round(length · count / total)`` rows (largest
    remainders, so the total is exactly ``count``) at evenly spaced frames, in order.
    """
    ids, starts, lengths = np.unique(sequence_ids, return_index=True, return_counts=True)
    total = int(lengths.sum())
    if not 0 < count <= total:
        raise ValueError(f"count must be in [1, {total}], got {count}")
    quota = lengths * count / total
    keep = np.floor(quota).astype(int)
    keep[np.argsort(keep - quota)[: count - keep.sum()]] += 1
    rows = [start + np.round(np.linspace(0, length - 1, k)).astype(int)
            for start, length, k in zip(starts, lengths, keep, strict=True) if k > 0]
    return np.sort(np.concatenate(rows))


def shifted_rows(sequence_ids: np.ndarray, count: int, seed: int) -> np.ndarray:
    """Like :func:`even_rows`, but each sequence's evenly spaced frames start at a random phase.

    ``seed`` 0 is :func:`even_rows` itself; other seeds give other ``count``-pose training sets
    with the same number of rows per sequence (``--subsets``).
    """
    rows = even_rows(sequence_ids, count)
    if seed == 0:
        return rows
    rng = np.random.default_rng(seed)
    shifted = []
    for sequence in np.unique(sequence_ids[rows]):
        frames = np.flatnonzero(sequence_ids == sequence)
        keep = int(np.sum(sequence_ids[rows] == sequence))
        spacing = len(frames) / keep
        positions = np.floor(rng.uniform(0.0, spacing) + spacing * np.arange(keep)).astype(int)
        shifted.append(frames[np.minimum(positions, len(frames) - 1)])
    return np.sort(np.concatenate(shifted))


def subset(poses: PoseSet, rows: np.ndarray) -> PoseSet:
    """The pose set restricted to ``rows`` (sequence ids keep their meaning)."""
    return PoseSet(states=poses.states[rows], markers_2d=poses.markers_2d[rows],
                   sequence_ids=poses.sequence_ids[rows], sequences=poses.sequences,
                   template=poses.template, fps=poses.fps, image_size=poses.image_size)


def features_of(poses: PoseSet) -> np.ndarray:
    with jax.enable_x64(True):
        return np.asarray(pose_features(jnp.asarray(poses.states), poses.template))


# ---------------------------------------------------------------------------------- errors


def marker_errors(features: np.ndarray, held_out: PoseSet) -> dict:
    """Pixel error of reconstructed features, placed where the held-out poses are.

    The features become SPM states with the held-out rows' own (log scale, x, y), then markers
    with the (training) template, compared with the held-out markers the states were fitted to.
    """
    with jax.enable_x64(True):
        states = states_from_features(jnp.asarray(features), jnp.asarray(held_out.states[:, :3]),
                                      held_out.template)
        markers = markers_of(states, held_out.template)
    per_marker = np.linalg.norm(markers - held_out.markers_2d, axis=-1)  # (poses, markers)
    per_pose = per_marker.mean(axis=1)
    torso = per_pose / held_out.torso_lengths()
    return {"error_px": float(per_pose.mean()), "error_p95_px": float(np.percentile(per_pose, 95)),
            "error_torso": float(torso.mean()), "error_max_px": float(per_marker.max())}


def pca_reconstruction(train: np.ndarray, test: np.ndarray, latent_dim: int) -> np.ndarray:
    mean = train.mean(axis=0)
    _, _, components = np.linalg.svd(train - mean, full_matrices=False)
    basis = components[:latent_dim]
    return mean + (test - mean) @ basis.T @ basis


# ---------------------------------------------------------------------------------- jaxtrack


# Compiled ahead by time_compiled (GPLVM.inverse is not jitted: called eagerly it retraces and
# recompiles its solve on every call). A GPLVM is a pytree of arrays only, so it is an argument.
def _inverse(model, poses, objective="posterior"):
    result = model.inverse(poses, objective=objective)
    return result.latents, result.result == optx.RESULTS.successful


def _reconstruct(model, poses, objective="posterior"):
    latents, converged = _inverse(model, poses, objective)
    return jax.vmap(model.mean)(latents), converged


# untimed (GPy's model through jaxtrack's μ⁻¹): compiled once for all subsets
_reconstruct_jit = jax.jit(_reconstruct, static_argnames="objective")


def _means(model, latents):
    return jax.vmap(model.mean)(latents)


def _means_and_variances(model, latents):
    return jax.vmap(model.mean_and_variance)(latents)


def fit_options(args) -> dict:
    """``fit_gplvm`` arguments from the command line."""
    options = dict(latent_dim=args.latent_dim, active_size=args.active_size,
                   iterations=args.iterations, active_steps=args.active_steps,
                   inactive_steps=args.inactive_steps, optimiser=args.optimiser)
    return options


def train_jaxtrack(features: np.ndarray, args, label: str):
    """Warm-up fit (one outer iteration, compiles every stage), then the timed fit."""
    options = fit_options(args)
    del options["iterations"]
    tqdm.write(f"[{label}] warm-up fit (1 iteration, compiles) on {len(features)} poses")
    warm = fit_gplvm(features, iterations=1, **options)
    tqdm.write(f"[{label}] timed fit ({args.iterations} iterations)")
    cpu = time.process_time()
    fit = fit_gplvm(features, **fit_options(args))
    cpu = time.process_time() - cpu
    first_iteration = fit.trace[0]["seconds"]
    compile_s = max(warm.seconds - warm.init_seconds - first_iteration, 0.0)
    return fit, compile_s, cpu


def held_out_jaxtrack(fit, held_out_features: np.ndarray, held_out: PoseSet,
                      objective: str = "posterior") -> dict:
    with jax.enable_x64(True):
        poses = jnp.asarray(held_out_features)
        compile_s, run_s, cpu, (reconstructions, converged) = time_compiled(
            partial(_reconstruct, objective=objective), fit.model, poses, repeats=3)
    return {"inverse_compile_s": compile_s, "inverse_s": run_s, "inverse_cpu_s": cpu,
            "converged": float(np.mean(np.asarray(converged))),
            **marker_errors(np.asarray(reconstructions), held_out)}


def inverse_timing(fit, poses: np.ndarray, label: str, objective: str = "posterior") -> dict:
    with jax.enable_x64(True):
        compile_s, run_s, cpu, (_, converged) = time_compiled(
            partial(_inverse, objective=objective), fit.model, jnp.asarray(poses), repeats=3)
    return {"what": f"μ⁻¹ (float64, {objective})", "model": label, "count": len(poses),
            "compile_s": compile_s, "run_s": run_s, "cpu_s": cpu,
            "per_1000_ms": 1e3 * run_s / len(poses) * 1e3,
            "throughput_per_s": len(poses) / run_s, "converged": float(np.mean(converged))}


def mean_timing(fit, counts, repeats: int, label: str) -> list[dict]:
    model = fit.model.astype(jnp.float32)
    rng = np.random.default_rng(0)
    training = np.asarray(fit.model.latents)
    rows = []
    for count in counts:
        picks = training[rng.integers(0, len(training), count)]
        latents = jnp.asarray(picks + 0.1 * rng.standard_normal(picks.shape), jnp.float32)
        for what, function in (("μ (float32)", _means), ("μ, σ² (float32)", _means_and_variances)):
            compile_s, run_s, cpu, output = time_compiled(function, model, latents,
                                                          repeats=repeats)
            assert jax.tree.leaves(output)[0].dtype == jnp.float32
            rows.append({"what": what, "model": label, "count": count, "compile_s": compile_s,
                         "run_s": run_s, "cpu_s": cpu, "per_1000_ms": 1e3 * run_s / count * 1e3,
                         "throughput_per_s": count / run_s})
    return rows


# ---------------------------------------------------------------------------------- GPy


def with_elapsed_bar(description: str, function, *args, **kwargs):
    """Run ``function`` in a thread while a bar shows the elapsed seconds."""
    outcome = {}
    worker = threading.Thread(target=lambda: outcome.update(value=function(*args, **kwargs)))
    worker.start()
    with tqdm(desc=description, unit="s", bar_format="{desc}: {elapsed} {postfix}") as bar:
        while worker.is_alive():
            worker.join(1.0)
            bar.update(1)
    return outcome["value"]


def _gpy_setting(args) -> str:
    return f"sparse, M={args.active_size}" if args.gpy_model == "sparse" else "full"


def run_gpy(train_features: np.ndarray, held_out_features: np.ndarray, held_out: PoseSet,
            args) -> dict:
    # GPy's GPLVMs have a zero mean: give it centred data (as fit_gplvm centres inside) and the
    # same Isomap start, and add the training mean back to its reconstructions.
    mean = train_features.mean(axis=0)
    centred = train_features - mean
    start, description = initial_latents(centred, args.latent_dim, "isomap")
    names = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    saved = {name: os.environ.get(name) for name in names}
    if args.gpy_blas_threads > 0:  # the subprocess inherits the environment
        os.environ.update({name: str(args.gpy_blas_threads) for name in names})
    tick, cpu = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        result = with_elapsed_bar(
            f"GPy {_gpy_setting(args)} GPLVM (N={len(centred)}, "
            f"max_iters={args.gpy_max_iters}, BLAS threads {args.gpy_blas_threads or 'default'})",
            run_gpy_reference, centred, held_out_features - mean, latent_dim=args.latent_dim,
            num_inducing=args.active_size, max_iters=args.gpy_max_iters, model=args.gpy_model,
            init_latents=start, seed=0, timeout=args.gpy_timeout)
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
    wall = time.perf_counter() - tick
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - cpu.ru_utime - cpu.ru_stime
    if "skipped" in result:
        return {"skipped": result["skipped"]}
    errors = marker_errors(np.asarray(result["reconstructions"]) + mean, held_out)
    keep = {key: value for key, value in result.items() if not isinstance(value, np.ndarray)}
    same = {}
    if args.gpy_model == "full":
        model = gpy_full_model(result, centred, mean)
        with jax.enable_x64(True):
            reconstructions, _ = _reconstruct_jit(model, jnp.asarray(held_out_features),
                                                  objective=args.inverse)
            check = jax.vmap(model.mean)(jnp.asarray(result["test_latents"]))
        same = {"same_inverse": args.inverse,
                "same_inverse_error_px": marker_errors(np.asarray(reconstructions),
                                                       held_out)["error_px"],
                "transplant_max_abs_diff": float(np.max(np.abs(
                    np.asarray(check) - result["reconstructions"] - mean)))}
    return {**keep, **errors, **same, "init": description, "subprocess_wall_s": wall,
            "subprocess_cpu_s": cpu, "blas_threads": args.gpy_blas_threads or "default"}


def gpy_full_model(result: dict, centred: np.ndarray, mean: np.ndarray) -> GPLVM:
    """GPy's trained exact GPLVM as a jaxtrack :class:`GPLVM` (every pose active).

    Same kernel (isotropic RBF + Gaussian noise): α = GPy's RBF variance, γ = 1/lengthscale²,
    β = 1/noise variance, X = GPy's latents. μ then equals GPy's ``predict`` (checked on its
    test latents: ``transplant_max_abs_diff``), so both models can be inverted by one μ⁻¹.
    """
    with jax.enable_x64(True):
        kernel = KernelParameters.create(alpha=result["rbf_variance"],
                                         beta=1.0 / result["noise_variance"],
                                         gamma=1.0 / result["rbf_lengthscale"] ** 2)
        latents = jnp.asarray(result["train_latents"])
        return GPLVM.from_active_set(kernel, jnp.asarray(centred), jnp.asarray(mean), latents,
                                     jnp.arange(latents.shape[0]))


def subset_record(seed: int, ours: dict, gpy: dict | None, load: float | None = None) -> dict:
    """One training subset's jaxtrack and GPy time and held-out error, with their ratios."""
    record = {"subset": seed, "load_1min": os.getloadavg()[0] if load is None else load,
              "jaxtrack_train_s": ours["train_s"], "jaxtrack_total_s": ours["total_s"],
              "jaxtrack_error_px": ours["error_px"]}
    if gpy is not None and "skipped" not in gpy:
        record.update({
            "gpy_train_s": gpy["train_seconds"],
            "gpy_total_s": gpy["train_seconds"] + gpy["inverse_seconds"],
            "gpy_error_px": gpy["error_px"]})
        if "same_inverse_error_px" in gpy:
            record["gpy_same_inverse_error_px"] = gpy["same_inverse_error_px"]
            record["error_gpy_same_inverse_over_jaxtrack"] = (gpy["same_inverse_error_px"]
                                                              / ours["error_px"])
        record.update({
            "train_time_gpy_over_jaxtrack": record["gpy_train_s"] / record["jaxtrack_train_s"],
            "time_gpy_over_jaxtrack": record["gpy_total_s"] / record["jaxtrack_total_s"],
            "error_gpy_over_jaxtrack": record["gpy_error_px"] / record["jaxtrack_error_px"]})
    return record


def subset_medians(subsets: list[dict]) -> dict:
    """Median of every numeric column over the subsets, and the ratios of the medians."""
    keys = [key for key in subsets[0] if key != "subset"
            and all(isinstance(record.get(key), float) for record in subsets)]
    medians = {key: float(np.median([record[key] for record in subsets])) for key in keys}
    if "gpy_train_s" in medians:
        medians.update({
            "ratio_of_medians_train_time_gpy_over_jaxtrack":
                medians["gpy_train_s"] / medians["jaxtrack_train_s"],
            "ratio_of_medians_time_gpy_over_jaxtrack":
                medians["gpy_total_s"] / medians["jaxtrack_total_s"],
            "ratio_of_medians_error_gpy_over_jaxtrack":
                medians["gpy_error_px"] / medians["jaxtrack_error_px"]})
    if "gpy_same_inverse_error_px" in medians:
        medians["ratio_of_medians_error_gpy_same_inverse_over_jaxtrack"] = (
            medians["gpy_same_inverse_error_px"] / medians["jaxtrack_error_px"])
    return medians


# ---------------------------------------------------------------------------------- main


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 5000],
                        help="training set sizes (1000 5000); GPy runs on the first")
    parser.add_argument("--active-size", type=int, default=200)
    defaults = inspect.signature(fit_gplvm).parameters
    for name, what in (("iterations", "outer iterations T"),
                       ("active_steps", "BFGS step cap of eq. 1"),
                       ("inactive_steps", "BFGS step cap of each eq. 2 solve")):
        default = defaults[name].default
        parser.add_argument("--" + name.replace("_", "-"), type=int, default=default,
                            help=f"{what} ({default}, fit_gplvm's default)")
    parser.add_argument("--optimiser", choices=OPTIMISERS,
                        default=defaults["optimiser"].default,
                        help="eq. 1's minimiser (bfgs, fit_gplvm's default)")
    parser.add_argument("--inverse", choices=INVERSE_OBJECTIVES,
                        default=inspect.signature(GPLVM.inverse).parameters["objective"].default,
                        help="jaxtrack's μ⁻¹ for the held-out error: eq. 5 (posterior, the "
                             "default) or argmin ½|y − μ(x)|²; with --gpy-model full GPy's "
                             "model is also inverted this way")
    parser.add_argument("--subsets", type=int, default=5,
                        help="training subsets of the first size (other frames of every "
                             "sequence) on which jaxtrack and GPy both run; medians compared (5)")
    parser.add_argument("--latent-dim", type=int, default=2)
    parser.add_argument("--views", type=int, default=5, help="views per clip (5)")
    parser.add_argument("--inverse-poses", type=int, default=10_000,
                        help="poses for the μ⁻¹ timing (10 000)")
    parser.add_argument("--mean-counts", type=int, nargs="+", default=[1_000, 10_000],
                        help="particle counts for the μ timing")
    parser.add_argument("--mean-repeats", type=int, default=200)
    parser.add_argument("--gpy-max-iters", type=int, default=300,
                        help="GPy L-BFGS-B iteration/evaluation cap (300: ~2.5 min at N=1000)")
    parser.add_argument("--gpy-model", choices=("sparse", "full"), default="sparse",
                        help="GPy's SparseGPLVM with M = --active-size inducing inputs (sparse, "
                             "default) or its exact GPLVM over all N poses (full: eq. 1 itself, "
                             "~3× GPy sparse's time)")
    parser.add_argument("--gpy-timeout", type=float, default=1800.0)
    parser.add_argument("--gpy-blas-threads", type=int, default=1,
                        help="OpenBLAS/OpenMP/MKL threads of the GPy subprocess (1, as fit_gplvm "
                             "uses; 0 = the libraries' default)")
    parser.add_argument("--skip-gpy", action="store_true")
    validation_names = ", ".join(clip.split("/")[-1] for clip in VALIDATION_CLIPS)
    parser.add_argument("--validation", action="store_true",
                        help=f"train without and score on the validation clips "
                             f"({validation_names}) instead of the held-out ones: for choosing "
                             f"settings")
    parser.add_argument("--quick", action="store_true",
                        help="sizes 400 800, active 100, 2 iterations, 2 000 μ⁻¹ poses, no GPy")
    parser.add_argument("--json", default=None,
                        help="default benchmarks/results/gplvm.json (gplvm_quick.json)")
    parser.add_argument("--plot", default=None,
                        help="default benchmarks/results/gplvm_latent_space.png (…_quick.png)")
    args = parser.parse_args(argv)
    if args.quick:
        args.sizes, args.active_size, args.iterations = [400, 800], 100, 2
        args.inverse_poses, args.mean_repeats, args.skip_gpy = 2_000, 50, True
        args.subsets = 1
    suffix = ("_quick" if args.quick else "") + ("_validation" if args.validation else "")
    training_clips, held_out_clips = split(args.validation)
    args.json = args.json or f"benchmarks/results/gplvm{suffix}.json"
    args.plot = args.plot or f"benchmarks/results/gplvm_latent_space{suffix}.png"
    Path(args.plot).parent.mkdir(parents=True, exist_ok=True)  # git ignores it: not in a clone
    load_start = os.getloadavg()
    started = time.perf_counter()
    print(f"device: {device_description()}")
    print(f"load average at start (1, 5, 15 min): {load_start[0]:.2f} {load_start[1]:.2f} "
          f"{load_start[2]:.2f} on {os.cpu_count()} cores")

    # data: a 30 fps pool of training poses, held-out clips with the training template, and
    # the held-out clips from many more views for the μ⁻¹ timing
    tick = time.perf_counter()
    pool = pose_set(clip_motions(training_clips), views=args.views)
    held_out_motions = clip_motions(held_out_clips)
    held_out = pose_set(held_out_motions, views=args.views, template=pool.template)
    timing_views = -(-args.inverse_poses // (len(held_out.states) // args.views))
    timing = pose_set(held_out_motions, views=timing_views, template=pool.template)
    timing_features = features_of(subset(timing, even_rows(timing.sequence_ids,
                                                           args.inverse_poses)))
    held_out_features = features_of(held_out)
    print(f"data: {len(training_clips)} training clips x {args.views} views = "
          f"{len(pool.states)} poses at 30 fps; held out {len(held_out_clips)} clips x "
          f"{args.views} views = {len(held_out.states)} poses (median torso "
          f"{np.median(held_out.torso_lengths()):.0f} px); μ⁻¹ timing: {len(timing_features)} "
          f"held-out poses from {timing_views} views ({time.perf_counter() - tick:.1f} s)")
    with jax.enable_x64(True):
        floor = markers_of(jnp.asarray(held_out.states), held_out.template)
    floor_px = float(np.linalg.norm(floor - held_out.markers_2d, axis=-1).mean())

    rows, speed_rows, fits, traces = [], [], {}, {}
    mean_pose = np.broadcast_to(features_of(pool).mean(axis=0), held_out_features.shape)
    rows.append({"method": "mean pose", "poses": len(pool.states), "setting": "0-d",
                 **marker_errors(mean_pose, held_out)})
    for size in args.sizes:
        train = subset(pool, even_rows(pool.sequence_ids, size))
        features = features_of(train)
        fit, compile_s, train_cpu_s = train_jaxtrack(features, args, f"jaxtrack N={size}")
        fits[size] = (fit, train)
        traces[size] = {"init": fit.init, "init_seconds": fit.init_seconds, "trace": fit.trace}
        stages = {stage: sum(row["stage_seconds"][stage] for row in fit.trace)
                  for stage in fit.trace[0]["stage_seconds"]}
        tqdm.write(f"[jaxtrack N={size}] train {fit.seconds:.1f} s wall, {train_cpu_s:.1f} s CPU: "
                   f"init {fit.init_seconds:.1f} s, "
                   + ", ".join(f"{stage} {seconds:.1f} s" for stage, seconds in stages.items()))
        held = held_out_jaxtrack(fit, held_out_features, held_out, args.inverse)
        rows.append({
            "method": "jaxtrack", "poses": size,
            "setting": f"active {min(args.active_size, size)}, T={args.iterations}, "
                       f"{args.optimiser} {args.active_steps}, μ⁻¹ {args.inverse}",
            "train_compile_s": compile_s, "train_s": fit.seconds, "init_s": fit.init_seconds,
            "objective": fit.trace[-1]["objective"], **held,
            "first_run_s": compile_s + fit.seconds + held["inverse_compile_s"] + held["inverse_s"],
            "total_s": fit.seconds + held["inverse_s"],
            "cpu_s": train_cpu_s + held["inverse_cpu_s"],
            "peak_rss_mb": peak_rss_mb()})
        tick = time.perf_counter()
        pca = pca_reconstruction(features, held_out_features, args.latent_dim)
        rows.append({"method": "PCA", "poses": size, "setting": f"q={args.latent_dim}",
                     "train_s": time.perf_counter() - tick, **marker_errors(pca, held_out)})
        tqdm.write(f"[jaxtrack N={size}] μ⁻¹ of {len(timing_features)} poses")
        speed_rows.append(inverse_timing(fit, timing_features, f"N={size}", args.inverse))
        speed_rows += mean_timing(fit, args.mean_counts, args.mean_repeats, f"N={size}")

    gpy = None
    if not args.skip_gpy:
        size = args.sizes[0]
        fit, train = fits[size]
        gpy = run_gpy(features_of(train), held_out_features, held_out, args)
        if "skipped" in gpy:
            print(f"GPy skipped: {gpy['skipped']}")
        else:
            rows.append({
                "method": "GPy", "poses": size,
                "setting": f"{_gpy_setting(args)}, max_iters={args.gpy_max_iters}, "
                           f"{args.gpy_blas_threads or 'default'} BLAS thr.",
                "train_s": gpy["train_seconds"], "objective": gpy["final_objective"],
                "inverse_s": gpy["inverse_seconds"],
                "total_s": gpy["train_seconds"] + gpy["inverse_seconds"],
                "cpu_s": gpy["subprocess_cpu_s"],
                **{key: gpy[key] for key in ("error_px", "error_p95_px", "error_torso",
                                             "error_max_px")}})
            if "same_inverse_error_px" in gpy:
                rows.append({"method": "GPy model, jaxtrack's μ⁻¹", "poses": size,
                             "setting": f"full, μ⁻¹ {args.inverse}",
                             "error_px": gpy["same_inverse_error_px"]})

    # the same comparison on more training subsets of the first size (other frames of every
    # sequence), jaxtrack and GPy one after the other on each; medians over all subsets
    size = small = args.sizes[0]
    first = next(row for row in rows if row["method"] == "jaxtrack" and row["poses"] == size)
    subsets = [subset_record(0, first, gpy)]
    for seed in range(1, args.subsets):
        train = subset(pool, shifted_rows(pool.sequence_ids, size, seed))
        features = features_of(train)
        tqdm.write(f"[subset {seed}] jaxtrack fit on {size} poses (compiled by the first)")
        load = os.getloadavg()[0]
        fit = fit_gplvm(features, progress=False, **fit_options(args))
        held = held_out_jaxtrack(fit, held_out_features, held_out, args.inverse)
        ours = {"train_s": fit.seconds, "total_s": fit.seconds + held["inverse_s"], **held}
        theirs = None if args.skip_gpy else run_gpy(features, held_out_features, held_out, args)
        subsets.append(subset_record(seed, ours, theirs, load))

    # the latent space of the smallest model
    fit, train = fits[args.sizes[0]]
    placement = np.median(train.states[:, :3], axis=0)

    def decode(latent):
        with jax.enable_x64(True):
            features = fit.model.mean(jnp.asarray(latent, jnp.float64))
            states = states_from_features(features[None], jnp.asarray(placement)[None],
                                          train.template)
            return markers_of(states, train.template)[0]

    names = [name.split("/")[-1] for name in train.clip_names]
    plot = plot_latent_space(fit.model, args.plot, labels=names, decode=decode,
                             edges=marker_edges(SPM_MARKERS))

    print()
    print(f"held-out error |y − μ(μ⁻¹(y))| as markers: mean over {len(held_out.states)} poses of "
          f"the mean marker distance (states→markers floor {floor_px:.1e} px)")
    columns = [("method", "method", "s"), ("poses", "N", "d"), ("setting", "setting", "s"),
               ("train_compile_s", "compile s", ".1f"), ("train_s", "train s", ".2f"),
               ("objective", "objective*", ".1f"), ("inverse_compile_s", "μ⁻¹ compile s", ".1f"),
               ("inverse_s", "μ⁻¹ s", ".2f"), ("converged", "conv", ".3f"),
               ("total_s", "train+μ⁻¹ s", ".2f"), ("cpu_s", "cpu s†", ".1f"),
               ("error_px", "err px", ".2f"),
               ("error_p95_px", "p95 px", ".2f"), ("error_torso", "err/torso", ".4f")]
    print_table(rows, columns)
    print(f"* jaxtrack: eq. 1 on the active set; GPy: negative log marginal likelihood of its "
          f"{args.gpy_model} model on all N. Different quantities, not comparable.")
    print("† CPU seconds (all threads) of the timed train + one μ⁻¹ run; for GPy of its whole"
          " subprocess (python and GPy import included). Less sensitive to load than wall time.")
    print()
    print("speed (float64 μ⁻¹ of held-out poses, max 64 BFGS steps; float32 μ via jit(vmap))")
    speed_columns = [("what", "what", "s"), ("model", "model", "s"), ("count", "count", "d"),
                     ("compile_s", "compile s", ".2f"), ("run_s", "run s", ".4g"),
                     ("cpu_s", "cpu s", ".4g"),
                     ("per_1000_ms", "ms / 1000", ".4g"), ("throughput_per_s", "per s", ".3g"),
                     ("converged", "conv", ".3f")]
    print_table(speed_rows, speed_columns)

    ratios = {}
    by_method = {(row["method"], row["poses"]): row for row in rows}
    small = args.sizes[0]
    ours, pca_row = by_method[("jaxtrack", small)], by_method[("PCA", small)]
    for size in args.sizes:
        ratios[f"error_pca_over_jaxtrack_N{size}"] = (by_method[("PCA", size)]["error_px"]
                                                      / by_method[("jaxtrack", size)]["error_px"])
    if gpy is not None and "skipped" not in gpy:
        theirs = by_method[("GPy", small)]
        ratios.update({
            "time_gpy_over_jaxtrack": theirs["total_s"] / ours["total_s"],
            "time_gpy_over_jaxtrack_first_run": theirs["total_s"] / ours["first_run_s"],
            "train_time_gpy_over_jaxtrack": theirs["train_s"] / ours["train_s"],
            "cpu_gpy_over_jaxtrack": theirs["cpu_s"] / ours["cpu_s"],
            "error_gpy_over_jaxtrack": theirs["error_px"] / ours["error_px"],
            **({"error_gpy_same_inverse_over_jaxtrack":
                gpy["same_inverse_error_px"] / ours["error_px"]}
               if "same_inverse_error_px" in gpy else {}),
            "error_gpy_over_pca": theirs["error_px"] / pca_row["error_px"],
        })
    print()
    for key, value in ratios.items():
        print(f"{key}: {value:.3g}")
    medians = subset_medians(subsets)
    ratios.update({f"subsets_median_{key}": value for key, value in medians.items()
                   if "over" in key})
    print()
    print(f"jaxtrack vs GPy on {len(subsets)} training subsets of {small} poses (held-out error; "
          "train s = training only, total s = training + μ⁻¹ of the held-out poses)")
    subset_columns = [("subset", "subset", "s"), ("load_1min", "load", ".2f"),
                      ("jaxtrack_train_s", "jaxtrack train s", ".2f"),
                      ("jaxtrack_total_s", "total s", ".2f"),
                      ("jaxtrack_error_px", "err px", ".2f"),
                      ("gpy_train_s", "GPy train s", ".2f"), ("gpy_total_s", "total s", ".2f"),
                      ("gpy_error_px", "err px", ".2f"),
                      ("gpy_same_inverse_error_px", "same μ⁻¹ px", ".2f"),
                      ("train_time_gpy_over_jaxtrack", "train ×", ".2f"),
                      ("time_gpy_over_jaxtrack", "total ×", ".2f"),
                      ("error_gpy_over_jaxtrack", "GPy/jaxtrack err", ".3f"),
                      ("error_gpy_same_inverse_over_jaxtrack", "same μ⁻¹", ".3f")]
    print_table([*({**record, "subset": str(record["subset"])} for record in subsets),
                 {**medians, "subset": "median"}], subset_columns)
    for key, value in medians.items():
        if key.startswith("ratio_of_medians"):
            print(f"{key}: {value:.3g}")
    load_end = os.getloadavg()
    print(f"load average at end (1, 5, 15 min): {load_end[0]:.2f} {load_end[1]:.2f} "
          f"{load_end[2]:.2f}; benchmark wall {time.perf_counter() - started:.0f} s")
    write_json(args.json, {
        "benchmark": "gplvm", "device": device_description(), "arguments": vars(args),
        "load_average_start": load_start, "load_average_end": load_end,
        "training_clips": training_clips, "held_out_clips": held_out_clips,
        "pool_poses": len(pool.states), "held_out_poses": len(held_out.states),
        "states_to_markers_floor_px": floor_px,
        "rows": rows, "speed_rows": speed_rows, "ratios": ratios,
        "subsets": subsets, "subset_medians": medians, "fits": traces, "gpy": gpy,
        "latent_space_plot": str(plot),
        "wall_s": time.perf_counter() - started,
        "median_torso_px": float(statistics.median(held_out.torso_lengths())),
    })
    print(f"wrote {args.json} and {Path(plot)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
