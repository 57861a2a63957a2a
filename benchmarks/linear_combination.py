"""Speed of Ong & Gong's linear-combination tracker: frames and particle-fitness evaluations per
second at the paper's largest setting (300 samples × 5 CONDENSATION iterations per frame).

A model is trained on two real wave takes rendered through two Pose2Sim cameras (or loaded with
``--model``); a held-out take (another subject) is rendered and observed, and the tracker's
compiled scan is timed over its frames: propagation (eq. 4-6) and fitness (eq. 8-9) together,
compile time apart. The target is ≥ 30 frames per second on the project's 2-core CPU.

    python -m benchmarks.linear_combination [--particles 300] [--iterations 5] [--frames 60]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import jax.random as jr

from benchmarks._common import device_description, print_table, write_json

RESULTS = Path(__file__).parent / "results"
HISTORY = "animateddrawings/history_c119d6b/"
TRAIN = ("animateddrawings/fair1_wave_hello", HISTORY + "8yr_old_wave_hello")  # training subjects
HELD_OUT = HISTORY + "cmu_1006_wave_hello_1"  # a test subject (jaxtrack.data.splits)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, nargs="+", default=[100, 300])
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--clusters", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs (the fastest is "
                        "reported: other jobs on a shared machine only slow a run down)")
    parser.add_argument("--model", help="a model saved by jaxtrack.experiments."
                                        "linear_combination.train (default: train one)")
    parser.add_argument("--out", default=str(RESULTS / "linear_combination.json"))
    arguments = parser.parse_args()

    import jax
    import jax.numpy as jnp

    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.likelihoods.contour_normals import ContourObservation
    from jaxtrack.trackers import Engine
    from jaxtrack.trackers.linear_combination import _scan, linear_combination_tracker

    tick = time.perf_counter()
    if arguments.model:
        trained = lc.load(arguments.model)
    else:
        trained = lc.train(list(TRAIN), views=(0, 2), num_clusters=arguments.clusters)
    train_seconds = time.perf_counter() - tick
    sequence = lc.render_hybrid_sequences(HELD_OUT, views=(0,), max_frames=arguments.frames + 1,
                                          num_contour=trained.model.layout.num_contour,
                                          keep_observations=True)[0]
    observations = jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float32)
                                if leaf.dtype != bool else jnp.asarray(leaf),
                                sequence.observations)
    observations = ContourObservation(*(observations.gradient, observations.head,
                                        observations.hands, observations.found))
    frames = len(sequence.skeleton) - 1
    rest = jax.tree.map(lambda leaf: leaf[1:], observations)
    keys = jr.split(jr.PRNGKey(1), frames)
    rows = []
    for particles in arguments.particles:
        tracker = linear_combination_tracker(trained.model, engine=Engine(particles),
                                             iterations=arguments.iterations)
        state = tracker.start(jr.PRNGKey(0), jax.tree.map(lambda leaf: leaf[0], observations))
        tick = time.perf_counter()
        compiled = _scan.lower(tracker, state, keys, rest).compile()
        compile_seconds = time.perf_counter() - tick
        walls, cpus = [], []
        for _ in range(arguments.repeats):
            tick, cpu = time.perf_counter(), time.process_time()
            jax.block_until_ready(compiled(tracker, state, keys, rest))
            walls.append(time.perf_counter() - tick)
            cpus.append(time.process_time() - cpu)
        wall, cpu = min(walls), min(cpus)
        fps = frames / wall
        rows.append({"particles": particles, "iterations": arguments.iterations,
                     "frames": frames, "compile_s": compile_seconds,
                     "ms_per_frame": 1e3 * wall / frames, "cpu_ms_per_frame": 1e3 * cpu / frames,
                     "fps": fps, "fitness_per_s": fps * particles * arguments.iterations,
                     "target_met": fps >= 30.0})
    load = os.getloadavg()[0]
    print(f"device: {device_description()}; load average {load:.1f} while timing")
    print(f"model: {trained.model.num_components} components, {trained.model.num_clusters} "
          f"clusters, N_C = {trained.model.layout.num_contour} ({train_seconds:.0f} s to "
          f"train/load)")
    print_table(rows, [("particles", "N", "d"), ("iterations", "iter", "d"),
                       ("frames", "frames", "d"), ("compile_s", "compile s", ".1f"),
                       ("ms_per_frame", "ms/frame", ".2f"),
                       ("cpu_ms_per_frame", "CPU ms/frame", ".2f"), ("fps", "frames/s", ".1f"),
                       ("fitness_per_s", "fitness/s", ".3g"), ("target_met", "≥30 fps", "")])
    write_json(arguments.out, {"device": device_description(), "load_average": load,
                               "rows": rows,
                               "components": trained.model.num_components,
                               "clusters": trained.model.num_clusters})


if __name__ == "__main__":
    main()
