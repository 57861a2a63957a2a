"""``jaxtrack evaluate``: train a model, render held-out clips, track, score, write JSON/plots.

``--method latent|condensation|mht`` here; ``linear-combination`` in
``jaxtrack.cli._train_linear_combination`` and ``mixed-state`` in
``jaxtrack.cli._evaluate_mixed_state``."""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.cli._common import (
    UserError,
    add_asf_option,
    check_asf,
    check_clips,
    check_held_out,
    check_json_and_plots,
    check_memory,
    check_prior_file,
    check_seed,
    integer,
    load_clip_sources,
    real,
    seed,
)
from jaxtrack.cli._options import add_tracker_options, tracker_options
from jaxtrack.priors.gplvm import OPTIMISERS

__all__ = ["METHODS", "add_parser", "tracking_bytes"]

METHODS = ("latent", "condensation", "mht", "linear-combination", "mixed-state")

_SAMPLES_PER_POSE = 9 * 12 * 7
"""Pixels one pose's likelihood reads: 9 limb strips of 12 × 7 points (``likelihoods.limbs``;
the marker patches read 12 × 13² = 2 028, the same order)."""
_FLOATS_PER_SAMPLE = 4
"""Live 4-byte values per sample point while a frame's particles are scored: its x and y, the
pixel read and its centred value."""
_STATE_FLOATS = 25 * 6
"""A particle's SPM state (25 numbers) in its copies: carried, resampled parents, propagated
children, decoded markers and the weights, ancestors and sort keys beside them."""
_FIXED_BYTES = 1 << 30
"""The rest of a run: JAX and XLA, the compiled scan, a chunk of frames, the GPLVM."""


