"""Does the tracking likelihood prefer the true pose? Rendered validation clips against the real
Pose2Sim videos.

    python -m papers.tian2005.likelihood_at_truth  # 3 validation clips + 4 real views
    python -m papers.tian2005.likelihood_at_truth --frames 20 --views cam01

A tracker can only follow a person if its likelihood scores the true pose above the poses it
drifts to. This script measures that directly, with the latent tracker's default likelihood
(limb strips, their oriented edges and the arms' foreground against the sequence's median
background; templates cut at frame 0's true pose, as every tracker cuts them). On each
sequence it tracks with the default latent tracker (200 particles, the shared refinement)
from frame 0's truth, then scores, in every later frame, with the bilinear reads the
refinement uses:

- the true pose (the rendered markers, or the reference triangulated from four cameras, as an
  SPM pose of the prior's template: exact on the markers),
- the tracker's estimate,
- frame 0's true pose held still ("static").

and reports how often the truth scores higher than the estimate in the frames where the
estimate is more than 15 % of the torso off (the tracker is losing the person: does the
likelihood say so?), and than the static pose where that is more than 15 % off (the person
moved: does the likelihood see where to?). Near 100 % the likelihood knows the pose and the
search or the dynamics lose it; near 50 % or below it cannot tell, and no prior or search can
follow the person with it.

With ``--masks mediapipe`` the foreground term reads MediaPipe's person segmentation of each
frame (a fourth observation channel, ``jaxtrack.vision.edge_observations(masks=...)``; its
venv as ``jaxtrack/vision/mediapipe.py`` says) instead of the median background, which on the real
videos holds the man; ``--foreground-weight`` sets its μ (default the likelihood's), and
``--coverage-weight`` turns on the coverage term, which charges the masks for what the body
leaves unexplained, at weight ν.

The rendered sequences are the scripted comparison's validation clips
(``jaxtrack.data.clip_sets.GESTURE_CLIPS["validation"]``, frontal view, real-photo background,
30 fps); the real ones the four Pose2Sim views tracked as ``papers.tian2005.real_video`` does
(every second frame). The prior is
the scripted comparison's default (the training subjects' waves). Writes
``papers/tian2005/results/runs/likelihood_at_truth.json`` and prints a markdown table.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, run_header
from jaxtrack._files import write_json_atomically
from jaxtrack.vision.mediapipe import (
    add_mask_options,
    check_mask_options,
    likelihood_options,
    masks_or_exit,
)
from papers.tian2005 import RUNS, candidate_prior

RESULTS = RUNS
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
LOST = 0.15
"""An estimate (or the static pose) this far off, as a fraction of the torso, counts as off."""


def truth_preference(tracker, first_frame: np.ndarray, observations: np.ndarray,
                     truth: np.ndarray, estimate: np.ndarray) -> dict:
    """Per frame after the first: the log-likelihoods of the true pose, the estimate and frame
    0's pose held still, each as an SPM pose of the tracker's template, under the likelihood
    the tracker's filter uses (its templates cut from ``first_frame`` at ``truth[0]``), and
    the errors of the estimate and of the static pose in fractions of the true torso.

    Args:
        tracker: a latent, CONDENSATION or MHT tracker (``jaxtrack.trackers``).
        first_frame: frame 0's observation (the grey frame and its edge maps).
        observations: ``(time, ...)`` every frame's observation, frame 0 first.
        truth, estimate: ``(time, 12, 2)`` the true markers and the tracker's estimate.
    """
    import jax
    import jax.numpy as jnp
    import jax.random as jr

    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.evaluation import torso_lengths
    from jaxtrack.trackers._particles import frame0_state
    from jaxtrack.trackers._refinement import score_pose

    state = tracker.start(jr.PRNGKey(0), first_frame, truth[0])
    model = state.model
    dtype = model.sharpness.dtype

    def states(markers):
        return jnp.stack([frame0_state(m, model.template, dtype) for m in markers])

    score = jax.jit(jax.vmap(lambda pose, frame: score_pose(
        pose, frame, model.templates, model.template, model.sharpness)))
    frames = jnp.asarray(observations[1:], dtype)
    static = np.repeat(truth[:1], len(truth) - 1, axis=0)
    logs = {name: np.asarray(score(states(markers), frames), np.float64)
            for name, markers in (("truth", truth[1:]), ("estimate", estimate[1:]),
                                  ("static", static))}
    torso = torso_lengths(truth[1:], UPPER_BODY_12)

    def error(markers):
        return np.mean(np.linalg.norm(markers - truth[1:], axis=-1), axis=-1) / torso

    return {"log_likelihood": {name: values.tolist() for name, values in logs.items()},
            "estimate_error_torso": error(estimate[1:]).tolist(),
            "static_error_torso": error(static).tolist()}


def summarise(name: str, kind: str, check: dict) -> dict:
    """One table row: how often the truth outscores the estimate (static pose) where that is
    off by more than :data:`LOST` of the torso."""
    logs = {key: np.asarray(value) for key, value in check["log_likelihood"].items()}
    row = {"sequence": name, "kind": kind, "frames": int(len(logs["truth"])),
           "estimate_error_torso": float(np.mean(check["estimate_error_torso"]))}
    for other in ("estimate", "static"):
        off = np.asarray(check[f"{other}_error_torso"]) > LOST
        wins = logs["truth"][off] > logs[other][off]
        row[f"{other}_off_frames"] = int(off.sum())
        row[f"truth_beats_{other}"] = float(wins.mean()) if off.any() else None
        row[f"median_margin_{other}"] = (float(np.median(logs["truth"][off] - logs[other][off]))
                                         if off.any() else None)
    return row


def _share(value: float | None) -> str:
    return "—" if value is None else f"{100 * value:.0f} %"


def table(rows: list[dict]) -> str:
    """Markdown: one row per sequence (:func:`summarise`'s rows)."""
    share = _share

    def margin(value):
        return "—" if value is None else f"{value:+.1f}"

    lines = ["| sequence | kind | frames | tracker error / torso | frames estimate off | "
             "truth > estimate | median margin | frames static off | truth > static | "
             "median margin |", "|" + "---|" * 10]
    for row in rows:
        lines.append(
            f"| {row['sequence']} | {row['kind']} | {row['frames']} | "
            f"{100 * row['estimate_error_torso']:.1f} % | {row['estimate_off_frames']} | "
            f"{share(row['truth_beats_estimate'])} | {margin(row['median_margin_estimate'])} | "
            f"{row['static_off_frames']} | {share(row['truth_beats_static'])} | "
            f"{margin(row['median_margin_static'])} |")
    return "\n".join(lines)


def _check_sequence(prior, name: str, kind: str, frames: np.ndarray, truth: np.ndarray,
                    fps: float, background: np.ndarray | None, likelihood: str,
                    masks: np.ndarray | None = None, options: dict | None = None
                    ) -> tuple[dict, dict]:
    import jax.random as jr

    from jaxtrack import trackers
    from jaxtrack.vision import edge_observations

    options = options or {}
    tracker = trackers.latent_tracker(prior.model, prior.template,
                                      engine=trackers.Engine(200), fps=fps,
                                      likelihood=trackers.Likelihood(likelihood, **options),
                                      refinement=trackers.Refinement(), background=background)
    observations = (edge_observations(frames, masks=masks) if tracker.likelihood.needs_edges
                    else frames)
    result = trackers.track(tracker, jr.PRNGKey(0), observations, truth[0], progress=False)
    check = truth_preference(tracker, observations[0], observations, truth, result.markers)
    row = summarise(name, kind, check)
    print(f"  {name}: tracker {100 * row['estimate_error_torso']:.1f} % of the torso; truth > "
          f"estimate in {_share(row['truth_beats_estimate'])} of the "
          f"{row['estimate_off_frames']} frames it is off, > static in "
          f"{_share(row['truth_beats_static'])} of {row['static_off_frames']}", flush=True)
    return row, {"sequence": name, "kind": kind, **check}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.likelihood_at_truth",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=60,
                        help="rendered frames per validation clip (default 60)")
    parser.add_argument("--views", nargs="*", choices=CAMERAS, default=list(CAMERAS),
                        help="real Pose2Sim views (none: rendered clips only)")
    parser.add_argument("--no-rendered", action="store_true",
                        help="leave the rendered validation clips out")
    parser.add_argument("--likelihood", choices=("limbs+edges", "limbs", "markers"),
                        default="limbs+edges", help="the likelihood checked (default: the "
                                                    "trackers' default, limbs+edges)")
    parser.add_argument("--no-background", action="store_true",
                        help="limbs+edges without its foreground term (no median background)")
    add_mask_options(parser)
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default papers/tian2005/results/runs/likelihood_at_truth"
                             "[-LIKELIHOOD][-no-background][-masks][-muMU].json)")
    args = parser.parse_args(argv)
    if args.frames < 2:
        parser.error(f"--frames must be at least 2, got {args.frames}")
    if args.no_rendered and not args.views:
        parser.error("nothing to check: --no-rendered and no --views")
    if args.likelihood != "limbs+edges":
        for given, option in ((args.no_background, "--no-background"),
                              (args.masks != "none", "--masks"),
                              (args.foreground_weight is not None, "--foreground-weight"),
                              (args.coverage_weight is not None, "--coverage-weight")):
            if given:
                parser.error(f"{option} is about limbs+edges' foreground term; --likelihood "
                             f"{args.likelihood} has none")
    if args.no_background and args.masks != "none":
        parser.error("--no-background leaves the foreground term out; --masks gives it masks")
    suffix = check_mask_options(parser, args)
    out = args.out or RESULTS / ("likelihood_at_truth"
                                 + ("" if args.likelihood == "limbs+edges"
                                    else "-" + args.likelihood.replace("+", "_"))
                                 + ("-no-background" if args.no_background else "")
                                 + suffix + ".json")
    use_background = args.likelihood == "limbs+edges" and not args.no_background

    from jaxtrack.data.clip_sets import GESTURE_CLIPS, TRAINING_CLIPS
    from jaxtrack.evaluation.reference import default_folder
    from jaxtrack.experiments import render_test_sequences
    from jaxtrack.vision import median_grey_background
    from papers.tian2005.real_video import View

    started = time.perf_counter()
    prior = candidate_prior("waves")
    print(f"prior: {', '.join(TRAINING_CLIPS)}; {device_description()}")
    rows, records = [], []
    if not args.no_rendered:
        for index, clip in enumerate(GESTURE_CLIPS["validation"]):
            sequence = render_test_sequences(clip, views=1, seed=index,
                                             max_frames=args.frames)[0]
            masks = (masks_or_exit(sequence.images, sequence.name)
                     if args.masks == "mediapipe" else None)
            row, record = _check_sequence(prior, sequence.name, "rendered, validation",
                                          sequence.frames, sequence.truth, sequence.fps,
                                          median_grey_background(sequence.frames)
                                          if use_background else None, args.likelihood,
                                          masks, likelihood_options(args))
            rows.append(row)
            records.append(record)
    if args.views:
        folder = default_folder()
        for camera in args.views:
            view = View(folder, camera, None, 960, stride=2)
            masks = (masks_or_exit(view.images, camera) if args.masks == "mediapipe"
                     else None)
            row, record = _check_sequence(prior, f"Pose2Sim {camera}", "real, test",
                                          view.frames, view.truth, view.fps,
                                          view.background if use_background else None,
                                          args.likelihood, masks, likelihood_options(args))
            rows.append(row)
            records.append(record)
    text = table(rows)
    print(text)
    header = run_header("papers.tian2005.likelihood_at_truth", argv, started)
    write_json_atomically(out, {
        **header, "likelihood": args.likelihood,
        "background": use_background, "masks": args.masks,
        "foreground_weight": args.foreground_weight,
        "coverage_weight": args.coverage_weight, "lost": LOST, "rows": rows,
        "table": text, "sequences": records})
    print(f"wrote {out} in {header['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
