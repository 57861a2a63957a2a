"""``jaxtrack train``: learn a model from clips: the latent tracker's GPLVM pose prior
(``jaxtrack.priors.train``), the linear-combination model (``--method linear-combination``:
``jaxtrack.cli._train_linear_combination``) or the mixed-state posture model (``--method
mixed-state``: ``jaxtrack.cli._train_mixed_state``)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from jaxtrack.cli._common import (
    UserError,
    add_asf_option,
    check_asf,
    check_clips,
    check_prior_file,
    check_seed,
    integer,
    load_clip_sources,
    output_folder,
    outputs_or_nothing,
    real,
    seed,
)

__all__ = ["METHODS", "add_parser"]

METHODS = ("latent", "linear-combination", "mixed-state")


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train",
        help="learn a model from real motion clips (a GPLVM pose prior by default; a model for "
             "jaxtrack track)",
        description=(
            "Project the clips' upper-body poses from several viewpoints (±45°), learn a 2-D "
            "GPLVM with its latent dynamics (Algorithm 1 of Tian et al.) and save it with its "
            "SPM template (--method latent, the default). Without --clips, the clips the "
            "method's bundled model was trained on (bundled too), so that, e.g., jaxtrack "
            "train --out latent.npz remakes jaxtrack's own latent.npz. Re-running with the "
            "same settings and --out reuses the file. A clip "
            "is a catalogue name (see jaxtrack.data.list_clips()) or a path to a .bvh file or "
            "an .amc file (its .asf beside it, or given with --asf)."),
        epilog="example: jaxtrack train --clips animateddrawings/fair1_wave_hello "
               "animateddrawings/history_c119d6b/8yr_old_wave_hello --out waves.npz",
    )
    parser.add_argument("--method", choices=METHODS, default="latent",
                        help="what to train: the latent tracker's GPLVM prior (default), Ong & "
                        "Gong's linear-combination model, or Kwatra et al.'s posture model")
    parser.add_argument("--clips", nargs="+", default=None, metavar="CLIP",
                        help="clips to learn from: catalogue names or .bvh/.amc files "
                        "(default: the training subjects' clips bundled with jaxtrack that "
                        "the method's bundled model was trained on, jaxtrack.data.models; "
                        "python -m jaxtrack.data.models lists them)")
    add_asf_option(parser)
    parser.add_argument("--out", required=True, type=Path, metavar="MODEL.npz",
                        help="model file to write (reused when it holds a model trained with "
                             "the same settings)")
    parser.add_argument("--views", type=integer(1), default=5,
                        help="latent: viewpoints per clip (default 5)")
    parser.add_argument("--active", type=integer(1), default=200,
                        help="active set size (default 200)")
    parser.add_argument("--iterations", type=integer(1), default=3,
                        help="outer iterations of Algorithm 1 (default 3)")
    parser.add_argument("--seed", type=seed, default=0,
                        help="random seed of the training, 0 to 2**32 - 1 (default 0)")
    parser.add_argument("--parts", action="store_true",
                        help="latent: one GPLVM per body part (torso, each arm) instead of one "
                             "of the whole upper body: reconstructs new people's poses better "
                             "(papers/tian2005/history.md, 'A prior that generalises across "
                             "people')")
    parser.add_argument("--mirror", action="store_true",
                        help="latent: also learn from every clip's left-right mirror image")
    parser.add_argument("--back-constraint", type=real(positive=True, unit=" width"),
                        default=None, metavar="WIDTH",
                        help="latent: a back-constrained GPLVM, every latent a smooth function "
                             "of its pose, with this kernel width (relative to the median "
                             "distance between poses; papers/tian2005/history.md)")
    group = parser.add_argument_group("linear-combination and mixed-state")
    # linear-combination options
    group.add_argument("--cameras", type=integer(0), nargs="+", default=None, metavar="INDEX",
                       help="linear-combination: Pose2Sim cameras (0-3) each clip is rendered "
                       "through (default all four)")
    group.add_argument("--clusters", type=integer(2), default=None,
                       help="linear-combination: k-means clusters of the coefficient space")
    # mixed-state options
    group.add_argument("--max-frames", type=integer(2), default=None, metavar="N",
                       help="linear-combination, mixed-state: at most the first N frames of "
                       "each clip (default: all)")
    group.add_argument("--laid-down", nargs="+", default=None, metavar="CLIP",
                       help="mixed-state: clips also laid on their back and on their front "
                       "as lying training data (default: without --clips, the bundled posture "
                       "model's two waves; with --clips, none)")
    group.add_argument("--bins", type=integer(1), default=None, metavar="B",
                       help="mixed-state: bins per axis of the silhouette projection histograms "
                       "(default 16)")
    group.add_argument("--azimuths", type=real(-180.0, 180.0, unit=" degrees"), nargs="+",
                       default=None, metavar="DEGREES",
                       help="mixed-state: camera azimuths each clip is rendered from, degrees "
                       "from the subject's facing direction (default 90 -90 45 -45 0)")
    group.add_argument("--size", default=None, metavar="WIDTHxHEIGHT",
                       help="mixed-state: size of the rendered images (default 640x480)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from jaxtrack.data.models import METHODS, RECIPES

    if args.laid_down is not None and args.method != "mixed-state":
        raise UserError(f"--laid-down does not apply to --method {args.method} (it is the "
                        f"mixed-state posture model's lying training data)")
    if args.clips is None:  # the bundled model's clips, all bundled with the package
        recipe = RECIPES[METHODS[args.method]]
        args.clips = list(recipe.clips)
        if args.laid_down is None:
            args.laid_down = list(recipe.laid_down) or None
    if args.method == "linear-combination":
        from jaxtrack.cli import _train_linear_combination

        return _train_linear_combination.train(args)
    if args.method == "mixed-state":
        from jaxtrack.cli import _train_mixed_state

        return _train_mixed_state.train(args)
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
    if args.back_constraint is not None and not (math.isfinite(args.back_constraint)
                                                 and args.back_constraint > 0):
        raise UserError(f"--back-constraint must be a positive width, got {args.back_constraint}")
    check_prior_file(args.out, "--out", "delete it or choose another --out to train a new one")
    load_clip_sources(sources, "--clips")
    from jaxtrack.priors.gplvm import UPPER_BODY_PARTS

    with outputs_or_nothing(folder):  # a folder created for --out goes again on Ctrl-C
        print(f"training on {len(args.clips)} clip(s) -> {args.out}", flush=True)
        prior = train_prior(args.clips, views=args.views, active_size=args.active,
                            iterations=args.iterations, seed=args.seed, cache=args.out,
                            asf=args.asf, mirror=args.mirror,
                            parts=UPPER_BODY_PARTS if args.parts else None,
                            back_constraint=args.back_constraint)
    kind = f"{len(UPPER_BODY_PARTS)} GPLVMs, one per part," if args.parts else "GPLVM"
    print(f"{kind} of {prior.description['num_poses']} poses, active set "
          f"{prior.model.active_size} -> {args.out}")
    return 0
