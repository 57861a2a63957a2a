"""The tracker options every tracking command takes (``jaxtrack evaluate``, ``jaxtrack track``),
built once into option modules (``jaxtrack.trackers.Likelihood``, ``Refinement``,
``ArmSearch``) and passed through unopened."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from jaxtrack.cli._common import UserError, integer, real

__all__ = ["TrackerOptions", "add_tracker_options", "tracker_options"]


def add_tracker_options(parser: argparse.ArgumentParser) -> None:
    """``--likelihood``, ``--foreground`` and the refinement stage's ``--refine-steps``,
    ``--arm-grid`` and ``--arm-momentum`` (None: the method's defaults)."""
    parser.add_argument("--likelihood", choices=("limbs+edges", "limbs", "markers"),
                        default="limbs+edges", help="limb strips and their edges (default), "
                        "limb strips alone, or the paper's patches at the markers")
    parser.add_argument("--foreground", choices=("median", "none"), default="median",
                        help="limbs+edges: also score the arm strips by whether their centre "
                        "lines differ from the video's median background, for a static camera "
                        "(default median; none: off)")
    parser.add_argument("--refine-steps", type=integer(0), default=None, metavar="N",
                        help="Gauss-Newton steps of the full-state refinement stage of the "
                        "reported pose, for any method (0: none). Default: the latent "
                        "tracker refines with 10 steps (none with --likelihood markers), "
                        "CONDENSATION and MHT report their own estimate; giving this or an "
                        "arm option runs the same stage for any method")
    parser.add_argument("--arm-grid", type=integer(0), default=None, metavar="N",
                        help="angle offsets per arm joint of the arm search that starts each "
                        "refinement (odd; default 7; 0: no search)")
    parser.add_argument("--arm-momentum", type=real(0.0, 1.0), default=None, metavar="M",
                        help="the arm search also searches about the arm angles moved on by M "
                        "times their change over the last frame (0 to 1; default 1; 0: about "
                        "the carried arm alone)")


@dataclass(frozen=True)
class TrackerOptions:
    """What the tracking commands pass to a tracker: the likelihood, the refinement stage
    (``"default"``: the method's own default) and whether to score the foreground."""

    likelihood: object
    refinement: object
    foreground: bool


def tracker_options(args: argparse.Namespace) -> TrackerOptions:
    """The option modules of ``args``; a bad value is a one-line :class:`UserError`."""
    from jaxtrack.trackers import (
        DEFAULT_ARM_GRID,
        DEFAULT_ARM_MOMENTUM,
        DEFAULT_REFINE_STEPS,
        ArmSearch,
        Likelihood,
        Refinement,
    )

    if args.refine_steps is not None and args.refine_steps < 0:
        raise UserError(f"--refine-steps must be 0 or more, got {args.refine_steps}")
    try:
        likelihood = Likelihood(args.likelihood)
        refinement = "default"
        chosen = (args.refine_steps, args.arm_grid, args.arm_momentum)
        if args.refine_steps == 0:
            refinement = None
        elif any(value is not None for value in chosen):
            grid = DEFAULT_ARM_GRID if args.arm_grid is None else args.arm_grid
            momentum = DEFAULT_ARM_MOMENTUM if args.arm_momentum is None else args.arm_momentum
            search = None if grid == 0 else ArmSearch(grid=grid, momentum=momentum)
            refinement = Refinement(steps=args.refine_steps or DEFAULT_REFINE_STEPS,
                                    arm_search=search)
    except ValueError as error:
        option = str(error).split(" ", 1)[0].replace("_", "-")
        raise UserError(f"--{option} {str(error).split(' ', 1)[1]}") from None
    return TrackerOptions(likelihood, refinement,
                          args.foreground == "median" and likelihood.needs_edges)
