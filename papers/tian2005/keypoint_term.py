"""The keypoint term's scales fitted on the validation subjects, and the trackers with it there.

    python -m papers.tian2005.keypoint_term  # 3 validation clips × 2 views × 2 backgrounds
    python -m papers.tian2005.keypoint_term --quick      # one sequence, 12 frames (a smoke run)

The likelihood's keypoint term (``jaxtrack.likelihoods.edges``: ``Likelihood(keypoint_weight=
η)``) scores a per-frame detector's keypoints as the detector's error model, a bivariate Cauchy
about each keypoint with a scale τ_j per marker in fractions of the spine. This script

1. renders the scripted comparison's validation gesture clips (``papers.tian2005.tracking``
   ``GESTURE_CLIPS["validation"]``: Bandai's actors, validation subjects) from a frontal and a
   random view over a real photo and over clutter, ``--frames`` frames each at 30 fps;
2. runs MediaPipe Pose on them (``jaxtrack/vision/mediapipe.py``, its own venv) and **fits τ_j**:
   for each marker the median distance from MediaPipe's keypoint to the true marker, in spines
   (neck–pelvis) of the true pose, under the better left/right assignment of each frame (the
   term's own), over √3, a bivariate Cauchy's median radius in its scale; it prints them beside
   ``jaxtrack.likelihoods.edges.KEYPOINT_SCALES``, the library's (they should agree: those were
   fitted by this script);
3. tracks every sequence with the latent tracker, CONDENSATION and MHT (the scripted
   comparison's particle counts and training poses) × {own estimate, + refinement} × {without
   the term, with it at η = 3/2, the Cauchy density's own, or the weights
   ``--keypoint-weights`` gives, and the library's τ_j}, from frame 0's truth, and scores them
   (mean error in % of the torso, frames within 15 %, runs lost), with MediaPipe alone beside
   them.

No setting is chosen from step 3: it says what the term does where the image likelihood
already holds the person (on rendered frames it does), so that a user knows what it costs
there, and at which weight. Writes ``papers/tian2005/results/runs/keypoint_term.json`` and prints
markdown tables.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
from pathlib import Path

import jax.random as jr
import numpy as np

from benchmarks._common import device_description, run_header
from jaxtrack._files import write_json_atomically
from papers.tian2005 import RUNS, candidate_prior

RESULTS = RUNS
METHODS = ("latent", "condensation", "mht")
ESTIMATES = ("own", "refined")
MEDIAN_RADIUS = np.sqrt(3.0)
"""A bivariate Cauchy's median distance from its centre, in its scale."""


def better_assignment_distances(points: np.ndarray, confidence: np.ndarray,
                                truth: np.ndarray) -> np.ndarray:
    """``(frames, 12)`` distances from each keypoint to its true marker in spines of the true
    pose, under the better of the two left/right assignments per frame (NaN where the keypoint
    was not found)."""
    from jaxtrack.likelihoods._base import SPINE_MARKERS
    from jaxtrack.likelihoods.edges import MIRRORED_MARKERS

    spine = np.linalg.norm(truth[:, SPINE_MARKERS[0]] - truth[:, SPINE_MARKERS[1]], axis=-1)
    found = confidence > 0
    given = np.where(found, np.linalg.norm(points - truth, axis=-1), np.nan)
    mirror = list(MIRRORED_MARKERS)
    mirrored = np.where(found[:, mirror], np.linalg.norm(points[:, mirror] - truth, axis=-1),
                        np.nan)
    swap = np.nansum(mirrored, axis=1) < np.nansum(given, axis=1)
    return np.where(swap[:, None], mirrored, given) / spine[:, None]


def fit_scales(distances: np.ndarray) -> np.ndarray:
    """τ_j: the median of each marker's distances (in spines) over √3."""
    return np.nanmedian(distances, axis=0) / MEDIAN_RADIUS


def make_tracker(method: str, estimate: str, prior, sequence, weight: float):
    """One configuration (the protocol's ``build_tracker``); ``weight`` the keypoint term's η
    (0: off)."""
    from jaxtrack import trackers
    from jaxtrack.experiments import DEFAULT_PARTICLES, build_tracker

    likelihood = (trackers.Likelihood(keypoint_weight=weight) if weight
                  else trackers.Likelihood())
    return build_tracker(method, prior, sequence, DEFAULT_PARTICLES[method], likelihood,
                         trackers.Refinement() if estimate == "refined" else None)


def score(markers: np.ndarray, truth: np.ndarray) -> dict:
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.evaluation import evaluate_track

    metrics = evaluate_track(markers[1:], truth[1:], UPPER_BODY_12)
    return {key: metrics[key] for key in ("mean_error_torso", "fraction_within_15", "failed")}