def tracking_bytes(method: str, particles: int) -> int:
    """Approximate peak memory of tracking one sequence with ``particles`` particles (modes
    for ``mht``): every particle's state and its likelihood's work arrays are live at once
    inside the compiled step, so the peak grows as particles × (state + samples read per pose
    × values per sample). MHT's modes each hold a Gauss-Newton Jacobian, 25 columns of the
    residuals. About 13 kB a particle: an upper estimate to refuse impossible runs, checked
    against measured peaks in ``papers/tian2005/history.md`` (section "Memory")."""
    per_particle = 4 * (_STATE_FLOATS + _SAMPLES_PER_POSE * _FLOATS_PER_SAMPLE)
    if method == "mht":
        per_particle *= 25
    return _FIXED_BYTES + particles * per_particle


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "evaluate",
        help="track held-out real clips with a method and write metrics as JSON",
        description=(
            "Train the GPLVM on the --train clips (cached in the --json file's folder), render "
            "each --test clip (frontal and random views, photo and clutter backgrounds) with "
            "exact ground truth, track it with --method initialised from frame 0, and write the "
            "metrics (per sequence and overall) as JSON; with --plots, error plots and overlay "
            "videos. A clip is a catalogue name (see jaxtrack.data.list_clips()) or a path to a "
            ".bvh file or an .amc file (its .asf beside it, or given with --asf)."),
    )
    parser.add_argument("--method", required=True, choices=METHODS,
                        help="the tracker: Tian et al.'s latent-space tracker, CONDENSATION in "
                        "the 25-d state with AR(2) dynamics, multiple-hypothesis tracking, Ong "
                        "& Gong's linear-combination tracker (3-D skeleton error), or Kwatra et "
                        "al.'s mixed-state tracker (posture and body parts)")
    parser.add_argument("--train", nargs="+", default=None, metavar="CLIP",
                        help="clips to train on: catalogue names or .bvh/.amc files (required "
                        "for latent, condensation and mht; linear-combination and mixed-state "
                        "default to their training clips)")
    parser.add_argument("--test", nargs="+", default=None, metavar="CLIP",
                        help="held-out clips to render and track: catalogue names or "
                             ".bvh/.amc files (required for latent, condensation and mht; "
                             "linear-combination and mixed-state default to their test clips)")
    add_asf_option(parser)
    parser.add_argument("--particles", type=integer(1), default=None,
                        help="particles (modes for mht); default 200 / 1000 / 10")
    parser.add_argument("--seed", type=seed, default=0,
                        help="random seed of training, viewpoints, rendering and tracking "
                             "(default 0)")
    parser.add_argument("--prior-optimiser", choices=OPTIMISERS, default="bfgs",
                        help="eq. 1's minimiser when training the GPLVM (default bfgs, what the "
                             "tracking results in papers/tian2005/history.md used; lbfgs: see "
                             "docs/gplvm.md)")
    add_tracker_options(parser)
    parser.add_argument("--baseline-dynamics", choices=("training", "test_start"),
                        default="training",
                        help="what CONDENSATION's AR(2) and MHT's step are learned from: the "
                             "--train clips' poses (default), or the first 30 frames of each "
                             "test clip's ground truth (Tian et al.'s protocol)")
    parser.add_argument("--allow-same-subject", action="store_true",
                        help="score --test clips whose subject (jaxtrack.data.splits) also "
                             "performed a --train clip; by default that is refused")
    parser.add_argument("--views", type=integer(1), default=2,
                        help="views per test clip (default 2)")
    parser.add_argument("--backgrounds", nargs="+", default=["photo", "clutter"],
                        choices=("plain", "photo", "clutter"),
                        help="what each test clip is rendered over: a plain grey, a real photo, "
                        "or synthetic clutter (default photo clutter)")
    parser.add_argument("--max-frames", type=integer(2, reason="(frame 0 starts the tracker)"),
                        default=None, metavar="N",
                        help="track at most the first N frames of each test clip (at 30 fps; "
                             "default: all)")
    parser.add_argument("--json", required=True, type=Path, metavar="OUT.json",
                        help="metrics file to write (its folder is created; the trained GPLVM "
                             "is cached beside it as gplvm_cache.npz)")
    parser.add_argument("--plots", type=Path, default=None, metavar="DIR",
                        help="also write error plots and overlay videos into DIR")
    group = parser.add_argument_group("linear-combination and mixed-state")
    # linear-combination options
    group.add_argument("--cameras", type=integer(0), nargs="+", default=None, metavar="INDEX",
                       help="linear-combination: Pose2Sim cameras (0-3) to render through "
                       "(default all four); mixed-state: also render the test clips through "
                       "these (default none)")
    group.add_argument("--iterations", type=integer(1), default=None,
                       help="linear-combination: CONDENSATION iterations per frame (default 5)")
    # mixed-state options
    group.add_argument("--bins", type=integer(1), default=None, metavar="B",
                       help="mixed-state: bins per axis of the silhouette projection histograms "
                       "(default 16)")
    group.add_argument("--azimuths", type=real(-180.0, 180.0, unit=" degrees"), nargs="+",
                       default=None, metavar="DEGREES",
                       help="mixed-state: camera azimuths each --train and --test clip is "
                       "rendered from, degrees from the subject's facing direction (default 90 "
                       "-90 45 -45 0)")
    group.add_argument("--size", default=None, metavar="WIDTHxHEIGHT",
                       help="mixed-state: size of the rendered images (default 640x480)")
    group.add_argument("--lag", type=integer(0), default=None, metavar="FRAMES",
                       help="mixed-state: lag of the fixed-lag smoother scored beside the "
                       "whole-sequence one (default 10)")
    group.add_argument("--train-max-frames", type=integer(2), default=None, metavar="N",
                       help="mixed-state: at most the first N frames of each --train clip "
                       "(default: all)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.method == "linear-combination":
        from jaxtrack.cli import _train_linear_combination

        return _train_linear_combination.evaluate(args)
    if args.method == "mixed-state":
        from jaxtrack.cli import _evaluate_mixed_state

        return _evaluate_mixed_state.evaluate(args)
    for option in ("train", "test"):
        if getattr(args, option) is None:
            raise UserError(f"--{option} is required for --method {args.method}")
    from jaxtrack._files import write_json_atomically
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.evaluation import (
        compare_methods,
        evaluate_track,
        plot_errors_over_time,
        summarise,
    )
    from jaxtrack.experiments import DEFAULT_PARTICLES, render_test_sequences, run_method
    from jaxtrack.priors.train import train_prior
    from jaxtrack.vision import write_overlay_video

    train_sources = check_clips(args.train, "--train", args.asf)
    test_sources = check_clips(args.test, "--test", args.asf)
    check_asf(args.asf, train_sources + test_sources)
    check_held_out(train_sources, test_sources)
    if not args.allow_same_subject:
        from jaxtrack.data.splits import check_disjoint

        try:
            check_disjoint(args.train, args.test)
        except ValueError as error:
            raise UserError(f"{error}; or pass --allow-same-subject") from None
    if args.particles is not None and args.particles < 1:
        raise UserError(f"--particles must be positive, got {args.particles}")
    if args.views < 1:
        raise UserError(f"--views must be positive, got {args.views}")
    if args.max_frames is not None and args.max_frames < 2:
        raise UserError(f"--max-frames must be at least 2 (frame 0 starts the tracker), got "
                        f"{args.max_frames}")
    check_seed(args.seed)
    options = tracker_options(args)
    folder = check_json_and_plots(args)
    cache = folder / "gplvm_cache.npz"
    check_prior_file(cache, "the GPLVM cached beside --json:",
                     "delete it (it is retrained and rewritten) or write --json elsewhere")
    particles = args.particles or DEFAULT_PARTICLES[args.method]
    check_memory(tracking_bytes(args.method, particles), f"tracking with {particles} "
                 f"{'modes' if args.method == 'mht' else 'particles'}", "--particles")
    load_clip_sources(train_sources + test_sources, "--train/--test")
    # every argument checked: only now is anything written
    folder.mkdir(parents=True, exist_ok=True)
    if args.plots is not None:
        args.plots.mkdir(parents=True, exist_ok=True)
    prior = train_prior(args.train, cache=cache, seed=args.seed,
                        optimiser=args.prior_optimiser, asf=args.asf)
    per_sequence = []
    for clip in args.test:
        for sequence in render_test_sequences(clip, views=args.views,
                                              backgrounds=args.backgrounds, seed=args.seed,
                                              max_frames=args.max_frames, asf=args.asf):
            result = run_method(args.method, prior, sequence, particles=particles,
                                seed=args.seed, likelihood=options.likelihood,
                                refinement=options.refinement, background=options.foreground,
                                baseline_dynamics=args.baseline_dynamics)
            tracker_record = result.options
            metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12,
                                     seconds_per_frame=result.seconds_per_frame,
                                     compile_seconds=result.compile_seconds)
            metrics |= {"sequence": sequence.name, "clip": clip}
            per_sequence.append(metrics)
            if args.plots is not None:
                plot_errors_over_time({args.method: metrics["errors_torso"]},
                                      args.plots / f"{sequence.name}_errors.png",
                                      fps=sequence.fps, title=sequence.name)
                write_overlay_video(sequence.images, {args.method: result.markers},
                                    args.plots / f"{sequence.name}_{args.method}.mp4",
                                    fps=sequence.fps, marker_names=UPPER_BODY_12,
                                    truth=sequence.truth)
    overall = summarise(per_sequence)
    write_json_atomically(args.json, {
        "method": args.method, "particles": particles, "seed": args.seed,
        "tracker": tracker_record, "baseline_dynamics": args.baseline_dynamics,
        "train": args.train, "test": args.test,
        "prior": prior.description,
        "overall": overall, "sequences": per_sequence})
    print(compare_methods({f"{args.method} (N={particles})": overall}))
    print(f"wrote {args.json}")
    return 0
