"""``jaxtrack train --method mixed-state``: Kwatra, Bobick & Johnson's posture model (a
discrete posture and five body parts from silhouettes; ``docs/mixed-state.md``).

:func:`train` renders the training clips from several azimuths, labels their postures and fits
the posture model (:func:`jaxtrack.experiments.mixed_state.train`), saved atomically; the
``--laid-down`` clips are also laid on their back and front as lying training data. Without
``--clips`` it trains on the clips of the bundled posture model (``jaxtrack.data.models``, all
bundled with the package; the experiment's own set,
:data:`jaxtrack.experiments.mixed_state.TRAINING_CLIPS`, adds DeepMimic's LGPL clips). The
options shared by ``evaluate`` (``jaxtrack.cli._evaluate_mixed_state``) and ``track``
(``jaxtrack.cli._track_mixed_state``) are checked here. Every argument is checked first; a bad
one is a one-line :class:`UserError` naming it, raised before anything is computed or written.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import time
from pathlib import Path

from jaxtrack.cli._clip_checks import load_clip_sources
from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_clips,
    check_seed,
    one_line,
    output_folder,
)
from jaxtrack.cli._mixed_state import (
    DEFAULT_BINS,
    DEFAULT_SIZE,
    TRAINING_BACKGROUNDS,
    refuse_other_methods,
)

__all__ = ["azimuth_radians", "check_clip_files", "fit_posture_model", "matches",
           "model_summary", "parse_image_size", "read_saved_model", "refuse_test_subjects",
           "train", "training_settings", "write_json"]


def parse_image_size(text: str | None, option: str = "--size") -> tuple[int, int]:
    if text is None:
        return DEFAULT_SIZE
    width, separator, height = text.lower().partition("x")
    try:
        size = (int(width), int(height))
    except ValueError:
        size = None
    if not separator or size is None or min(size) < 32 or max(size) > 4096:
        raise UserError(f"{option} must be WIDTHxHEIGHT with each side from 32 to 4096 pixels, "
                        f"got {text!r}")
    return size


def azimuth_radians(values: list[float] | None) -> tuple[float, ...]:
    """Radians from ``--azimuths`` degrees (the experiment's five views by default)."""
    from jaxtrack.experiments.mixed_state import VIEW_AZIMUTHS

    if values is None:
        return tuple(float(value) for value in VIEW_AZIMUTHS)
    bad = [value for value in values if not (math.isfinite(value) and -180 <= value <= 180)]
    if bad:
        raise UserError(f"--azimuths must be degrees from -180 to 180, got {bad[0]}")
    return tuple(math.radians(value) for value in dict.fromkeys(values))


def refuse_test_subjects(clips: list[str], sources: list, option: str) -> None:
    """A posture model is never trained on a test subject (``jaxtrack.data.splits``); clips of
    no known subject (a user's own files) are not checked."""
    from jaxtrack.data.splits import UnknownSubjectError, split_of, subject_of

    for clip, source in zip(clips, sources, strict=True):
        # a catalogue file given by its path is known by its folder and name
        for name in (clip, f"{source.file.parent.name}/{source.file.name}"):
            try:
                subject = subject_of(name)
            except UnknownSubjectError:
                continue
            if split_of(name) == "test":
                raise UserError(f"{option} {clip}: subject {subject} is a test subject "
                                f"(jaxtrack.data.splits); train on training or validation "
                                f"subjects only")
            break


def check_clip_files(sources: list, option: str) -> None:
    """Clips given by path must read and map onto the renderer's HumanEva-15 markers (the
    posture labels need the legs); catalogue clips are the tested ones."""
    from jaxtrack.body.markers import HUMANEVA_15

    load_clip_sources(sources, option, HUMANEVA_15)


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def training_settings(clips: list[str], sources: list, azimuths, size, bins, max_frames,
                       seed, laid_down: list[str] | None = None,
                       laid_down_sources: list | None = None) -> dict:
    """What a posture model is trained from, as its saved description holds it: a saved model
    with these values is reused (``laid_down``: clips also laid on their back and front, with
    their sources, recorded only when given)."""
    from jaxtrack.experiments import mixed_state as ms

    settings = {"clips": list(clips), "azimuths": [float(value) for value in azimuths],
                "backgrounds": list(TRAINING_BACKGROUNDS), "image_size": list(size),
                "num_bins": bins, "max_frames": max_frames, "seed": seed,
                "pose2sim_cameras": list(ms.TRAINING_POSE2SIM_CAMERAS),
                "components": ms.DEFAULT_COMPONENTS, "covariance": ms.DEFAULT_COVARIANCE,
                "regularisation": ms.DEFAULT_REGULARISATION,
                "clip_sha256": [_file_digest(source.file) for source in sources]}
    if laid_down:
        settings["laid_down"] = list(laid_down)
        settings["laid_down_sha256"] = [_file_digest(source.file)
                                        for source in laid_down_sources]
    return json.loads(json.dumps(settings))


def matches(description: dict, settings: dict) -> bool:
    return all(description.get(name) == value for name, value in settings.items())


def read_saved_model(path: Path, what: str, remedy: str):
    """An existing posture-model file the command would reuse, or None when there is none."""
    from jaxtrack.priors.postures import PostureFormatError, load_posture_model

    if path.exists() and not path.is_file():
        raise UserError(f"{what} {path} is a folder, not a posture model; {remedy}")
    if not path.is_file():
        return None
    try:
        return load_posture_model(path)
    except (PostureFormatError, OSError) as error:
        reason = one_line(error).removeprefix(f"{path}: ").removeprefix(f"{path}:")
        raise UserError(f"{what} {path} is damaged or not a posture model ({reason}); "
                        f"{remedy}") from None


def fit_posture_model(settings: dict, option: str, frames_option: str):
    """Render, label and fit; a posture the clips never show is the user's to fix."""
    from jaxtrack.experiments.mixed_state import train as train_model

    begin = time.perf_counter()
    extra = {}
    if settings.get("laid_down"):
        train_model, extra = _train_with_laid_down, {"laid_down": settings["laid_down"]}
    try:
        model, description = train_model(
            settings["clips"], azimuths=settings["azimuths"],
            backgrounds=settings["backgrounds"], image_size=tuple(settings["image_size"]),
            num_bins=settings["num_bins"], max_frames=settings["max_frames"],
            seed=settings["seed"], pose2sim_cameras=settings["pose2sim_cameras"],
            components=settings["components"], covariance=settings["covariance"],
            regularisation=settings["regularisation"], **extra)
    except ValueError as error:
        if "training frames" not in str(error):
            raise
        more = " (or lying: --laid-down)" if "lying" in str(error) else ""
        raise UserError(f"{option}: {one_line(error)}{more}; or raise {frames_option}"
                        ) from None
    description = description | settings | {"seconds": time.perf_counter() - begin}
    return model, description


LAID_DOWN_SEEDS = {"up": 1000, "down": 2000}
"""Render seeds added to ``--seed`` for the laid-down clips (other background crops than the
standing clips')."""


def _train_with_laid_down(clips, *, laid_down, azimuths, backgrounds, image_size, num_bins,
                          max_frames, seed, pose2sim_cameras, **fitting):
    """:func:`jaxtrack.experiments.mixed_state.train` with the ``laid_down`` clips also laid on
    their back and on their front (:meth:`jaxtrack.body.motion.Motion.laid_down`), rendered
    from the same views and labelled by the same rule: lying training data from people who
    were filmed standing."""
    from jaxtrack.experiments import mixed_state as ms

    features, labels, rendered = ms.training_features(
        clips, azimuths=azimuths, backgrounds=backgrounds, image_size=image_size,
        num_bins=num_bins, max_frames=max_frames, seed=seed, pose2sim_cameras=pose2sim_cameras)
    for face, offset in LAID_DOWN_SEEDS.items():
        for sequence in ms.render_sequences(laid_down, azimuths, backgrounds, image_size,
                                            max_frames, seed + offset, pose2sim_cameras,
                                            laid_down=face):
            values, names = ms.labelled_features(sequence, num_bins)
            features.append(values)
            labels.append(names)
    return ms.fit(features, labels, **fitting, **rendered, laid_down=list(laid_down))


def model_summary(description: dict) -> str:
    counts = description.get("label_counts", {})
    shown = ", ".join(f"{name} {count}" for name, count in counts.items())
    return (f"posture model of {description.get('frames', '?')} frames ({shown}) from "
            f"{len(description.get('clips', []))} clips x {len(description.get('azimuths', []))} "
            f"views at {'x'.join(map(str, description.get('image_size', [])))}, "
            f"{description.get('num_bins')} bins")


def train(args: argparse.Namespace) -> int:
    """``jaxtrack train --method mixed-state``: fit and save the posture model."""
    from jaxtrack.data.models import RECIPES

    refuse_other_methods(args, "train")
    bundled = RECIPES["postures"]  # without --clips: what the bundled posture model learnt from
    clips = list(bundled.clips) if args.clips is None else list(args.clips)
    if args.clips is None and getattr(args, "laid_down", None) is None:
        args.laid_down = list(bundled.laid_down)
    sources = check_clips(clips, "--clips")
    refuse_test_subjects(clips, sources, "--clips")
    laid_down = list(getattr(args, "laid_down", None) or [])
    laid_sources = check_clips(laid_down, "--laid-down") if laid_down else []
    refuse_test_subjects(laid_down, laid_sources, "--laid-down")
    if args.out.suffix != ".npz":
        raise UserError(f"--out {args.out}: must be a .npz path")
    folder = output_folder(args.out, "--out")
    check_seed(args.seed)
    max_frames = at_least(args.max_frames, 2, "--max-frames", None)
    bins = at_least(args.bins, 1, "--bins", DEFAULT_BINS)
    azimuths = azimuth_radians(args.azimuths)
    size = parse_image_size(args.size)
    existing = read_saved_model(args.out, "--out", "delete it or choose another --out")
    check_clip_files(sources, "--clips")
    if laid_down:
        check_clip_files(laid_sources, "--laid-down")
    settings = training_settings(clips, sources, azimuths, size, bins, max_frames, args.seed,
                                 laid_down, laid_sources)
    if existing is not None and matches(existing.description, settings):
        print(f"{model_summary(existing.description)}: {args.out} already holds it (reused)")
        return 0
    from jaxtrack.priors.postures import save_posture_model

    model, description = fit_posture_model(settings, "--clips", "--max-frames")
    folder.mkdir(parents=True, exist_ok=True)
    save_posture_model(args.out, model, description=description)
    print(f"{model_summary(description)} -> {args.out} ({description['seconds']:.1f} s)")
    return 0


def write_json(path: Path, value) -> Path:
    from jaxtrack._files import write_json_atomically

    try:
        return write_json_atomically(path, value)
    except OSError as error:
        raise UserError(f"cannot write {path}: {one_line(error)}") from None
