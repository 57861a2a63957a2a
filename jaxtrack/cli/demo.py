"""``jaxtrack demo``: the end-to-end example (:func:`jaxtrack.experiments.demo.run_demo`)."""

from __future__ import annotations

import argparse

__all__ = ["add_parser"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser("demo", help="run the end-to-end example (the main job)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from jaxtrack.experiments.demo import run_demo

    return run_demo(seed=args.seed)
