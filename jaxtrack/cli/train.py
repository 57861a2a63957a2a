"""``jaxtrack train``: learn a GPLVM pose prior from clips (``jaxtrack.priors.train``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.cli._common import (
    UserError,
    add_asf_option,
    check_asf,
    check_clips,
    check_prior_file,
    check_seed,
    load_clip_sources,
    output_folder,
)

__all__ = ["add_parser"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train",
        help="learn a GPLVM pose prior from real motion clips (a model for jaxtrack track)",
        description=(
            "Project the clips' upper-body poses from several viewpoints (±45°), learn a 2-D "
            "GPLVM with its latent dynamics (Algorithm 1 of Tian et al.) and save it with its "
            "SPM template. Re-running with the same settings and --out reuses the file. A clip "
            "is a catalogue name (see jaxtrack.data.list_clips()) or a path to a .bvh file or "
            "an .amc file (its .asf beside it, or given with --asf)."),
        epilog="example: jaxtrack train --clips animateddrawings/fair1_wave_hello "
               "animateddrawings/history_c119d6b/8yr_old_wave_hello --out waves.npz",
    )
    parser.add_argument("--clips", nargs="+", required=True, metavar="CLIP",
                        help="clips to learn from: catalogue names or .bvh/.amc files")
    add_asf_option(parser)
    parser.add_argument("--out", required=True, type=Path, metavar="MODEL.npz",
                        help="model file to write (reused when it holds a model trained with "
                             "the same settings)")
    parser.add_argument("--views", type=int, default=5, help="viewpoints per clip (default 5)")
    parser.add_argument("--active", type=int, default=200, help="active set size (default 200)")
    parser.add_argument("--iterations", type=int, default=3,
                        help="outer iterations of Algorithm 1 (default 3)")
    parser.add_argument("--seed", type=int, default=0,
                        help="random seed of the training (default 0)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from jaxtrack.priors.train import train_prior

    sources = check_clips(args.clips, "--clips", args.asf)
    check_asf(args.asf, sources)
    if args.out.suffix != ".npz":
        raise UserError(f"--out {args.out}: must be a .npz path")
    folder = output_folder(args.out, "--out")
    for name in ("views", "active", "iterations"):
        if getattr(args, name) < 1:
            raise UserError(f"--{name} must be positive, got {getattr(args, name)}")
    check_seed(args.seed)
    check_prior_file(args.out, "--out", "delete it or choose another --out to train a new one")
    load_clip_sources(sources, "--clips")
    folder.mkdir(parents=True, exist_ok=True)
    prior = train_prior(args.clips, views=args.views, active_size=args.active,
                        iterations=args.iterations, seed=args.seed, cache=args.out,
                        asf=args.asf)
    print(f"GPLVM of {prior.description['num_poses']} poses, active set "
          f"{prior.model.active_size} -> {args.out}")
    return 0
