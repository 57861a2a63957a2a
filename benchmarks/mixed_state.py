"""Cost of Kwatra et al.'s mixed-state tracker: filtering and smoothing a long sequence.

The observations are real: CMU 75_20 (stand → sit → stand) rendered from the side at 320 × 240
over a photo, silhouettes by background subtraction, features, hypotheses and nearest-point maps
(:func:`jaxtrack.trackers.mixed_state.observations_from_silhouettes`), the clip repeated to
``--frames`` frames. The posture model is fitted to the clip's own frames with its posture
labels, the lying postures standing in from mirrored-aspect copies (the cost does not depend on
the model's values, only on its shapes). Each stage is jitted and compiled ahead (compile time
apart), then timed as the median of ``--repeats`` runs with ``block_until_ready``:

    filter          filter_sequence: one lax.scan over the frames, history kept
    smooth          ancestry tracing (smc.trace_ancestry) + MAP posture and expected parts
    filter+smooth   the two together: the target is < 2 s for 1 000 frames × 1 000 particles
    fixed lag       smooth_fixed_lag with ``--lag`` frames
    backward        smooth_backward, the two-pass smoother (backward simulation), with
                    ``--backward-paths`` paths: paths × particles densities per frame

    python -m benchmarks.mixed_state                      # 1 000 frames × 1 000 particles
    python -m benchmarks.mixed_state --frames 200 --particles 200 --repeats 1
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import jax
import jax.random as jr
import numpy as np

from benchmarks._common import device_description, time_compiled


def _observations(num_frames: int):
    from jaxtrack.experiments.mixed_state import render_posture_sequence
    from jaxtrack.priors.postures import fit_posture_model
    from jaxtrack.trackers.mixed_state import MixedStateFrame, observations_from_silhouettes

    sequence = render_posture_sequence("cmu_posture_bvh/75_20", np.pi / 2, image_size=(320, 240))
    observations = observations_from_silhouettes(sequence.masks)
    repeat = lambda leaf: np.resize(np.asarray(leaf), (num_frames, *leaf.shape[1:]))  # noqa: E731
    observations = MixedStateFrame(*(repeat(leaf) for leaf in (
        observations.features, observations.hypotheses, observations.nearest,
        observations.status)))
    features = np.asarray(observations.features[:len(sequence.labels)])
    labels = sequence.labels.copy()
    lying = features.copy()
    lying[:, -1] = -np.abs(lying[:, -1]) - 1.0  # wide boxes stand in for the lying postures
    model = fit_posture_model([features, lying, lying], [labels, np.full(len(labels), 3),
                                                         np.full(len(labels), 4)])
    return observations, model


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--particles", type=int, default=1000)
    parser.add_argument("--lag", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--backward-paths", type=int, default=100,
                        help="paths of the two-pass smoother (0: not timed)")
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    args = parser.parse_args(argv)
    if args.frames < 2 or args.particles < 1 or args.repeats < 1 or args.backward_paths < 0:
        parser.error("--frames must be at least 2, --particles and --repeats at least 1, "
                     "--backward-paths 0 or more")
    from jaxtrack.trackers.mixed_state import (
        MixedStateModel,
        filter_sequence,
        smooth,
        smooth_backward,
        smooth_fixed_lag,
    )

    observations, posture_model = _observations(args.frames)
    model = MixedStateModel(jax.tree.map(lambda leaf: leaf.astype(np.float32), posture_model))
    observations = jax.tree.map(jax.numpy.asarray, observations)
    key = jr.PRNGKey(0)
    num = args.particles
    filtered = lambda key, model, obs: filter_sequence(key, model, obs, num)  # noqa: E731
    both = lambda key, model, obs: smooth(filter_sequence(key, model, obs, num))  # noqa: E731
    rows = {}
    compile_s, run_s, cpu_s, result = time_compiled(filtered, key, model, observations,
                                                    repeats=args.repeats)
    rows["filter"] = (compile_s, run_s, cpu_s)
    compile_s, run_s, cpu_s, _ = time_compiled(smooth, result, repeats=args.repeats)
    rows["smooth"] = (compile_s, run_s, cpu_s)
    compile_s, run_s, cpu_s, _ = time_compiled(both, key, model, observations,
                                               repeats=args.repeats)
    rows["filter+smooth"] = (compile_s, run_s, cpu_s)
    lagged = lambda result: smooth_fixed_lag(result, args.lag)  # noqa: E731
    compile_s, run_s, cpu_s, _ = time_compiled(lagged, result, repeats=args.repeats)
    rows[f"fixed lag {args.lag}"] = (compile_s, run_s, cpu_s)
    if args.backward_paths:
        paths = args.backward_paths
        backward = lambda key, result, model, obs: smooth_backward(  # noqa: E731
            key, result, model, obs, paths)
        compile_s, run_s, cpu_s, _ = time_compiled(backward, key, result, model, observations,
                                                   repeats=args.repeats)
        rows[f"backward {paths}"] = (compile_s, run_s, cpu_s)
    device = device_description()
    print(f"mixed-state tracker, {args.frames} frames x {num} particles, float32, "
          f"image 320 x 240; {device}; load average {os.getloadavg()[0]:.1f}")
    print(f"{'stage':<16}{'compile s':>11}{'run s':>9}{'CPU s':>9}{'ms/frame':>10}")
    for name, (compile_s, run_s, cpu_s) in rows.items():
        print(f"{name:<16}{compile_s:>11.2f}{run_s:>9.3f}{cpu_s:>9.3f}"
              f"{1000 * run_s / args.frames:>10.3f}")
    total = rows["filter+smooth"][1]
    print(f"filter+smooth: {total:.3f} s against the 2 s target ({total / 2.0:.2f} x the target)")
    out = {"frames": args.frames, "particles": num, "lag": args.lag,
           "backward_paths": args.backward_paths, "device": device,
           "load_average": os.getloadavg()[0],
           "stages": {name: dict(zip(("compile_s", "run_s", "cpu_s"), values, strict=True))
                      for name, values in rows.items()}}
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
