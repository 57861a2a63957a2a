"""Command line: ``jaxtrack demo | render | ...``.

Each subcommand lives in a ``_add_<name>`` function that registers its parser and handler; the
handlers import their heavy dependencies lazily so ``jaxtrack --help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys


class UserError(Exception):
    """An error caused by the user's input: printed as one line, exit status 2."""


def _add_demo(subparsers) -> None:
    parser = subparsers.add_parser("demo", help="run the end-to-end example (the main job)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.set_defaults(handler=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    from jaxtrack._demo import main as demo_main

    return demo_main(seed=args.seed)


_SUBCOMMANDS = [_add_demo]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxtrack",
        description="JAX particle filters for human body pose tracking.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in _SUBCOMMANDS:
        add(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except UserError as error:
        print(f"jaxtrack {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
