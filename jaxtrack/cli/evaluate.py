"""``jaxtrack evaluate``: train a GPLVM, render held-out clips, track, score, write JSON/plots."""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.cli._common import UserError, check_clips
from jaxtrack.cli._options import add_tracker_options, tracker_options
from jaxtrack.priors.gplvm import OPTIMISERS

__all__ = ["add_parser"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "evaluate",
        help="track held-out real clips with a method and write metrics as JSON",
        description=(
            "Train the GPLVM on the --train clips (cached in the --json file's folder), render "
            "each --test clip (frontal and random views, photo and clutter backgrounds) with "
            "exact ground truth, track it with --method initialised from frame 0, and write the "
            "metrics (per sequence and overall) as JSON; with --plots, error plots and overlay "
            "videos. Clip names: see jaxtrack.data.list_clips()."),
    )
    parser.add_argument("--method", required=True, choices=("latent", "condensation", "mht"))
    parser.add_argument("--train", nargs="+", required=True, metavar="CLIP")
    parser.add_argument("--test", nargs="+", required=True, metavar="CLIP")
    parser.add_argument("--particles", type=int, default=None,
                        help="particles (modes for mht); default 200 / 1000 / 10")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--prior-optimiser", choices=OPTIMISERS, default="bfgs",
                        help="eq. 1's minimiser when training the GPLVM (default bfgs, what the "
                             "README's results used; lbfgs: see benchmarks/RESULTS.md)")
    add_tracker_options(parser)
    parser.add_argument("--views", type=int, default=2, help="views per test clip (default 2)")
    parser.add_argument("--backgrounds", nargs="+", default=["photo", "clutter"],
                        choices=("plain", "photo", "clutter"))
    parser.add_argument("--max-frames", type=int, default=None)
    parser.add_argument("--json", required=True, type=Path, metavar="OUT.json")
    parser.add_argument("--plots", type=Path, default=None, metavar="DIR")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
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

    check_clips(args.train, "--train")
    check_clips(args.test, "--test")
    overlap = sorted(set(args.train) & set(args.test))
    if overlap:
        raise UserError(f"--test clips must be held out, but {', '.join(overlap)} is also in "
                        f"--train")
    if args.particles is not None and args.particles < 1:
        raise UserError(f"--particles must be positive, got {args.particles}")
    if args.views < 1:
        raise UserError(f"--views must be positive, got {args.views}")
    options = tracker_options(args)
    if args.json.suffix != ".json" or not args.json.parent.exists():
        raise UserError(f"--json {args.json}: must be a .json path in an existing folder")
    if args.plots is not None:
        args.plots.mkdir(parents=True, exist_ok=True)
    particles = args.particles or DEFAULT_PARTICLES[args.method]
    prior = train_prior(args.train, cache=args.json.parent / "gplvm_cache.npz", seed=args.seed,
                        optimiser=args.prior_optimiser)
    per_sequence = []
    for clip in args.test:
        for sequence in render_test_sequences(clip, views=args.views,
                                              backgrounds=args.backgrounds, seed=args.seed,
                                              max_frames=args.max_frames):
            result = run_method(args.method, prior, sequence, particles=particles,
                                seed=args.seed, likelihood=options.likelihood,
                                refinement=options.refinement, background=options.foreground)
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
        "tracker": tracker_record,
        "train": args.train, "test": args.test,
        "prior": prior.description,
        "overall": overall, "sequences": per_sequence})
    print(compare_methods({f"{args.method} (N={particles})": overall}))
    print(f"wrote {args.json}")
    return 0