def table(runs: list[dict]) -> str:
    lines = ["| method | estimate | keypoint term | runs | error/torso | within 15 % | lost | "
             "ms/frame | compile s |", "|---|---|---|---|---|---|---|---|---|"]
    key = lambda run: (run["method"], run["estimate"], run["keypoints"])  # noqa: E731
    order = {name: index for index, name in enumerate((*METHODS, "mediapipe"))}
    for (method, estimate, keypoints), group in itertools.groupby(
            sorted(runs, key=lambda run: (order[run["method"]], run["estimate"],
                                          run.get("keypoint_weight", 0.0))), key=key):
        group = list(group)
        ms = [run["ms_per_frame"] for run in group if run.get("ms_per_frame") is not None]
        compile_s = [run["compile_seconds"] for run in group if run.get("compile_seconds")]
        lines.append("| " + " | ".join([
            method, estimate, keypoints, str(len(group)),
            f"{100 * statistics.mean(r['mean_error_torso'] for r in group):.1f} %",
            f"{100 * statistics.mean(r['fraction_within_15'] for r in group):.0f} %",
            f"{sum(bool(r['failed']) for r in group)}/{len(group)}",
            f"{statistics.median(ms):.1f}" if ms else "—",
            f"{max(compile_s):.1f}" if compile_s else "—"]) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.keypoint_term",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=60, help="frames per sequence (60)")
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--estimates", nargs="+", choices=ESTIMATES, default=list(ESTIMATES))
    parser.add_argument("--keypoint-weights", type=float, nargs="+", default=None,
                        metavar="ETA", help="the term's weights η to track with (default 1.5, "
                        "the Cauchy density's own)")
    parser.add_argument("--no-tracking", action="store_true",
                        help="fit the scales only (steps 1-2)")
    parser.add_argument("--quick", action="store_true",
                        help="one clip, the frontal photo view, 12 frames, the latent tracker "
                             "with refinement, a small prior (a smoke run)")
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default "
                        "papers/tian2005/results/runs/keypoint_term.json; "
                             "--quick: keypoint_term_quick.json)")
    args = parser.parse_args(argv)
    if args.frames < 2:
        parser.error(f"--frames must be at least 2, got {args.frames}")
    from jaxtrack.likelihoods.edges import CAUCHY_KEYPOINT_WEIGHT

    weights = args.keypoint_weights or [CAUCHY_KEYPOINT_WEIGHT]
    if not all(np.isfinite(weight) and weight > 0 for weight in weights):
        parser.error(f"--keypoint-weights must be positive numbers, got {weights}")
    started = time.perf_counter()

    from jaxtrack.body import SPM_MARKERS
    from jaxtrack.data.clip_sets import GESTURE_CLIPS, QUICK_TRAINING, TRAINING_CLIPS
    from jaxtrack.experiments import render_test_sequences
    from jaxtrack.likelihoods.edges import KEYPOINT_SCALES
    from jaxtrack.vision.mediapipe import detected_keypoints, run_mediapipe

    clips, views, backgrounds, frames = GESTURE_CLIPS["validation"], 2, ("photo", "clutter"), \
        args.frames
    methods, estimates = tuple(args.methods), tuple(args.estimates)
    if args.quick:
        clips, views, backgrounds, frames = clips[:1], 1, ("photo",), 12
        methods, estimates = ("latent",), ("refined",)
    out = args.out or RESULTS / ("keypoint_term_quick.json" if args.quick
                                 else "keypoint_term.json")
    sequences, detections, distances = [], [], []
    for index, clip in enumerate(clips):
        for sequence in render_test_sequences(clip, views=views, seed=index, max_frames=frames,
                                              backgrounds=backgrounds):
            found = run_mediapipe(sequence.images)
            if "skipped" in found:
                raise SystemExit(f"MediaPipe, {sequence.name}: {found['skipped']}")
            points, confidence = detected_keypoints(found)
            sequences.append(sequence)
            detections.append((points, confidence, found["markers"]))
            distances.append(better_assignment_distances(points, confidence, sequence.truth))
            print(f"{sequence.name}: MediaPipe found the person in {int(found['found'].sum())} "
                  f"of {len(sequence.truth)} frames")
    fitted = fit_scales(np.concatenate(distances))
    lines = ["| marker | fitted τ (spines) | KEYPOINT_SCALES |", "|---|---|---|"]
    lines += [f"| {name} | {value:.3f} | {library:.3f} |"
              for name, value, library in zip(SPM_MARKERS, fitted, KEYPOINT_SCALES, strict=True)]
    scales_table = "\n".join(lines)
    print(scales_table)

    runs = []
    for sequence, (_, _, filled) in zip(sequences, detections, strict=True):
        runs.append({"method": "mediapipe", "estimate": "own", "keypoints": "—",
                     "sequence": sequence.name, **score(filled, sequence.truth)})
    if not args.no_tracking:
        from jaxtrack.trackers import track
        from papers.tian2005.real_video import _share_compilations

        _share_compilations()  # every sequence is 640 × 480: one compilation per configuration

        prior = candidate_prior("waves", **(QUICK_TRAINING if args.quick else {}))
        print(f"prior: {', '.join(TRAINING_CLIPS)}; {device_description()}")
        for method, estimate, weight in itertools.product(methods, estimates, [0.0, *weights]):
            for sequence, (points, confidence, _) in zip(sequences, detections, strict=True):
                tracker = make_tracker(method, estimate, prior, sequence, weight)
                result = track(tracker, jr.PRNGKey(0), sequence.frames, sequence.truth[0],
                               progress=False,
                               keypoints=(points, confidence) if weight else None)
                run = {"method": method, "estimate": estimate,
                       "keypoints": f"η = {weight:g}" if weight else "off",
                       "keypoint_weight": weight,
                       "sequence": sequence.name,
                       "ms_per_frame": 1000 * result.seconds_per_frame,
                       "compile_seconds": result.compile_seconds,
                       **score(result.markers, sequence.truth)}
                runs.append(run)
                print(f"  {method:12s} {estimate:7s} {run['keypoints']:7s} {sequence.name}: "
                      f"{100 * run['mean_error_torso']:5.1f} % torso, "
                      f"{100 * run['fraction_within_15']:3.0f} % within 15 %")
    text = table(runs)
    print(text)
    header = run_header("papers.tian2005.keypoint_term", argv, started)
    write_json_atomically(out, {
        **header, "clips": list(clips), "views": views, "backgrounds": list(backgrounds),
        "frames": frames, "markers": list(SPM_MARKERS), "keypoint_weights": weights,
        "fitted_scales": [float(value) for value in fitted],
        "library_scales": list(KEYPOINT_SCALES), "scales_table": scales_table,
        "table": text, "runs": runs})
    print(f"wrote {out} in {header['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
