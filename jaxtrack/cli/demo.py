"""``jaxtrack demo``: the end-to-end example (:func:`jaxtrack.experiments.demo.run_demo`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.cli._common import UserError, output_directory, seed

__all__ = ["add_parser"]

OUTPUT = Path("jaxtrack-demo")


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo", help="run the end-to-end example (the main job)",
        description=(
            "Train a GPLVM pose prior on three bundled real wave gestures (or reuse the cached "
            "one), render a fourth, held-out take over a real photo background with exact "
            "ground truth, track it with the latent-space tracker (200 particles) and with "
            "CONDENSATION in the full pose space (1000 particles), 3 seeds each, and print a "
            "comparison table. Takes a few minutes on a laptop CPU."),
        epilog=(
            f"writes into ./{OUTPUT}/ (created): gplvm_waves.npz (the trained prior, reused by "
            "later runs; delete it to retrain), tracking.mp4 (both trackers' markers over the "
            "video, the truth thin and white on top), errors.png (error per frame), "
            "latent_space.png (the prior's latent space) and metrics.json (every number "
            "printed). The prior can be given to jaxtrack track --model "
            f"{OUTPUT}/gplvm_waves.npz."))
    parser.add_argument("--seed", type=seed, default=0,
                        help="random seed of training, rendering and the first tracker run "
                        "(default 0)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from jaxtrack.experiments.demo import run_demo
    from jaxtrack.priors.gplvm import GPLVMFormatError

    if OUTPUT.exists() and not OUTPUT.is_dir():
        raise UserError(f"./{OUTPUT} exists and is not a folder; the demo writes its outputs "
                        "into that folder: move or delete the file and run again")
    output_directory(OUTPUT, "the demo's output folder")
    cache = OUTPUT / "gplvm_waves.npz"
    if cache.exists() and not cache.is_file():
        raise UserError(f"{cache} exists and is not a file; delete it and run again to retrain")
    try:
        return run_demo(seed=args.seed, output_dir=OUTPUT)
    except GPLVMFormatError as error:
        raise UserError(f"the cached prior {cache} cannot be read "
                        f"({' '.join(str(error).split())}); delete it and run again to "
                        "retrain") from None
