"""What the commands share: the user-error exception, the parser that reports a bad argument in
one line, the parse-time types of numeric arguments (seeds included), and the checks of their
common arguments (clips given by name or path, model files, output paths, memory), each raising
a :class:`UserError` that names the argument and what is wrong, before any work is done; and
:func:`outputs_or_nothing`, which removes what a failed or interrupted command wrote."""

from __future__ import annotations

import argparse
import contextlib
import math
import re
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

__all__ = ["ArgumentsError", "MAX_SEED", "OneLineParser", "TRAINING_FPS", "UserError",
           "add_asf_option", "at_least", "available_memory", "check_asf", "check_clip_frames",
           "check_clips", "check_held_out", "check_json_and_plots", "check_memory",
           "check_prior_file", "check_seed", "finite_json", "fit_mask_file", "format_bytes",
           "integer", "load_clip_sources", "model_or_default", "one_line", "output_directory",
           "output_folder", "outputs_or_nothing", "pipeline_errors", "pose2sim_cameras",
           "read_mask_files", "real", "seed"]

MAX_SEED = 2**32 - 1
"""The largest seed. ``jax.random.key`` keeps only a seed's low 32 bits without 64-bit mode
(``key(2**32 + 5) == key(5)``) and overflows above 2**63, so seeds are 0 to 2**32 - 1."""


class UserError(Exception):
    """An error caused by the user's input: printed as one line, exit status 2."""


class ArgumentsError(UserError):
    """A command line argparse refused; ``prog`` names the command (``jaxtrack track``)."""

    def __init__(self, prog: str, message: str):
        super().__init__(message)
        self.prog = prog


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (no usage block): raised as
    :class:`ArgumentsError` for ``jaxtrack.cli.main`` to print, exit status 2. A value refused
    by a type of this module reads ``--seed must be ...``."""

    def error(self, message: str):
        found = re.match(r"argument (-[\w-]+)(?:/-[\w-]+)?: (must .*)$", message, re.DOTALL)
        if found:
            message = f"{found.group(1)} {found.group(2)}"
        raise ArgumentsError(self.prog, f"{one_line(message)} (see {self.prog} --help)")


def integer(minimum: int | None = None, maximum: int | None = None, *,
            reason: str = "") -> Callable[[str], int]:
    """An argparse ``type``: a whole number from ``minimum`` to ``maximum`` (either may be
    None), refused at parse time; ``reason`` (e.g. ``"(frame 0 starts the tracker)"``) follows
    the range in the message."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
        if (minimum is not None and value < minimum) or (maximum is not None
                                                         and value > maximum):
            if maximum is None:
                bounds = f"at least {minimum}"
            elif minimum is None:
                bounds = f"at most {maximum}"
            else:
                bounds = f"from {minimum} to {maximum}"
            raise argparse.ArgumentTypeError(
                f"must be {bounds}{' ' + reason if reason else ''}, got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def real(minimum: float | None = None, maximum: float | None = None, *,
         positive: bool = False, unit: str = "") -> Callable[[str], float]:
    """An argparse ``type``: a finite number from ``minimum`` to ``maximum`` (above 0 with
    ``positive``), refused at parse time with the text as given."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        low = minimum is None or value >= minimum
        high = maximum is None or value <= maximum
        if not (math.isfinite(value) and low and high and (value > 0 or not positive)):
            if minimum is not None and maximum is not None:
                bounds = f"between {minimum:g} and {maximum:g}{unit}"
            elif positive:
                bounds = f"a positive{unit or ' number'}"
            elif minimum is not None:
                bounds = f"a number of at least {minimum:g}{unit}"
            else:
                bounds = f"a finite number{unit}"
            raise argparse.ArgumentTypeError(f"must be {bounds}, got {text}")
        return value

    parse.__name__ = "number"
    return parse


seed = integer(0, MAX_SEED, reason="(a 32-bit seed: jax.random.key keeps only the low 32 "
               "bits)")
"""The argparse ``type`` of every ``--seed``: 0 to :data:`MAX_SEED`."""


def one_line(error: BaseException | str) -> str:
    """An error's message on one line."""
    return " ".join(str(error).split())


@contextlib.contextmanager
def pipeline_errors(other: str) -> Iterator[None]:
    """Around :func:`jaxtrack.experiments.pipeline.track_video`: a video that cannot be read,
    a mask file that does not fit, or inputs that disagree become one-line errors
    (:class:`UserError`; ``other`` names the last kind's source, e.g. ``--video V``)."""
    from jaxtrack.vision import MaskFileError, VideoError

    try:
        yield
    except VideoError as error:
        raise UserError(f"--video: {one_line(error)}") from None
    except MaskFileError as error:
        raise UserError(f"--masks {one_line(error)}") from None
    except ValueError as error:
        raise UserError(f"{other}: {one_line(error)}") from None


def at_least(value: int | None, minimum: int, option: str, default):
    """``value`` (``default`` when None), refused with a one-line error below ``minimum``."""
    if value is None:
        return default
    if value < minimum:
        raise UserError(f"{option} must be at least {minimum}, got {value}")
    return value


