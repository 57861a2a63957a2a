"""Command line: ``jaxtrack demo | render | evaluate | train | track | triangulate | clips``.

One module per command, each with ``add_parser(subparsers)`` that registers its parser and
handler; the handlers import their heavy dependencies lazily so ``jaxtrack --help`` stays fast
and needs no OpenCV. A bad argument (argparse's, or a :class:`UserError` raised by a handler) is
printed as one line and exits with status 2.

Ctrl-C prints ``jaxtrack COMMAND: interrupted`` and exits with status 130. What the command was
writing is removed on the way out (its temporary files by ``jaxtrack._files.write_atomically``,
its finished outputs by ``jaxtrack.cli._common.outputs_or_nothing``). Run as a program
(``argv`` None), the process then ends with ``os._exit(130)`` after flushing its output:
a KeyboardInterrupt raised while XLA's threads still run a computation can crash the
interpreter's teardown (a segmentation fault, exit status 139), and nothing is left to tear
down that matters.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

from jaxtrack.cli import clips, demo, evaluate, render, track, train, triangulate
from jaxtrack.cli._common import ArgumentsError, OneLineParser, UserError

__all__ = ["INTERRUPTED", "UserError", "build_parser", "main"]

INTERRUPTED = 130
"""The exit status after Ctrl-C (128 + SIGINT, as shells report it)."""

_COMMANDS = (demo, render, evaluate, train, track, triangulate, clips)


def build_parser() -> OneLineParser:
    parser = OneLineParser(
        prog="jaxtrack",
        description="JAX particle filters for human body pose tracking.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in _COMMANDS:
        command.add_parser(subparsers)
    return parser


def _exit_now(code: int) -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def _on_sigint(signum, frame) -> None:
    """Python's own reaction to Ctrl-C (``KeyboardInterrupt``), recorded first: an exception
    raised inside a callback XLA runs can be swallowed there, and the record makes the next
    output written raise it again (``jaxtrack._files.record_interrupt``)."""
    from jaxtrack import _files

    _files.record_interrupt()
    raise KeyboardInterrupt


@contextlib.contextmanager
def _recording_interrupts():
    """:func:`_on_sigint` as the SIGINT handler for the command's duration (main thread only:
    elsewhere signals cannot be handled), the previous handler and no record left after."""
    from jaxtrack import _files

    _files.clear_interrupts()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _files.clear_interrupts()  # what follows in this process is not the command's


def main(argv: list[str] | None = None) -> int:
    command = "jaxtrack"
    try:
        args = build_parser().parse_args(argv)
        command = f"jaxtrack {args.command}"
        with _recording_interrupts():
            return int(args.handler(args) or 0)
    except ArgumentsError as error:
        print(f"{error.prog}: error: {error}", file=sys.stderr)
        return 2
    except UserError as error:
        print(f"{command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\n{command}: interrupted" if _on_terminal() else f"{command}: interrupted",
              file=sys.stderr)
        if argv is None:  # a program, not a caller that goes on
            _exit_now(INTERRUPTED)
        return INTERRUPTED


def _on_terminal() -> bool:
    """Whether stderr is a terminal (where ``^C`` was echoed on the current line)."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False
