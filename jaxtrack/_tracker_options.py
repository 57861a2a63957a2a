"""The latent tracker's command-line options, shared by ``jaxtrack evaluate`` and ``jaxtrack
track``: the likelihood and its foreground term, the full-state refinement and its arm
search."""

from __future__ import annotations

import argparse

__all__ = ["add_tracker_options", "check_tracker_options"]


def add_tracker_options(parser: argparse.ArgumentParser) -> None:
    """``--likelihood``, ``--refine-steps``, ``--arm-grid``, ``--foreground`` and
    ``--arm-momentum`` (None: the tracker's defaults)."""
    parser.add_argument("--likelihood", choices=("limbs+edges", "limbs", "markers"),
                        default="limbs+edges", help="limb strips and their edges (default), "
                        "limb strips alone, or the paper's patches at the markers")
    parser.add_argument("--refine-steps", type=int, default=None, metavar="N",
                        help="latent tracker: Gauss-Newton steps of the full-state refinement "
                        "of its reported pose (default 10, none with --likelihood markers; 0: "
                        "the paper's estimate)")
    parser.add_argument("--arm-grid", type=int, default=None, metavar="N",
                        help="latent tracker: angle offsets per arm joint of the arm search "
                        "that starts each refinement (odd; default 7; 0: no search)")
    parser.add_argument("--foreground", choices=("median", "none"), default="median",
                        help="limbs+edges: also score the arm strips by whether their centre "
                        "lines differ from the video's median background, for a static camera "
                        "(default median; none: off)")
    parser.add_argument("--arm-momentum", type=float, default=None, metavar="M",
                        help="latent tracker: the arm search also searches about the arm "
                        "angles moved on by M times their change over the last frame (0 to 1; "
                        "default 1; 0: about the carried arm alone)")


def check_tracker_options(args: argparse.Namespace, user_error: type[Exception]) -> None:
    """Reject a negative ``--refine-steps``, an even or negative ``--arm-grid`` or an
    ``--arm-momentum`` outside [0, 1]."""
    if args.refine_steps is not None and args.refine_steps < 0:
        raise user_error(f"--refine-steps must be 0 or more, got {args.refine_steps}")
    if args.arm_grid not in (None, 0) and (args.arm_grid < 0 or args.arm_grid % 2 == 0):
        raise user_error(f"--arm-grid must be 0 or odd, got {args.arm_grid}")
    if args.arm_momentum is not None and not 0 <= args.arm_momentum <= 1:
        raise user_error(f"--arm-momentum must be in [0, 1], got {args.arm_momentum}")
