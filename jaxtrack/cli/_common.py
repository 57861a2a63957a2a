"""What the commands share: the user-error exception, the parser that reports a bad argument in
one line, the parse-time types of numeric arguments (seeds included), and the checks of their
common arguments (clips given by name or path, model files, output paths, memory), each raising
a :class:`UserError` that names the argument and what is wrong, before any work is done; and
:func:`outputs_or_nothing`, which removes what a failed or interrupted command wrote."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

__all__ = ["MAX_SEED", "OneLineParser", "UserError", "add_asf_option", "available_memory",
           "check_clips", "check_held_out", "check_json_and_plots", "check_memory",
           "check_prior_file", "check_seed", "fit_mask_file", "format_bytes", "integer",
           "load_clip_sources", "output_directory", "output_folder", "outputs_or_nothing",
           "pose2sim_cameras", "read_mask_files", "real", "seed"]

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


def check_seed(value: int) -> None:
    """``--seed`` must be a whole number from 0 to :data:`MAX_SEED` (:data:`seed` checks it at
    parse time; this, for a value set otherwise)."""
    if not 0 <= value <= MAX_SEED:
        raise UserError(f"--seed must be from 0 to {MAX_SEED} (a 32-bit seed: jax.random.key "
                        f"keeps only the low 32 bits), got {value}")


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


def load_clip_sources(sources: Sequence, option: str) -> None:
    """Read every clip given by path and check that its rig supplies the upper-body markers
    and that it has frames enough to train on (:func:`check_clip_frames`); catalogue clips are
    the tested ones and are read when used."""
    from jaxtrack.body.markers import UPPER_BODY_12, MarkerMapError, marker_joint_indices
    from jaxtrack.body.motion import MocapFormatError

    for source in sources:
        if source.from_catalogue:
            continue
        try:
            motion = source.load()
            marker_joint_indices(motion, UPPER_BODY_12)
        except (MocapFormatError, MarkerMapError, OSError) as error:
            raise UserError(f"{option} {source.spec}: {one_line(error)}") from None
        check_clip_frames(motion, source.spec, option)


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


def _probe(folder: Path) -> str | None:
    """Why no file can be created in ``folder`` (None when one can): a probe file is created
    and removed, which sees what ``os.access`` does not (``/proc``, a read-only mount, a root
    user's view of a folder without write permission)."""
    try:
        handle, name = tempfile.mkstemp(dir=folder, prefix=".jaxtrack-probe-")
    except OSError as error:
        return error.strerror or type(error).__name__
    os.close(handle)
    os.unlink(name)
    return None


def _writable(folder: Path, path: Path, option: str) -> None:
    """``folder`` may not exist yet (it is created after every check), but what exists of it
    must be a folder in which a file can be created."""
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{option} {path}: cannot create folder {folder}, {existing} is a file")
    reason = _probe(existing)
    if reason is not None:
        raise UserError(f"{option} {path}: cannot write into folder {existing} ({reason})")


def output_folder(path: Path, option: str) -> Path:
    """The folder an output file goes in: it may not exist yet (it is created after every
    check), but what exists of it must be a folder a file can be created in (a probe file is
    created and removed there). Returns the folder."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    _writable(folder, path, option)
    if path.is_dir():
        raise UserError(f"{option} {path} is a folder; give a file name")
    return folder


def output_directory(folder: Path, option: str) -> Path:
    """An output folder (``--out DIR``): a folder, or nothing yet below a folder that files can
    be created in (probed). Returns the folder."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"{option} {folder} is a file; give a folder")
    _writable(folder, folder, option)
    return folder


@contextlib.contextmanager
def outputs_or_nothing(*folders: Path) -> Iterator[list]:
    """Create ``folders``; yield a list to which the body adds each file it writes. If the body
    fails or is interrupted (Ctrl-C), those files and the folders created here (when left
    empty) are removed, so that a command leaves all its outputs or none. (A file being written
    atomically, ``jaxtrack._files.write_atomically``, removes its own temporary file.)"""
    created, written = [], []
    for folder in folders:
        missing, existing = [], Path(folder)
        while not existing.exists():
            missing.append(existing)
            existing = existing.parent
        Path(folder).mkdir(parents=True, exist_ok=True)
        created.extend(missing)
    created.sort(key=lambda folder: len(folder.parts), reverse=True)  # deepest first
    try:
        yield written
    except BaseException:
        for path in written:
            Path(path).unlink(missing_ok=True)
        for folder in created:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


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
