"""Ong & Gong's error surfaces (their Fig. 10 and 12): mean 3-D skeleton error of the
linear-combination tracker over cluster counts × samples per iteration, on a training clip and
on the held-out test subject.

For each cluster count a model is trained on the training subjects (``jaxtrack.experiments.
linear_combination.TRAIN_CLIPS``, through the Pose2Sim cameras of ``--views``); the tracker then
runs at each sample count (5 iterations per frame) on the first training clip (the paper's
"training sequences") and on the test subject's two waves, every view. Eq. 9's tolerances P, Q
and the step ω are the ones ``python -m papers.ong2002.evaluation`` chose on the
validation subject (2026-11-26: P = 64, Q = 16, ω = 0.03, the library's defaults since
2026-11-29); ``--P``, ``--Q`` and ``--step`` give others. The paper's grid is clusters
{10, 20, …, 100} × samples {10, 20, …, 90, 100, 150, …, 300}; ``--clusters`` and ``--samples``
take a coarser one.

    python -m papers.ong2002.surface [--frames 60] [--clusters 10 40 100] ...

Prints the grid, writes ``papers/ong2002/results/linear_combination_surface.json`` (after every
grid point, ``"complete": false`` until the last) and the plot ``linear_combination_surface.png``
beside it.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, print_table, write_json

RESULTS = Path(__file__).parent / "results"
PAPER_CLUSTERS = tuple(range(10, 101, 10))
PAPER_SAMPLES = (*range(10, 101, 10), *range(150, 301, 50))


def surface(clusters, samples, *, views, frames: int, fitness, step, iterations: int = 5,
            progress: bool = True, on_row=None, done: list[dict] = ()) -> list[dict]:
    """One row ``{clusters, samples, training_m, test_m, training_mean_m, test_mean_m,
    train_seconds}`` per grid point (``*_m``: the best particle's skeleton, the paper's estimate;
    ``*_mean_m``: the particles' weighted mean, the library's);
    ``on_row(rows)`` is called after each (a long grid's partial results survive a stop), and
    the grid points of ``done`` (earlier rows) are kept, not run again.

    Every grid point compiles new programs (the sample count and the model's shapes are
    static), so the compiled ones are released after each: a process may hold only
    ``vm.max_map_count`` memory mappings, and the whole grid's programs exceed it (the
    compiler then fails with "Cannot allocate memory"; docs/testing.md).
    """
    import jax
    import jax.numpy as jnp
    from tqdm import tqdm

    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.trackers.linear_combination import release_compiled

    def score(model, sequences, particles):
        """Mean error of the best particle's skeleton (the paper's) and of the weighted mean."""
        errors = []
        for sequence in sequences:
            run = lc.run_method("linear-combination", model, sequence.observations,
                                fitness=fitness, step=jnp.asarray(step), particles=particles,
                                iterations=iterations)
            errors.append([lc.skeleton_error(run[key], sequence.skeleton).mean()
                           for key in ("skeleton", "mean_skeleton")])
        best, mean = np.mean(errors, axis=0)
        return float(best), float(mean)

    render = dict(views=tuple(views), max_frames=frames, keep_observations=True, seed=7)
    training = lc.render_hybrid_sequences(lc.TRAIN_CLIPS[0], **render)
    test = [s for clip in lc.TEST_CLIPS for s in lc.render_hybrid_sequences(clip, **render)]
    finished = {(int(row["clusters"]), int(row["samples"])): row for row in done}
    rows = []
    with tqdm(total=len(clusters) * len(samples), disable=not progress,
              desc="error surface") as bar:
        for count in clusters:
            model = None
            for particles in samples:
                if (int(count), int(particles)) in finished:
                    rows.append(finished[(int(count), int(particles))])
                    bar.update()
                    continue
                if model is None:
                    tick = time.perf_counter()
                    model = lc.train(list(lc.TRAIN_CLIPS), views=tuple(views),
                                     num_clusters=count)
                    train_seconds = time.perf_counter() - tick
                training_m, training_mean_m = score(model, training, particles)
                test_m, test_mean_m = score(model, test, particles)
                rows.append({"clusters": int(count), "samples": int(particles),
                             "training_m": training_m, "test_m": test_m,
                             "training_mean_m": training_mean_m, "test_mean_m": test_mean_m,
                             "train_seconds": train_seconds})
                release_compiled()
                jax.clear_caches()
                bar.update()
                if on_row is not None:
                    on_row(rows)
    return rows


SMALL_CLUSTERS = (10, 20, 40, 70, 100)
SMALL_SAMPLES = (10, 20, 50, 100, 300)
"""A 5 × 5 corner-to-corner subset of the paper's grid, for a run of about half an hour on two
shared CPU cores (``python -m papers.ong2002``'s default; ``--full`` runs the paper's)."""


def grid(rows: list[dict], key: str) -> tuple[list[int], list[int], np.ndarray]:
    """The rows' ``key`` as a ``(clusters, samples)`` array in millimetres (NaN where no row).

    Returns:
        ``(cluster counts, sample counts, errors)``, the counts sorted.
    """
    clusters = sorted({int(row["clusters"]) for row in rows})
    samples = sorted({int(row["samples"]) for row in rows})
    errors = np.full((len(clusters), len(samples)), np.nan)
    for row in rows:
        errors[clusters.index(int(row["clusters"])), samples.index(int(row["samples"]))] = (
            1e3 * float(row[key]))
    return clusters, samples, errors


def trends(rows: list[dict], key: str) -> dict:
    """What the paper's Fig. 10 and 12 read off a surface, with the noise to judge it by.

    The error is fitted by an additive model, error ≈ m + a(clusters) + b(samples); the
    residuals' standard deviation ``noise_mm`` is what one grid point (one seed) scatters by,
    so a mean over a row of S points is uncertain by about noise_mm / √S, and the difference of
    two such means by √2 times that. A trend is said to hold only where the difference exceeds
    two of its standard errors (``difference_margin_*_mm``).

    Returns:
        ``by_clusters_mm`` (the mean over sample counts per cluster count),
        ``by_samples_mm`` (the mean over cluster counts per sample count), ``noise_mm``,
        ``falls_with_samples`` (the fewest samples' mean exceeds the most samples' by the margin),
        ``falls_with_clusters`` (the fewest clusters' mean exceeds the lowest cluster mean
        by the margin), ``overfits_with_clusters`` (the most clusters' mean exceeds the lowest
        by the margin), ``best_clusters`` and ``best_point``.
    """
    clusters, samples, errors = grid(rows, key)
    if np.isnan(errors).any():
        raise ValueError(f"the grid of {key!r} has holes; give every clusters × samples point")
    by_clusters = errors.mean(axis=1)
    by_samples = errors.mean(axis=0)
    fitted = by_clusters[:, None] + by_samples[None, :] - errors.mean()
    dof = max((len(clusters) - 1) * (len(samples) - 1), 1)
    noise = float(np.sqrt(((errors - fitted) ** 2).sum() / dof))
    se_clusters = noise / np.sqrt(len(samples))  # one cluster count's mean over samples
    se_samples = noise / np.sqrt(len(clusters))
    margin_clusters, margin_samples = 2 * np.sqrt(2) * se_clusters, 2 * np.sqrt(2) * se_samples
    lowest = int(np.argmin(by_clusters))
    best = np.unravel_index(int(np.argmin(errors)), errors.shape)
    return {"clusters": clusters, "samples": samples,
            "by_clusters_mm": [round(float(v), 1) for v in by_clusters],
            "by_samples_mm": [round(float(v), 1) for v in by_samples],
            "noise_mm": round(noise, 1),
            "difference_margin_clusters_mm": round(float(margin_clusters), 1),
            "difference_margin_samples_mm": round(float(margin_samples), 1),
            "falls_with_samples": bool(by_samples[0] - by_samples[-1] > margin_samples),
            "falls_with_clusters": bool(by_clusters[0] - by_clusters[lowest] > margin_clusters),
            "overfits_with_clusters": bool(by_clusters[-1] - by_clusters[lowest]
                                           > margin_clusters),
            "best_clusters": clusters[lowest],
            "best_point": {"clusters": clusters[best[0]], "samples": samples[best[1]],
                           "error_mm": round(float(errors[best]), 1)}}


def heat_map(rows: list[dict], key: str, path: str | Path, *, title: str,
             reference: tuple[str, float] | None = None) -> Path:
    """A clusters × samples heat map of ``key`` (mm), each cell labelled with its value.

    Args:
        rows: the surface's rows.
        key: the error to draw (``training_m``, ``test_m``, ...).
        path: the PNG to write (its folder must exist).
        title: the figure's title.
        reference: ``(name, mm)``, a level to name in the colour bar's label (e.g. a
            constant skeleton's error), or None.

    Returns:
        The path.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    clusters, samples, errors = grid(rows, key)
    figure, axis = plt.subplots(figsize=(1.0 + 0.75 * len(samples), 1.2 + 0.5 * len(clusters)))
    image = axis.imshow(errors, origin="lower", cmap="viridis", aspect="auto")
    axis.set_xticks(range(len(samples)), [str(v) for v in samples])
    axis.set_yticks(range(len(clusters)), [str(v) for v in clusters])
    axis.set_xlabel("samples per iteration")
    axis.set_ylabel("clusters")
    middle = np.nanmean(errors)
    for i in range(len(clusters)):
        for j in range(len(samples)):
            axis.text(j, i, f"{errors[i, j]:.0f}", ha="center", va="center", fontsize=8,
                      color="white" if errors[i, j] < middle else "black")
    label = "mean 3-D skeleton error (mm)"
    if reference is not None:
        label += f"\n({reference[0]}: {reference[1]:.0f} mm)"
    figure.colorbar(image, ax=axis, label=label)
    axis.set_title(title, fontsize=10)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clusters", type=int, nargs="+", default=list(PAPER_CLUSTERS))
    parser.add_argument("--samples", type=int, nargs="+", default=list(PAPER_SAMPLES))
    parser.add_argument("--frames", type=int, default=60, help="frames per clip (30 fps)")
    parser.add_argument("--views", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--P", type=float, default=64.0, help="eq. 9's contour tolerance")
    parser.add_argument("--Q", type=float, default=16.0, help="eq. 9's hand tolerance")
    parser.add_argument("--step", type=float, default=0.03, help="the propagation step ω")
    parser.add_argument("--out", type=Path, default=RESULTS / "linear_combination_surface.json")
    parser.add_argument("--resume", action="store_true",
                        help="keep the grid points --out already holds from a run with the same "
                             "settings and run the rest")
    args = parser.parse_args(argv)
    if min(args.clusters) < 2 or min(args.samples) < 1 or args.frames < 2:
        raise SystemExit("--clusters must be at least 2, --samples at least 1, --frames at "
                         "least 2")
    import jax.numpy as jnp

    from jaxtrack.evaluation import plot_error_surface
    from jaxtrack.likelihoods.contour_normals import FitnessSettings

    fitness = FitnessSettings(contour_tolerance=jnp.asarray(args.P),
                              hands_tolerance=jnp.asarray(args.Q))
    begin = time.perf_counter()

    def record(rows, complete=False):
        write_json(args.out, {"benchmark": "linear_combination_surface",
                              "device": device_description(),
                              "arguments": {key: str(value) if isinstance(value, Path) else value
                                            for key, value in vars(args).items()},
                              "complete": complete, "seconds": time.perf_counter() - begin,
                              "rows": rows})

    done = []
    if args.resume and args.out.is_file():
        import json

        earlier = json.loads(args.out.read_text())
        settings = {key: value for key, value in earlier.get("arguments", {}).items()
                    if key not in ("clusters", "samples", "resume")}
        current = {key: str(value) if isinstance(value, Path) else value
                   for key, value in vars(args).items()
                   if key not in ("clusters", "samples", "resume")}
        if settings != current:
            raise SystemExit(f"--resume: {args.out} was written with other settings "
                             f"({settings}); run without --resume or write --out elsewhere")
        done = earlier["rows"]
        print(f"--resume: {len(done)} grid points from {args.out}")
    rows = surface(args.clusters, args.samples, views=args.views, frames=args.frames,
                   fitness=fitness, step=args.step, iterations=args.iterations, on_row=record,
                   done=done)
    seconds = time.perf_counter() - begin
    print(f"device: {device_description()}; {len(rows)} grid points in {seconds:.0f} s; "
          f"P={args.P:g} Q={args.Q:g} ω={args.step:g}, {args.iterations} iterations, "
          f"{args.frames} frames per clip, views {args.views}")
    print_table([{**row, "training_mm": 1e3 * row["training_m"], "test_mm": 1e3 * row["test_m"]}
                 for row in rows],
                [("clusters", "clusters", "d"), ("samples", "samples", "d"),
                 ("training_mm", "training clip (mm)", ".0f"),
                 ("test_mm", "held-out subject (mm)", ".0f")])
    figure = plot_error_surface(rows, args.out.with_suffix(".png"),
                                title="Mean 3-D skeleton error (Ong & Gong, Fig. 10 and 12)")
    record(rows, complete=True)
    print(f"wrote {args.out} and {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
