"""Command line: ``jaxtrack demo | render | evaluate | train | track | clips``.

One module per command, each with ``add_parser(subparsers)`` that registers its parser and
handler; the handlers import their heavy dependencies lazily so ``jaxtrack --help`` stays fast
and needs no OpenCV. A :class:`UserError` raised by a handler is printed as one line and exits
with status 2.
"""

from __future__ import annotations

import argparse
import sys

from jaxtrack.cli import clips, demo, evaluate, render, track, train
from jaxtrack.cli._common import UserError

__all__ = ["UserError", "build_parser", "main"]

_COMMANDS = (demo, render, evaluate, train, track, clips)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxtrack",
        description="JAX particle filters for human body pose tracking.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in _COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except UserError as error:
        print(f"jaxtrack {args.command}: error: {error}", file=sys.stderr)
        return 2

