"""``jaxtrack train``: learn a GPLVM pose prior from clips (``jaxtrack.priors.train``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.cli._common import UserError, check_clips

__all__ = ["add_parser"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train",
        help="learn a GPLVM pose prior from real motion clips (a model for jaxtrack track)",
        description=(
            "Project the clips' upper-body poses from several viewpoints (±45°), learn a 2-D "
            "GPLVM with its latent dynamics (Algorithm 1 of Tian et al.) and save it with its "
            "SPM template. Re-running with the same settings and --out reuses the file. Clip "
            "names: see jaxtrack.data.list_clips()."),
        epilog="example: jaxtrack train --clips animateddrawings/fair1_wave_hello "
               "animateddrawings/history_c119d6b/8yr_old_wave_hello --out waves.npz",
    )
    parser.add_argument("--clips", nargs="+", required=True, metavar="CLIP")
    parser.add_argument("--out", required=True, type=Path, metavar="MODEL.npz")
    parser.add_argument("--views", type=int, default=5, help="viewpoints per clip (default 5)")
    parser.add_argument("--active", type=int, default=200, help="active set size (default 200)")
    parser.add_argument("--iterations", type=int, default=3,
                        help="outer iterations of Algorithm 1 (default 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from jaxtrack.priors.train import train_prior

    check_clips(args.clips, "--clips")
    if args.out.suffix != ".npz" or not args.out.parent.is_dir():
        raise UserError(f"--out {args.out}: must be a .npz path in an existing folder")
    for name in ("views", "active", "iterations"):
        if getattr(args, name) < 1:
            raise UserError(f"--{name} must be positive, got {getattr(args, name)}")
    prior = train_prior(args.clips, views=args.views, active_size=args.active,
                        iterations=args.iterations, seed=args.seed, cache=args.out)
    print(f"GPLVM of {prior.description['num_poses']} poses, active set "
          f"{prior.model.active_size} -> {args.out}")
    return 0
