"""``--method mixed-state``'s command-line defaults and the other methods' options it refuses,
shared by ``jaxtrack train|evaluate|track --method mixed-state``
(``jaxtrack.cli._train_mixed_state``, ``_evaluate_mixed_state``, ``_track_mixed_state``)."""

from __future__ import annotations

import argparse

from jaxtrack.cli._common import UserError

__all__ = ["BASE_BYTES", "CACHE_NAME", "DEFAULT_BINS", "DEFAULT_LAG", "DEFAULT_PARTICLES",
           "DEFAULT_SIZE", "HISTORY_BYTES", "PIXEL_BYTES", "TRAINING_BACKGROUNDS",
           "refuse_other_methods"]

DEFAULT_PARTICLES = 500
DEFAULT_LAG = 10
DEFAULT_BINS = 16
DEFAULT_SIZE = (640, 480)
TRAINING_BACKGROUNDS = ("photo",)
CACHE_NAME = "posture_cache.npz"
BASE_BYTES = 1.0e9  # JAX, XLA and the compiled scans
HISTORY_BYTES = 3 * 8 * 13
"""Per particle and frame: posture, five parts (x, y), log-weight and ancestor (13 numbers of
8 bytes at most), about three copies live at once (the history, the smoother's traced paths, the
estimates' work arrays)."""
PIXEL_BYTES = 2 * 4 + 1 + 3
"""Per pixel and frame: the nearest-silhouette map (two int16) on the host and on the device,
the silhouette, and the RGB frame."""

_OTHER_METHODS = {
    # option: (default, what to say instead)
    "asf": (None, "mixed-state reads an .amc file with its .asf beside it"),
    "views": (None, "use --azimuths"),
    "active": (200, "it is a GPLVM setting"),
    "cameras": (None, "it is a linear-combination setting"),
    "clusters": (None, "it is a linear-combination setting"),
    "calibration": (None, "it is a linear-combination setting"),
    "skin": (None, "it is a linear-combination setting"),
    "view_selection": (None, "it is a linear-combination setting"),
    "skeleton": (None, "it is a linear-combination setting"),
    "coverage_weight": (None, "it is a setting of the latent tracker's likelihood"),
    "keypoints": (None, "it is read by the latent tracker's likelihood"),
    "keypoint_weight": (None, "it is a setting of the latent tracker's likelihood"),
    "iterations": (None, "it is a linear-combination or GPLVM setting"),
    "prior_optimiser": ("bfgs", "it is a GPLVM setting"),
    "baseline_dynamics": ("training", "it is a CONDENSATION/MHT setting"),
    "allow_same_subject": (False, "the clip split is jaxtrack.experiments.mixed_state's"),
    "likelihood": ("limbs+edges", "the part likelihood is Kwatra et al.'s eq. 4-7"),
    "foreground": ("median", "silhouettes come from the median background (jaxtrack track "
                   "takes --masks)"),
    "refine_steps": (None, "it is a refinement of the latent tracker's pose"),
    "arm_grid": (None, "it is a refinement of the latent tracker's pose"),
    "arm_momentum": (None, "it is a refinement of the latent tracker's pose"),
    "init": ("face", "the tracker starts from the first frame's silhouette"),
}
_COMMAND_DEFAULTS = {"train": {"views": 5, "iterations": 3}, "evaluate": {"views": 2}}


_COMMAND_TAKES = {"evaluate": {"cameras"}, "track": {"keypoints"}}
"""Options of :data:`_OTHER_METHODS` a command does take for --method mixed-state
(``evaluate --cameras``: the test clips also through these Pose2Sim cameras; ``track
--keypoints``: the detections as part hypotheses)."""


def refuse_other_methods(args: argparse.Namespace, command: str) -> None:
    """Options of the other methods, set away from their defaults, are refused (not ignored)."""
    defaults = _COMMAND_DEFAULTS.get(command, {})
    for name, (default, instead) in _OTHER_METHODS.items():
        if not hasattr(args, name) or name in _COMMAND_TAKES.get(command, ()):
            continue
        default = defaults.get(name, default)
        if getattr(args, name) != default:
            option = "--" + name.replace("_", "-")
            raise UserError(f"{option} does not apply to --method mixed-state ({instead})")
