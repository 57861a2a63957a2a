"""``--method mixed-state`` of ``jaxtrack train | evaluate | track``: Kwatra, Bobick & Johnson's
mixed-state tracker (a discrete posture and five body parts from silhouettes;
``docs/mixed-state.md``).

- :func:`train` renders the training clips from several azimuths, labels their postures and
  fits the posture model (:func:`jaxtrack.experiments.mixed_state.train`), saved atomically.
- :func:`evaluate` trains (cached beside ``--json`` as ``posture_cache.npz``), renders the test
  clips, filters, smooths and scores them (:func:`jaxtrack.experiments.mixed_state.evaluate`):
  the paper's Table 1 on stdout, its Fig. 2/4 and the smoothed posture confusion with
  ``--plots``.
- :func:`track` follows one video: silhouettes by background subtraction against the video's
  median background, filter and whole-sequence smoother, then ``DIR/overlay.mp4`` and
  ``DIR/track.json`` (the JSON last).

Every argument is checked first; a bad one is a one-line :class:`UserError` naming it, raised
before anything is computed or written. Files are written atomically.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import time
from pathlib import Path

from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_clip_frames,
    check_clips,
    check_held_out,
    check_json_and_plots,
    check_memory,
    check_seed,
    finite_json,
    fit_mask_file,
    one_line,
    output_directory,
    output_folder,
    outputs_or_nothing,
    pose2sim_cameras,
    read_mask_files,
)

__all__ = ["evaluate", "track", "train"]

DEFAULT_PARTICLES = 500
DEFAULT_LAG = 10
DEFAULT_BINS = 16
DEFAULT_SIZE = (640, 480)
TRAINING_BACKGROUNDS = ("photo",)
CACHE_NAME = "posture_cache.npz"
_BASE_BYTES = 1.0e9  # JAX, XLA and the compiled scans
_HISTORY_BYTES = 3 * 8 * 13
"""Per particle and frame: posture, five parts (x, y), log-weight and ancestor (13 numbers of
8 bytes at most), about three copies live at once (the history, the smoother's traced paths, the
estimates' work arrays)."""
_PIXEL_BYTES = 2 * 4 + 1 + 3
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


_COMMAND_TAKES = {"evaluate": {"cameras"}}
"""Options of :data:`_OTHER_METHODS` a command does take for --method mixed-state
(``evaluate --cameras``: the test clips also through these Pose2Sim cameras)."""


def _refuse_other_methods(args: argparse.Namespace, command: str) -> None:
    """Options of the other methods, set away from their defaults, are refused (not ignored)."""
    defaults = _COMMAND_DEFAULTS.get(command, {})
    for name, (default, instead) in _OTHER_METHODS.items():
        if not hasattr(args, name) or name in _COMMAND_TAKES.get(command, ()):
            continue
        default = defaults.get(name, default)
        if getattr(args, name) != default:
            option = "--" + name.replace("_", "-")
            raise UserError(f"{option} does not apply to --method mixed-state ({instead})")


def _image_size(text: str | None, option: str = "--size") -> tuple[int, int]:
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


def _azimuths(values: list[float] | None) -> tuple[float, ...]:
    """Radians from ``--azimuths`` degrees (the experiment's five views by default)."""
    from jaxtrack.experiments.mixed_state import VIEW_AZIMUTHS

    if values is None:
        return tuple(float(value) for value in VIEW_AZIMUTHS)
    bad = [value for value in values if not (math.isfinite(value) and -180 <= value <= 180)]
    if bad:
        raise UserError(f"--azimuths must be degrees from -180 to 180, got {bad[0]}")
    return tuple(math.radians(value) for value in dict.fromkeys(values))


def _refuse_test_subjects(clips: list[str], sources: list, option: str) -> None:
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


def _check_clip_files(sources: list, option: str) -> None:
    """Clips given by path must read and map onto the renderer's HumanEva-15 markers (the
    posture labels need the legs); catalogue clips are the tested ones."""
    from jaxtrack.body.markers import HUMANEVA_15, MarkerMapError, marker_joint_indices
    from jaxtrack.body.motion import MocapFormatError

    for source in sources:
        if source.from_catalogue:
            continue
        try:
            motion = source.load()
            marker_joint_indices(motion, HUMANEVA_15)
        except (MocapFormatError, MarkerMapError, OSError) as error:
            raise UserError(f"{option} {source.spec}: {one_line(error)}") from None
        check_clip_frames(motion, source.spec, option)


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def _training_settings(clips: list[str], sources: list, azimuths, size, bins, max_frames,
                       seed) -> dict:
    """What a posture model is trained from, as its saved description holds it: a saved model
    with these values is reused."""
    from jaxtrack.experiments import mixed_state as ms

    settings = {"clips": list(clips), "azimuths": [float(value) for value in azimuths],
                "backgrounds": list(TRAINING_BACKGROUNDS), "image_size": list(size),
                "num_bins": bins, "max_frames": max_frames, "seed": seed,
                "pose2sim_cameras": list(ms.TRAINING_POSE2SIM_CAMERAS),
                "components": ms.DEFAULT_COMPONENTS, "covariance": ms.DEFAULT_COVARIANCE,
                "regularisation": ms.DEFAULT_REGULARISATION,
                "clip_sha256": [_file_digest(source.file) for source in sources]}
    return json.loads(json.dumps(settings))


def _matches(description: dict, settings: dict) -> bool:
    return all(description.get(name) == value for name, value in settings.items())


def _read_saved_model(path: Path, what: str, remedy: str):
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


def _fit(settings: dict, option: str, frames_option: str):
    """Render, label and fit; a posture the clips never show is the user's to fix."""
    from jaxtrack.experiments.mixed_state import train as train_model

    begin = time.perf_counter()
    try:
        model, description = train_model(
            settings["clips"], azimuths=settings["azimuths"],
            backgrounds=settings["backgrounds"], image_size=tuple(settings["image_size"]),
            num_bins=settings["num_bins"], max_frames=settings["max_frames"],
            seed=settings["seed"], pose2sim_cameras=settings["pose2sim_cameras"],
            components=settings["components"], covariance=settings["covariance"],
            regularisation=settings["regularisation"])
    except ValueError as error:
        if "training frames" not in str(error):
            raise
        raise UserError(f"{option}: {one_line(error)}; or raise {frames_option}") from None
    description = description | settings | {"seconds": time.perf_counter() - begin}
    return model, description


def _model_summary(description: dict) -> str:
    counts = description.get("label_counts", {})
    shown = ", ".join(f"{name} {count}" for name, count in counts.items())
    return (f"posture model of {description.get('frames', '?')} frames ({shown}) from "
            f"{len(description.get('clips', []))} clips x {len(description.get('azimuths', []))} "
            f"views at {'x'.join(map(str, description.get('image_size', [])))}, "
            f"{description.get('num_bins')} bins")


def train(args: argparse.Namespace) -> int:
    """``jaxtrack train --method mixed-state``: fit and save the posture model."""
    from jaxtrack.experiments.mixed_state import TRAINING_CLIPS

    _refuse_other_methods(args, "train")
    clips = list(TRAINING_CLIPS) if args.clips is None else list(args.clips)
    sources = check_clips(clips, "--clips")
    _refuse_test_subjects(clips, sources, "--clips")
    if args.out.suffix != ".npz":
        raise UserError(f"--out {args.out}: must be a .npz path")
    folder = output_folder(args.out, "--out")
    check_seed(args.seed)
    max_frames = at_least(args.max_frames, 2, "--max-frames", None)
    bins = at_least(args.bins, 1, "--bins", DEFAULT_BINS)
    azimuths = _azimuths(args.azimuths)
    size = _image_size(args.size)
    existing = _read_saved_model(args.out, "--out", "delete it or choose another --out")
    _check_clip_files(sources, "--clips")
    settings = _training_settings(clips, sources, azimuths, size, bins, max_frames, args.seed)
    if existing is not None and _matches(existing.description, settings):
        print(f"{_model_summary(existing.description)}: {args.out} already holds it (reused)")
        return 0
    from jaxtrack.priors.postures import save_posture_model

    model, description = _fit(settings, "--clips", "--max-frames")
    folder.mkdir(parents=True, exist_ok=True)
    save_posture_model(args.out, model, description=description)
    print(f"{_model_summary(description)} -> {args.out} ({description['seconds']:.1f} s)")
    return 0


# --- evaluate ---------------------------------------------------------------------------------


def _plots(folder: Path, overall: dict, confusion, lag: int, title: str, frames: int
           ) -> list[Path]:
    """Fig. 2/4 (the fraction of frames within ε pixels per part, one curve per estimate) and
    the smoothed posture's confusion matrix, in ``folder``."""
    from jaxtrack.evaluation import (
        MIXED_STATE_ESTIMATES,
        MIXED_STATE_PARTS,
        mixed_state_label,
        plot_confusion,
        plot_fraction_within_per_part,
    )

    folder.mkdir(parents=True, exist_ok=True)
    curves = {mixed_state_label(kind, lag): overall[kind]["within"]
              for kind in MIXED_STATE_ESTIMATES}
    names = [name.replace("_", " ") for name in _posture_names()]
    return [plot_fraction_within_per_part(curves, folder / "fraction_within.png",
                                          parts=MIXED_STATE_PARTS, title=title),
            plot_confusion(confusion, names, folder / "posture_confusion.png",
                           xlabel="smoothed estimate", ylabel="true posture",
                           colour_label="fraction of the true posture's frames",
                           title=f"smoothed posture, {frames} frames")]


def evaluate(args: argparse.Namespace) -> int:
    """``jaxtrack evaluate --method mixed-state``: Table 1 on the held-out clips."""
    from jaxtrack.experiments.mixed_state import TEST_CLIPS, TRAINING_CLIPS

    started = time.perf_counter()
    _refuse_other_methods(args, "evaluate")
    train_clips = list(TRAINING_CLIPS) if args.train is None else list(args.train)
    test_clips = list(TEST_CLIPS) if args.test is None else list(args.test)
    train_sources = check_clips(train_clips, "--train")
    test_sources = check_clips(test_clips, "--test")
    check_held_out(train_sources, test_sources)
    _refuse_test_subjects(train_clips, train_sources, "--train")
    particles = at_least(args.particles, 1, "--particles", DEFAULT_PARTICLES)
    check_seed(args.seed)
    max_frames = at_least(args.max_frames, 2, "--max-frames", None)
    train_max_frames = at_least(args.train_max_frames, 2, "--train-max-frames", None)
    lag = at_least(args.lag, 0, "--lag", DEFAULT_LAG)
    bins = at_least(args.bins, 1, "--bins", DEFAULT_BINS)
    azimuths = _azimuths(args.azimuths)
    cameras = pose2sim_cameras(args.cameras, ())
    size = _image_size(args.size)
    backgrounds = list(dict.fromkeys(args.backgrounds))
    folder = check_json_and_plots(args)
    cache = folder / CACHE_NAME
    saved = _read_saved_model(cache, "the posture model cached beside --json:",
                              "delete it (it is retrained and rewritten) or write --json "
                              "elsewhere")
    frames_bound = max_frames or 300  # the default clips have at most 192 frames at 30 fps
    check_memory(int(_BASE_BYTES + frames_bound * (particles * _HISTORY_BYTES
                                                   + size[0] * size[1] * _PIXEL_BYTES)),
                 f"tracking {size[0]}x{size[1]} sequences with {particles} particles",
                 "--particles/--size")
    _check_clip_files(train_sources + test_sources, "--train/--test")
    settings = _training_settings(train_clips, train_sources, azimuths, size, bins,
                                  train_max_frames, args.seed)
    # every argument checked: only now is anything computed or written
    from jaxtrack.evaluation import mixed_state_table
    from jaxtrack.experiments.mixed_state import evaluate as evaluate_model
    from jaxtrack.priors.postures import save_posture_model

    if saved is not None and _matches(saved.description, settings):
        model, description = saved.model, saved.description
        print(f"{_model_summary(description)}: reused {cache}")
    else:
        model, description = _fit(settings, "--train", "--train-max-frames")
        folder.mkdir(parents=True, exist_ok=True)
        save_posture_model(cache, model, description=description)
        print(f"{_model_summary(description)} -> {cache} ({description['seconds']:.1f} s)")
    begin = time.perf_counter()
    results = evaluate_model(model, test_clips, azimuths=azimuths, backgrounds=backgrounds,
                             image_size=size, num_bins=bins, num_particles=particles, lag=lag,
                             max_frames=max_frames, seed=args.seed, pose2sim_cameras=cameras)
    evaluate_seconds = time.perf_counter() - begin
    overall = finite_json(results["overall"])
    frames = overall["smoothed"]["frames"]
    sizes = ([f"{size[0]}x{size[1]}"] if azimuths else []) + (
        [f"{len(cameras)} Pose2Sim camera(s) at a third of 1088x1920"] if cameras else [])
    title = (f"mixed-state, {len(results['sequences'])} sequences, {frames} frames at "
             f"{' and '.join(sizes)}, N={particles}")
    plots = []
    if args.plots is not None:
        plots = _plots(args.plots, overall, results["smoothed_confusion"], lag, title, frames)
    record = finite_json({
        "method": "mixed-state", "train": train_clips, "test": test_clips,
        "particles": particles, "lag": lag, "seed": args.seed, "max_frames": max_frames,
        "pose2sim_cameras": list(cameras),
        "posture_model": description, "posture_names": _posture_names(),
        "overall": results["overall"], "sequences": results["sequences"],
        "smoothed_confusion": results["smoothed_confusion"], "settings": results["settings"],
        "seconds": {"evaluate": evaluate_seconds, "total": time.perf_counter() - started}})
    json_path = _write_json(args.json, record)
    print(f"{title}; MSE in px² at each sequence's size")
    print(mixed_state_table(overall, lag))
    for path in (*plots, json_path):
        print(f"wrote {path}")
    return 0


def _posture_names() -> list[str]:
    from jaxtrack.priors.postures import POSTURE_NAMES

    return list(POSTURE_NAMES)


def _write_json(path: Path, value) -> Path:
    from jaxtrack._files import write_json_atomically

    try:
        return write_json_atomically(path, value)
    except OSError as error:
        raise UserError(f"cannot write {path}: {one_line(error)}") from None


# --- track ------------------------------------------------------------------------------------


def _load_model(path: Path):
    """The posture model of ``--model``; anything else is a one-line error naming it."""
    from jaxtrack.priors.postures import PostureFormatError, load_posture_model

    needed = "--method mixed-state needs a posture model from jaxtrack train --method mixed-state"
    if not path.exists():
        raise UserError(f"--model {path}: no such file")
    if not path.is_file():
        raise UserError(f"--model {path}: a folder, not a model file")
    try:
        saved = load_posture_model(path)
    except (PostureFormatError, OSError) as error:
        reason = one_line(error).removeprefix(f"{path}: ").removeprefix(f"{path}:")
        if "'jaxtrack.gplvm'" in reason:
            reason = "a GPLVM pose prior (for --method latent), not a posture model"
        raise UserError(f"--model {path}: {reason}; {needed}") from None
    features = saved.model.num_features
    if features < 3 or features % 2 == 0:
        raise UserError(f"--model {path}: {features} silhouette features, not 2 x bins + 1; "
                        f"{needed}")
    return saved


def _compiled(key, model, observations, particles: int):
    """Filter and smoother compiled ahead of time, so that compilation is timed apart."""
    import jax

    from jaxtrack.trackers.mixed_state import filter_sequence, smooth

    def run_filter(key, model, observations):
        return filter_sequence(key, model, observations, particles)

    filter_jit = jax.jit(run_filter)
    compiled_filter = filter_jit.lower(key, model, observations).compile()
    shapes = jax.eval_shape(run_filter, key, model, observations)
    compiled_smooth = jax.jit(smooth).lower(shapes).compile()
    return compiled_filter, compiled_smooth


def track(args: argparse.Namespace) -> int:
    """``jaxtrack track --method mixed-state``: posture and parts through one video."""
    from jaxtrack.cli.track import _frame_range, _options_record

    started = time.perf_counter()
    options_record = _options_record(args)
    _refuse_other_methods(args, "track")
    if len(args.video) != 1:
        raise UserError(f"--video: --method mixed-state tracks one video, got "
                        f"{len(args.video)}")
    video_path = args.video[0]
    given_masks = read_mask_files(args.masks, 1)[0]
    masks_path = None if args.masks is None else args.masks[0]
    particles = at_least(args.particles, 1, "--particles", DEFAULT_PARTICLES)
    check_seed(args.seed)
    if args.max_size < 32:
        raise UserError(f"--max-size must be at least 32, got {args.max_size}")
    output_directory(args.out, "--out")  # probed before any frame is read
    start, stop = _frame_range(args.frames)
    saved = _load_model(args.model)
    if not video_path.exists():
        raise UserError(f"--video {video_path}: no such video file")

    import jax
    import jax.random as jr
    import numpy as np

    from jaxtrack.cli._status import LOST_RULE, frame_statuses, status_counts, status_legend
    from jaxtrack.priors.postures import POSTURE_NAMES
    from jaxtrack.trackers.mixed_state import (
        MixedStateModel,
        instantaneous_estimates,
        observations_from_silhouettes,
    )
    from jaxtrack.vision import VideoError, median_background, read_video
    from jaxtrack.vision.foreground import largest_component
    from jaxtrack.vision.histograms import FRAME_OK, STATUS_NAMES, silhouettes
    from jaxtrack.vision.overlay import write_overlay_video_from_file
    from jaxtrack.vision.parts import PART_NAMES

    try:
        probe = read_video(video_path, start=start, max_frames=1)
        height, width = probe.frames.shape[1:3]
        scale = min(1.0, args.max_size / max(height, width))
        video = read_video(video_path, start=start,
                           max_frames=None if stop is None else stop - start, scale=scale)
    except VideoError as error:
        raise UserError(f"--video: {one_line(error)}") from None
    frames = video.frames
    num_frames, tracked_height, tracked_width = frames.shape[:3]
    scale = tracked_width / width  # the decoder rounds the size
    if num_frames < 3:
        raise UserError(f"--video {video_path}: {num_frames} frame(s) from frame {start}; the "
                        f"median background and tracking need at least 3")
    check_memory(int(_BASE_BYTES + num_frames * (particles * _HISTORY_BYTES + tracked_width
                                                 * tracked_height * _PIXEL_BYTES)),
                 f"tracking {num_frames} frames of {tracked_width}x{tracked_height} with "
                 f"{particles} particles", "--particles/--max-size/--frames")
    fps = video.fps if math.isfinite(video.fps) else None
    decoded = time.perf_counter()
    print(f"{video_path}: {num_frames} frames {width}x{height}"
          + (f" at {fps:.0f} fps" if fps else "") + f", tracked at {tracked_width}x"
          f"{tracked_height}")

    if given_masks is None:
        masks = silhouettes(frames, median_background(frames))
    else:  # the person's largest blob, as silhouettes() keeps it
        masks = fit_mask_file(given_masks, masks_path, video.frame_indices,
                              (tracked_width, tracked_height))
        masks = np.stack([largest_component(mask) for mask in masks])
    num_bins = (saved.model.num_features - 1) // 2
    observations = observations_from_silhouettes(masks, num_bins=num_bins)
    status = np.asarray(observations.status)
    if not np.any(status == FRAME_OK):
        source = (f"in --masks {masks_path}" if masks_path is not None else "against the "
                  "video's median background (a static camera and a person who moves are "
                  "needed)")
        raise UserError(f"--video {video_path}: no frame has a silhouette {source}; nothing "
                        f"written")
    observed = time.perf_counter()

    model = MixedStateModel(saved.model)
    key = jr.PRNGKey(args.seed)
    compile_begin = time.perf_counter()
    compiled_filter, compiled_smooth = _compiled(key, model, observations, particles)
    compile_seconds = time.perf_counter() - compile_begin
    run_begin = time.perf_counter()
    result = compiled_filter(key, model, observations)
    smoothed = jax.block_until_ready(compiled_smooth(result))
    run_seconds = time.perf_counter() - run_begin
    instant_posture, instant_parts = instantaneous_estimates(model, observations)
    estimates = {
        "instantaneous": (np.asarray(instant_posture), np.asarray(instant_parts), None),
        "filtered": (np.asarray(result.filtered_posture), np.asarray(result.filtered_parts),
                     np.asarray(result.filtered_posture_probabilities)),
        "smoothed": (np.asarray(smoothed.posture), np.asarray(smoothed.parts),
                     np.asarray(smoothed.posture_probabilities)),
    }
    ess = np.asarray(result.ess)
    arrays = [array for values in estimates.values() for array in values if array is not None]
    if not all(np.all(np.isfinite(array)) for array in [*arrays, ess]):
        raise UserError("tracking produced non-finite values; nothing written")

    ok = status == FRAME_OK
    smoothed_posture, smoothed_parts, _ = estimates["smoothed"]
    statuses = frame_statuses(smoothed_parts, (tracked_width, tracked_height),
                              degenerate=~(ess > 0), no_person=~ok)

    def named(points) -> dict:
        return {name: [round(float(x) / scale, 2), round(float(y) / scale, 2)]
                for name, (x, y) in zip(PART_NAMES, points, strict=True)}

    per_frame = []
    for t, index in enumerate(video.frame_indices):
        entry = {"frame": int(index),
                 "time_s": float(index / video.source_fps)
                 if math.isfinite(video.source_fps) else None,
                 "status": statuses[t].value, "silhouette": STATUS_NAMES[int(status[t])],
                 "ess": round(float(ess[t]), 2),
                 "posture": {}, "posture_probability": {}, "parts": {}}
        for kind, (posture, parts, probabilities) in estimates.items():
            # the instantaneous estimate reads the frame's silhouette alone: none without one
            known = kind != "instantaneous" or ok[t]
            entry["posture"][kind] = POSTURE_NAMES[int(posture[t])] if known else None
            entry["parts"][kind] = named(parts[t]) if known else None
            if probabilities is not None:
                entry["posture_probability"][kind] = round(
                    float(probabilities[t, int(posture[t])]), 4)
        per_frame.append(entry)

    overlay_path = args.out / "overlay.mp4"
    tracked = int(ok.sum())
    counts = status_counts(statuses)
    record = {
        "method": "mixed-state", "options": options_record, "video": str(video_path),
        "model": str(args.model), "statuses": status_legend(), "lost_rule": LOST_RULE,
        "status_counts": counts,
        "size": [width, height], "tracked_size": [tracked_width, tracked_height], "fps": fps,
        "silhouettes": ("median background" if masks_path is None
                        else f"masks {masks_path}"),
        "particles": particles, "seed": args.seed, "num_bins": num_bins,
        "tracker": model.options(),
        "posture_names": list(POSTURE_NAMES), "part_names": list(PART_NAMES),
        "posture_model": saved.description,
        "frames_with_silhouette": tracked,
        "seconds": {"decode": decoded - started, "silhouettes": observed - decoded,
                    "compile": compile_seconds, "filter_and_smooth": run_seconds,
                    "per_frame": run_seconds / num_frames,
                    "total": time.perf_counter() - started},
        "frames": per_frame,
    }
    with outputs_or_nothing(args.out) as written:  # all or nothing, Ctrl-C included
        try:  # the smoothed parts, labelled with the smoothed posture, at the video's own size
            overlay = write_overlay_video_from_file(
                video_path, video.frame_indices, {"smoothed": smoothed_parts / scale},
                overlay_path, fps=fps or 30.0, marker_names=PART_NAMES,
                labels=[f"{POSTURE_NAMES[int(posture)].replace('_', ' ')}  {t + 1}/"
                        f"{num_frames} {statuses[t].value}"
                        for t, posture in enumerate(smoothed_posture)])
        except (OSError, VideoError) as error:
            raise UserError(f"cannot write {overlay_path}: {one_line(error)}") from None
        written.append(overlay)
        json_path = _write_json(args.out / "track.json", finite_json(record))
        written.append(json_path)
    counts = np.bincount(estimates["smoothed"][0], minlength=len(POSTURE_NAMES))
    shown = ", ".join(f"{name} {count}" for name, count in zip(POSTURE_NAMES, counts,
                                                               strict=True) if count)
    print(f"tracked {num_frames} frames ({tracked} with a silhouette): "
          f"{1e3 * run_seconds / num_frames:.2f} ms/frame (compile {compile_seconds:.1f} s); "
          f"smoothed postures: {shown}; total {time.perf_counter() - started:.1f} s")
    print(f"  wrote {overlay}\n  wrote {json_path}")
    return 0
