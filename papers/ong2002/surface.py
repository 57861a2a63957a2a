"""Ong & Gong's error surfaces (their Fig. 10 and 12): mean 3-D skeleton error of the
linear-combination tracker over cluster counts × samples per iteration, on a training clip and
on the held-out test subject.

For each cluster count a model is trained on the training subjects (``jaxtrack.experiments.
linear_combination.TRAIN_CLIPS``, through the Pose2Sim cameras of ``--views``); the tracker then
runs at each sample count (5 iterations per frame) on the first training clip (the paper's
"training sequences") and on the test subject's two waves, every view. Eq. 9's tolerances P, Q
and the step ω are the ones ``python -m papers.ong2002.evaluation`` chose on the
validation subject (2026-11-26: P = 64, Q = 16, ω = 0.03); ``--P``, ``--Q`` and ``--step`` give
others. The paper's grid is clusters {10, 20, …, 100} × samples {10, 20, …, 90, 100, 150, …,
300}; ``--clusters`` and ``--samples`` take a coarser one.

    python -m papers.ong2002.surface [--frames 60] [--clusters 10 40 100] ...

Prints the grid, writes ``papers/ong2002/results/linear_combination_surface.json`` (after every
grid point, ``"complete": false`` until the last) and the plot ``linear_combination_surface.png``
beside it.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from benchmarks._common import device_description, print_table, write_json

RESULTS = Path(__file__).parent / "results"
PAPER_CLUSTERS = tuple(range(10, 101, 10))
PAPER_SAMPLES = (*range(10, 101, 10), *range(150, 301, 50))


def surface(clusters, samples, *, views, frames: int, fitness, step, iterations: int = 5,
            progress: bool = True, on_row=None, done: list[dict] = ()) -> list[dict]:
    """One row ``{clusters, samples, training_m, test_m, train_seconds}`` per grid point;
    ``on_row(rows)`` is called after each (a long grid's partial results survive a stop), and
    the grid points of ``done`` (earlier rows) are kept, not run again.

    Every grid point compiles new programs (the sample count and the model's shapes are
    static), so the compiled ones are released after each: a process may hold only
    ``vm.max_map_count`` memory mappings, and the whole grid's programs exceed it (the
    compiler then fails with "Cannot allocate memory"; docs/testing.md).
    """
    import jax
    import jax.numpy as jnp
    import numpy as np
    from tqdm import tqdm

    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.trackers.linear_combination import release_compiled

    def score(model, sequences, particles):
        errors = [lc.skeleton_error(lc.run_method(
            "linear-combination", model, sequence.observations, fitness=fitness,
            step=jnp.asarray(step), particles=particles, iterations=iterations)["skeleton"],
            sequence.skeleton).mean() for sequence in sequences]
        return float(np.mean(errors))

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
                rows.append({"clusters": int(count), "samples": int(particles),
                             "training_m": score(model, training, particles),
                             "test_m": score(model, test, particles),
                             "train_seconds": train_seconds})
                release_compiled()
                jax.clear_caches()
                bar.update()
                if on_row is not None:
                    on_row(rows)
    return rows


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
