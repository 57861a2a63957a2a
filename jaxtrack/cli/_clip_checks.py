"""The checks of the commands' clip arguments (clips given by catalogue name or by path, with
their ``--asf``; training and test clips kept apart; their frames) and of ``--json`` with
``--plots``, each raising a :class:`UserError` that names the argument and what is wrong."""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from jaxtrack.cli._common import UserError, one_line
from jaxtrack.cli._outputs import output_directory, output_folder

__all__ = ["TRAINING_FPS", "check_asf", "check_clip_frames", "check_clips", "check_held_out",
           "check_json_and_plots", "load_clip_sources"]


def _looks_like_path(spec: str) -> bool:
    # a name with a file's extension or a path's start: say the file is missing, not the name
    return (Path(spec).suffix.lower() in (".bvh", ".amc", ".asf")
            or spec.startswith((".", "~", os.sep)))


def check_clips(names: Iterable[str], option: str, asf: Path | None = None) -> list:
    """Resolve clips given as catalogue names or as paths to ``.bvh``/``.amc`` files.

    Returns:
        the :class:`jaxtrack.data.ClipSource` of each, in order.

    Raises:
        UserError: naming ``option`` and every unknown name (with the known ones), or the first
            path that is missing, not a motion file, or an ``.amc`` whose skeleton is neither
            beside it nor given with ``--asf``.
    """
    from jaxtrack.body.motion import MissingSkeletonError
    from jaxtrack.data import list_clips, resolve_clip

    if asf is not None and not asf.is_file():
        raise UserError(f"--asf {asf}: no such file")
    sources, unknown = [], []
    for name in names:
        try:
            sources.append(resolve_clip(name, asf=asf))
        except MissingSkeletonError as error:
            looked = ", ".join(path.name for path in error.tried)
            raise UserError(f"{option} {name}: no ASF skeleton beside it (looked for {looked} "
                            f"and for a single .asf in its folder); give the skeleton with "
                            f"--asf FILE.asf") from None
        except FileNotFoundError as error:
            if not _looks_like_path(name):
                unknown.append(name)
                continue
            raise UserError(f"{option} {name}: {one_line(error)}") from None
        except ValueError as error:  # a file that is not a motion, or a name without a folder
            if "/" not in name and not Path(name).is_file():
                unknown.append(name)
                continue
            raise UserError(f"{option} {name}: {one_line(error)}") from None
    if unknown:
        raise UserError(f"{option}: unknown clip(s) {', '.join(unknown)} (neither a file nor a "
                        f"catalogue name); known clips: {', '.join(list_clips())}")
    return sources


def check_held_out(train_sources: Sequence, test_sources: Sequence) -> None:
    """No ``--test`` clip may be one of the ``--train`` clips (the same file)."""
    trained = {source.file.resolve() for source in train_sources}
    overlap = [source.spec for source in test_sources if source.file.resolve() in trained]
    if overlap:
        raise UserError(f"--test clips must be held out, but {', '.join(overlap)} is also in "
                        f"--train")


def check_json_and_plots(args: argparse.Namespace) -> Path:
    """``--json`` must be a ``.json`` file that can be written, ``--plots`` (if given) a folder
    or nothing yet. Returns the folder of ``--json``."""
    if args.json.suffix != ".json":
        raise UserError(f"--json {args.json}: must be a .json path")
    folder = output_folder(args.json, "--json")
    if args.plots is not None and args.plots.exists() and not args.plots.is_dir():
        raise UserError(f"--plots {args.plots} is a file, not a folder")
    if args.plots is not None:
        output_directory(args.plots, "--plots")
    return folder


def check_asf(asf: Path | None, sources: Sequence) -> None:
    """``--asf`` must be a file, and there must be an ``.amc`` path for it to apply to."""
    if asf is None:
        return
    if not any(not source.from_catalogue and source.file.suffix.lower() == ".amc"
               for source in sources):
        raise UserError(f"--asf {asf}: no .amc file is given by path for it to apply to "
                        f"(catalogue clips keep their own skeleton)")


TRAINING_FPS = 30.0
"""The rate training takes a clip's frames at (``jaxtrack.priors.train.train_prior``'s and the
experiments' default)."""


def check_clip_frames(motion, spec: str, option: str, fps: float = TRAINING_FPS) -> None:
    """A training clip must give at least two frames at ``fps`` (the prior's dynamics are
    learned from consecutive frames): refused in one line naming the file and how many frames
    it needs."""
    step = max(motion.fps / fps, 1.0)
    taken = len(range(0, math.ceil(max(motion.num_frames - 0.5, 0) / step)))
    if taken < 2:
        needed = math.floor(step + 0.5) + 1
        raise UserError(f"{option} {spec}: {motion.num_frames} frame(s) at {motion.fps:g} fps "
                        f"give {taken} at {fps:g} fps, the rate clips are trained on; the "
                        f"motion's dynamics need two consecutive frames: give at least "
                        f"{needed} frames")


def load_clip_sources(sources: Sequence, option: str, markers: Sequence[str] | None = None
                      ) -> None:
    """Read every clip given by path and check that its rig supplies ``markers`` (default the
    upper-body markers) and that it has frames enough to train on (:func:`check_clip_frames`);
    catalogue clips are the tested ones and are read when used."""
    from jaxtrack.body.markers import UPPER_BODY_12, MarkerMapError, marker_joint_indices
    from jaxtrack.body.motion import MocapFormatError

    markers = UPPER_BODY_12 if markers is None else markers
    for source in sources:
        if source.from_catalogue:
            continue
        try:
            motion = source.load()
            marker_joint_indices(motion, markers)
        except (MocapFormatError, MarkerMapError, OSError) as error:
            raise UserError(f"{option} {source.spec}: {one_line(error)}") from None
        check_clip_frames(motion, source.spec, option)