def finite_json(value):
    """``value`` with every non-finite float replaced by None (JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_json(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [finite_json(item) for item in value]
    return value


def add_asf_option(parser: argparse.ArgumentParser) -> None:
    """``--asf``: the skeleton of the ``.amc`` files given by path."""
    parser.add_argument("--asf", type=Path, default=None, metavar="SKELETON.asf",
                        help="Acclaim skeleton of every .amc file given by path (default: the "
                             ".asf beside each, named like 07.asf for 07_01.amc, or with the "
                             "same stem, or the only .asf in its folder); catalogue clips keep "
                             "their own")


def read_mask_files(paths: Sequence[Path] | None, videos: int) -> list:
    """``--masks``: one ``(frames, height, width)`` bool array per video, or None for each
    without the option (:func:`jaxtrack.vision.read_masks`); refused in one line."""
    from jaxtrack.vision import MaskFileError, read_masks

    if paths is None:
        return [None] * videos
    if len(paths) != videos:
        raise UserError(f"--masks: one file per --video, got {len(paths)} for {videos}")
    try:
        return [read_masks(path) for path in paths]
    except MaskFileError as error:
        raise UserError(f"--masks {one_line(error)}") from None


def fit_mask_file(masks, path: Path, frame_indices, size: tuple[int, int]):
    """The masks of one ``--masks`` file for the tracked ``frame_indices`` at ``size``
    ``(width, height)`` (:func:`jaxtrack.vision.masks_for_frames`); refused in one line."""
    from jaxtrack.vision import MaskFileError, masks_for_frames

    try:
        return masks_for_frames(masks, frame_indices, size, name=str(path))
    except MaskFileError as error:
        raise UserError(f"--masks {one_line(error)}") from None


POSE2SIM_CAMERAS = 4
"""The cameras of the bundled Pose2Sim calibration."""


def pose2sim_cameras(cameras: Sequence[int] | None, default: tuple[int, ...],
                     option: str = "--cameras") -> tuple[int, ...]:
    """``option`` (``--cameras``): distinct Pose2Sim camera indices (``default`` without the
    option); refused in one line."""
    if cameras is None:
        return default
    bad = [camera for camera in cameras if not 0 <= camera < POSE2SIM_CAMERAS]
    if bad:
        raise UserError(f"{option} must be Pose2Sim camera indices 0-{POSE2SIM_CAMERAS - 1}, "
                        f"got {', '.join(map(str, bad))}")
    if len(set(cameras)) != len(cameras):
        raise UserError(f"{option} names a camera twice: {' '.join(map(str, cameras))}")
    return tuple(cameras)


def read_calibration(path: Path) -> list:
    """``--calibration``'s cameras (Z up): a Pose2Sim ``.toml`` or a Qualisys ``.qca.txt``, or a
    one-line :class:`UserError` naming the file."""
    from jaxtrack.body import read_qca
    from jaxtrack.vision.triangulation import CalibrationFileError, read_pose2sim_calibration

    if not path.is_file():
        raise UserError(f"--calibration {path}: no such file")
    try:
        return (read_pose2sim_calibration(path) if path.suffix == ".toml" else read_qca(path))
    except (CalibrationFileError, ValueError, KeyError, OSError) as error:
        raise UserError(f"--calibration {path}: {one_line(error)} (a Pose2Sim .toml or a "
                        f"Qualisys .qca.txt)") from None


def check_camera_indices(chosen: Sequence[int], count: int) -> None:
    """``--cameras``: distinct indices of ``--calibration``'s ``count`` cameras, or a one-line
    :class:`UserError`."""
    if any(not 0 <= index < count for index in chosen) or len(set(chosen)) != len(chosen):
        raise UserError(f"--cameras must be distinct indices 0-{count - 1} of the {count} "
                        f"cameras of --calibration, got {' '.join(map(str, chosen))}")


def check_seed(value: int) -> None:
    """``--seed`` must be a whole number from 0 to :data:`MAX_SEED` (:data:`seed` checks it at
    parse time; this, for a value set otherwise)."""
    if not 0 <= value <= MAX_SEED:
        raise UserError(f"--seed must be from 0 to {MAX_SEED} (a 32-bit seed: jax.random.key "
                        f"keeps only the low 32 bits), got {value}")


def model_or_default(model: Path | None, method: str) -> Path:
    """``--model``, or without it the model bundled with jaxtrack for ``method``
    (:func:`jaxtrack.data.models.default_model`); a one-line error when the package has none."""
    if model is not None:
        return model
    from jaxtrack.data.models import default_model

    try:
        return default_model(method)
    except FileNotFoundError as error:
        raise UserError(f"--model not given and {one_line(error)}") from None


def check_prior_file(path: Path, what: str, remedy: str) -> None:
    """An existing model file that the command would read must be a readable trained prior."""
    from jaxtrack.priors.gplvm import GPLVMFormatError
    from jaxtrack.priors.train import load_prior

    if path.exists() and not path.is_file():
        raise UserError(f"{what} {path} is a folder, not a model file; {remedy}")
    if not path.is_file():
        return
    try:
        load_prior(path)
    except (GPLVMFormatError, OSError) as error:
        reason = one_line(error)
        reason = reason.removeprefix(f"{path}: ").removeprefix(f"{path}:")
        raise UserError(f"{what} {path} is damaged or not a trained prior ({reason}); "
                        f"{remedy}") from None


# at the end: these modules import UserError from here
from jaxtrack.cli._clip_checks import (  # noqa: E402
    TRAINING_FPS,
    check_asf,
    check_clip_frames,
    check_clips,
    check_held_out,
    check_json_and_plots,
    load_clip_sources,
)
from jaxtrack.cli._outputs import (  # noqa: E402
    available_memory,
    check_memory,
    format_bytes,
    output_directory,
    output_folder,
    outputs_or_nothing,
)
