"""What the commands share: the user-error exception and the checks of their common arguments
(clips given by name or path, seeds, model files, output folders, memory), each raising a
:class:`UserError` that names the argument and what is wrong, before any work is done."""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["MAX_SEED", "UserError", "add_asf_option", "available_memory", "check_clips",
           "check_held_out", "check_json_and_plots",
           "check_memory", "check_prior_file", "check_seed", "fit_mask_file", "format_bytes",
           "load_clip_sources", "output_folder", "pose2sim_cameras", "read_mask_files"]

MAX_SEED = 2**63 - 1
"""The largest seed: JAX keys and NumPy generators take 0 to 2**63 - 1."""


class UserError(Exception):
    """An error caused by the user's input: printed as one line, exit status 2."""


def one_line(error: BaseException | str) -> str:
    """An error's message on one line."""
    return " ".join(str(error).split())


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


def check_seed(seed: int) -> None:
    """``--seed`` must be a whole number from 0 to :data:`MAX_SEED`."""
    if not 0 <= seed <= MAX_SEED:
        raise UserError(f"--seed must be from 0 to {MAX_SEED}, got {seed}")


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
    return folder


def check_asf(asf: Path | None, sources: Sequence) -> None:
    """``--asf`` must be a file, and there must be an ``.amc`` path for it to apply to."""
    if asf is None:
        return
    if not any(not source.from_catalogue and source.file.suffix.lower() == ".amc"
               for source in sources):
        raise UserError(f"--asf {asf}: no .amc file is given by path for it to apply to "
                        f"(catalogue clips keep their own skeleton)")


def load_clip_sources(sources: Sequence, option: str) -> None:
    """Read every clip given by path and check that its rig supplies the upper-body markers;
    catalogue clips are the tested ones and are read when used."""
    from jaxtrack.body.markers import UPPER_BODY_12, MarkerMapError, marker_joint_indices
    from jaxtrack.body.motion import MocapFormatError

    for source in sources:
        if source.from_catalogue:
            continue
        try:
            marker_joint_indices(source.load(), UPPER_BODY_12)
        except (MocapFormatError, MarkerMapError, OSError) as error:
            raise UserError(f"{option} {source.spec}: {one_line(error)}") from None


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


def output_folder(path: Path, option: str) -> Path:
    """The folder an output goes in: it may not exist yet (it is created after every check),
    but what exists of it must be a writable folder. Returns the folder."""
    folder = path.parent if str(path.parent) else Path(".")
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{option} {path}: cannot create folder {folder}, {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{option} {path}: folder {existing} is not writable")
    if path.is_dir():
        raise UserError(f"{option} {path} is a folder; give a file name")
    return folder


def format_bytes(count: float) -> str:
    """``1.5 GB``-style sizes (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(count) < 1000 or unit == "TB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1000
    raise AssertionError("unreachable")


def available_memory() -> int | None:
    """Bytes the run can still allocate: the accelerator's free memory when JAX runs on one,
    else the machine's available memory (``MemAvailable`` of /proc/meminfo, or ``sysconf``);
    None when neither can be read."""
    import jax

    device = jax.devices()[0]
    if device.platform != "cpu":
        stats = device.memory_stats() or {}
        if "bytes_limit" in stats:
            return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0))
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(needed: int, what: str, option: str) -> None:
    """Refuse a run whose estimated memory ``needed`` (bytes) exceeds what is available."""
    available = available_memory()
    if available is not None and needed > available:
        raise UserError(f"{option}: {what} needs about {format_bytes(needed)} of memory but "
                        f"this machine has {format_bytes(available)} available; use fewer")
