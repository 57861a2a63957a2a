"""Every tracker's output on the demo's held-out take, saved, and compared with an earlier save.

A refactor of the tracker layer should not move a marker. This script tracks the first
``--frames`` frames of the demo's held-out take (seed 0, the demo's prior) with each tracker as
``jaxtrack evaluate`` builds it, and writes their markers, best markers, ESS and
log-likelihoods to ``--out`` (``.npz``); with ``--compare REF.npz`` (a save made by an earlier
version, on the same machine: XLA compiles for the CPU it runs on) it prints, per array,
whether it is identical bit for bit or its largest difference, and exits 1 if any differ.

    python -m papers.tian2005.tracker_markers --out before.npz        # on the old version
    python -m papers.tian2005.tracker_markers --out after.npz --compare before.npz
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import jax.random as jr
import numpy as np

from papers.tian2005 import RUNS as FOLDER

RESULTS = FOLDER

# (name, method, particles, build_tracker options)
RUNS = (
    ("latent", "latent", 200, {}),
    ("latent_no_refinement", "latent", 200, {"refinement": None}),
    ("condensation", "condensation", 1000, {}),
    ("mht", "mht", 10, {}),
    ("latent_markers", "latent", 200, {"likelihood": "markers"}),
    ("condensation_refined", "condensation", 1000, {"refinement": "latent's"}),
)


def record(frames: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``{run/field: array}`` for every run of :data:`RUNS`."""
    from jaxtrack.experiments import build_tracker, render_test_sequences
    from jaxtrack.experiments.demo import HELD_OUT_CLIP, TRAIN_CLIPS
    from jaxtrack.priors.train import train_prior
    from jaxtrack.trackers import Likelihood, Refinement, track

    prior = train_prior(TRAIN_CLIPS, cache=RESULTS / "gplvm_waves.npz", seed=seed,
                        progress=False)
    sequence = render_test_sequences(HELD_OUT_CLIP, views=1, backgrounds=("photo",),
                                     seed=seed)[0]
    sequence = dataclasses.replace(sequence, frames=sequence.frames[:frames],
                                   truth=sequence.truth[:frames], images=sequence.images[:frames])
    arrays = {}
    for name, method, particles, options in RUNS:
        options = dict(options)
        if "likelihood" in options:
            options["likelihood"] = Likelihood(options["likelihood"])
        if options.get("refinement") == "latent's":
            options["refinement"] = Refinement()
        tracker = build_tracker(method, prior, sequence, particles, **options)
        result = track(tracker, jr.PRNGKey(seed), sequence.frames, sequence.truth[0],
                       progress=False)
        for field in ("markers", "best_markers", "ess", "log_likelihood"):
            arrays[f"{name}/{field}"] = getattr(result, field)
        error = np.mean(np.linalg.norm(result.markers - sequence.truth, axis=-1))
        print(f"{name:22s} mean error {error:7.3f} px, {1e3 * result.seconds_per_frame:6.2f} "
              f"ms/frame", flush=True)
    return arrays


def compare(arrays: dict[str, np.ndarray], reference: dict[str, np.ndarray]) -> bool:
    """Print each array's agreement with ``reference``; True when all are identical."""
    same = True
    for name in sorted(set(arrays) | set(reference)):
        if name not in arrays or name not in reference:
            print(f"{name:36s} only in {'the reference' if name in reference else 'this run'}")
            continue
        if np.array_equal(arrays[name], reference[name]):
            print(f"{name:36s} identical")
        else:
            same = False
            print(f"{name:36s} max |difference| "
                  f"{np.max(np.abs(arrays[name] - reference[name])):.3g}")
    return same


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--out", type=Path, required=True, metavar="OUT.npz")
    parser.add_argument("--compare", type=Path, default=None, metavar="REF.npz")
    args = parser.parse_args()
    arrays = record(args.frames)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(args.out, **arrays)
    print(f"wrote {args.out}")
    if args.compare is None:
        return 0
    with np.load(args.compare) as reference:
        return 0 if compare(arrays, dict(reference)) else 1


if __name__ == "__main__":
    sys.exit(main())
