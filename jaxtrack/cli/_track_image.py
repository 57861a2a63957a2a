"""``jaxtrack track --method latent|condensation|mht``: the image trackers over a video file.

The latent-space tracker (Tian, Li & Sclaroff 2005) and its two baselines, CONDENSATION and
MHT, whose dynamics are learned from the ``--model`` prior's training poses
(:func:`jaxtrack.experiments.protocol.video_tracker`, as ``jaxtrack evaluate`` builds them);
without ``--model``, the bundled ``latent.npz`` (:func:`jaxtrack.data.models.default_model`).
Every argument is checked, the first-frame pose found (``jaxtrack.cli._pose``) and the tracker
built here; :func:`jaxtrack.experiments.pipeline.track_video` decodes the video in chunks,
tracks it and writes ``overlay.mp4`` and ``track.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import (
    UserError,
    check_seed,
    model_or_default,
    one_line,
    output_directory,
    pipeline_errors,
    read_mask_files,
)
from jaxtrack.cli._detector import (
    FIT_PARTICLES,
    check_detection_options,
    detect_video,
    detection_tracker,
)
from jaxtrack.cli._options import tracker_options
from jaxtrack.cli._pose import (
    initialise,
    manual_markers,
    manual_numbers,
    person_box,
    read_keypoints,
)

__all__ = ["BYTES_PER_PARTICLE", "IMAGE_METHODS", "LINEAR_COMBINATION_ONLY", "run"]

IMAGE_METHODS = ("latent", "condensation", "mht")
# peak memory of latent `track` grows by 10-14 kB per particle (measured with --max-size 160 and
# 1 000, 20 000 and 60 000 particles) over about 1.1 GB; the estimate rounds both up
BYTES_PER_PARTICLE = 16_000
_BASE_BYTES = 1.5e9

LINEAR_COMBINATION_ONLY = ("calibration", "cameras", "view_selection", "skeleton", "skin",
                           "iterations")
"""``jaxtrack track``'s options that only ``--method linear-combination`` reads."""


def _load_prior(path: Path):
    """The ``--model`` prior (:class:`jaxtrack.priors.train.TrainedPrior`), or a one-line error
    naming what is wrong with the file."""
    import jax.numpy as jnp

    from jaxtrack.body import SPMTemplate
    from jaxtrack.priors.gplvm import GPLVMFormatError, load_gplvm
    from jaxtrack.priors.train import TrainedPrior

    if not path.is_file():
        raise UserError(f"--model {path}: no such file")
    try:
        saved = load_gplvm(path)
    except GPLVMFormatError as error:
        raise UserError(f"--model {path}: {' '.join(str(error).split())}") from None
    if "reference_lengths" not in saved.arrays or "reference_angles" not in saved.arrays:
        raise UserError(f"--model {path}: a GPLVM without an SPM template, not a tracking "
                        f"prior; make one with jaxtrack train")
    if not np.all(np.isfinite(np.asarray(saved.model.dynamics_std))):
        raise UserError(f"--model {path}: the GPLVM has no latent dynamics (ν); make one with "
                        f"jaxtrack train")
    template = SPMTemplate(jnp.asarray(saved.arrays["reference_lengths"]),
                           jnp.asarray(saved.arrays["reference_angles"]))
    return TrainedPrior(saved.model, template, saved.description,
                        training_states=saved.arrays.get("training_states"),
                        training_sequence_ids=saved.arrays.get("training_sequence_ids"))


def _check_particle_memory(particles: int) -> None:
    from jaxtrack._files import NotEnoughMemoryError, check_memory

    try:
        check_memory(_BASE_BYTES + BYTES_PER_PARTICLE * particles,
                     f"tracking with {particles} particles")
    except NotEnoughMemoryError as error:
        most = max(0, int((error.available - _BASE_BYTES) // BYTES_PER_PARTICLE))
        raise UserError(f"--particles: {error}; at most about {most} particles fit") from None


def frame_range(text: str | None) -> tuple[int, int | None]:
    """``--frames START:STOP`` as ``(start, stop or None)``; at least 2 frames."""
    if not text:
        return 0, None
    start, separator, stop = text.partition(":")
    try:
        first = int(start or 0)
        last = int(stop) if stop else None
    except ValueError:
        first = last = -1
    if not separator or first < 0 or (last is not None and last < first + 2):
        raise UserError(f"--frames must be START:STOP with at least 2 frames, got {text!r}")
    return first, last


def tracked_end(video: Path, stop: int | None) -> int | None:
    """One past the last video frame tracked: the frame count the container states, cut at
    ``--frames``' ``stop``; None where the container states none. What per-frame inputs are
    checked against before any work (a one-line error for an unreadable video)."""
    from jaxtrack.vision.video import VideoError, frame_count

    try:
        total = frame_count(video)
    except VideoError as error:
        raise UserError(f"--video: {one_line(error)}") from None
    return None if total is None else total if stop is None else min(stop, total)


def options_record(args: argparse.Namespace) -> dict:
    """The command line's options as ``track.json`` records them (paths as text)."""
    record = {}
    for name, value in sorted(vars(args).items()):
        if callable(value):
            continue
        if isinstance(value, Path):
            value = str(value)
        elif isinstance(value, list | tuple):
            value = [str(item) if isinstance(item, Path) else item for item in value]
        record[name] = value
    return record


def _likelihood(args, options, masks, detections: bool):
    """The likelihood with ``--coverage-weight`` set; with detections, the detection density
    times it (``jaxtrack.cli._detector``), or with ``--keypoint-weight`` its keypoint term; the
    other settings are kept as they are."""
    likelihood, terms = options.likelihood, {}
    if masks is not None and not likelihood.needs_edges:
        raise UserError(f"--masks: the {likelihood.kind!r} likelihood has no foreground "
                        f"term to read them (the default limbs+edges has)")
    if args.coverage_weight is not None:
        if masks is None:
            raise UserError("--coverage-weight: the coverage term reads the person's masks; "
                            "give --masks")
        terms["coverage_weight"] = ("--coverage-weight", args.coverage_weight)
    if detections and args.keypoint_weight is not None:
        if not likelihood.needs_edges:
            raise UserError(f"--keypoint-weight: the {likelihood.kind!r} likelihood has no "
                            f"keypoint term (the default limbs+edges has)")
        terms["keypoint_weight"] = ("--keypoint-weight", args.keypoint_weight)
    for name, (option, value) in terms.items():
        try:
            likelihood = dataclasses.replace(likelihood, **{name: value})
        except ValueError as error:
            raise UserError(f"{option}: {error}") from None
    if detections and args.keypoint_weight is None:
        from jaxtrack.likelihoods.detections import detection_model
        from jaxtrack.trackers import DetectionLikelihood

        return DetectionLikelihood(detection_model(), None if args.no_image else likelihood)
    return likelihood


def _check(args) -> tuple:
    """Every argument checked before the video is read; ``(masks, keypoints, likelihood,
    options)``."""
    from jaxtrack.experiments.protocol import DEFAULT_PARTICLES

    for name in LINEAR_COMBINATION_ONLY:  # refused, not ignored
        if getattr(args, name) is not None:
            raise UserError(f"--{name.replace('_', '-')} does not apply to --method "
                            f"{args.method} (it is a linear-combination setting)")
    if len(args.video) != 1:
        raise UserError(f"--video: --method {args.method} tracks one video, got "
                        f"{len(args.video)}")
    masks = read_mask_files(args.masks, 1)[0]
    args.video = args.video[0]
    if args.particles is None:
        args.particles = DEFAULT_PARTICLES[args.method]
    check_seed(args.seed)
    if args.method == "latent":
        _check_particle_memory(args.particles)
    if args.init.startswith("manual:"):
        manual_numbers(args.init[len("manual:"):])  # refused before anything is loaded
    elif args.init not in ("face", "keypoints"):
        raise UserError(f"--init must be face, keypoints or manual:x,y,... (24 numbers), got "
                        f"{args.init!r}")
    check_detection_options(args)
    keypoints = None if args.keypoints is None else read_keypoints(args.keypoints, args.person)
    options = tracker_options(args)
    detections = args.keypoints is not None or args.detector is not None
    return masks, keypoints, _likelihood(args, options, masks, detections), options


def run(args: argparse.Namespace) -> int:
    """``jaxtrack track --method latent|condensation|mht`` (module docstring)."""
    import jax.random as jr

    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.experiments.pipeline import track_video, tracking_scale, video_background
    from jaxtrack.experiments.protocol import video_tracker
    from jaxtrack.trackers import DetectionLikelihood
    from jaxtrack.vision import (
        foreground_mask,
        masks_for_frames,
        read_video,
    )

    args.model = model_or_default(args.model, args.method)  # the bundled latent.npz
    record_options = options_record(args)
    started = time.perf_counter()
    masks, keypoints, likelihood, options = _check(args)
    output_directory(args.out, "--out")  # probed before any frame is read
    start, stop = frame_range(args.frames)
    if not args.model.is_file():
        raise UserError(f"--model {args.model}: no such file")
    count = None if stop is None else stop - start
    detector = None
    if args.detector is not None:  # the checks are done: the detector's work may start
        args.keypoints, detector = detect_video(
            args, start, count, None if args.person is None else person_box(args.person))
        keypoints = read_keypoints(args.keypoints, args.person)
    if keypoints is not None and len(keypoints[0]) <= start:
        raise UserError(f"--keypoints: {args.keypoints} holds {len(keypoints[0])} frames; the "
                        f"video frames tracked start at frame {start}")
    if keypoints is not None:  # every frame tracked needs its row, checked before any work
        end = tracked_end(args.video, stop)
        last = None if end is None else end - 1
        if last is not None and len(keypoints[0]) <= last:
            raise UserError(f"--keypoints: {args.keypoints} holds {len(keypoints[0])} frames; "
                            f"the video frames tracked run to frame {last}")
    # fewer than 3 frames for a median, a mask file's size: one line naming the video
    with pipeline_errors(f"--video {args.video}"):
        probe = read_video(args.video, start=start, max_frames=1)
        size = probe.image_size
        if args.init.startswith("manual:"):  # against the video's own size, before any work
            manual_markers(args.init[len("manual:"):], size)
        prior = _load_prior(args.model)
        scale = tracking_scale(size, max_size=args.max_size)
        first = read_video(args.video, start=start, max_frames=1, scale=scale)
        tracked = first.image_size
        factors = np.array([tracked[0] / size[0], tracked[1] / size[1]])
        foreground = None
        if args.init == "face":
            if masks is not None:
                foreground = (masks_for_frames(masks, [start], tracked, name=str(args.masks[0])
                                               )[0], "masks")
            else:
                scene = video_background(args.video, scale=scale, start=start, max_frames=count)
                foreground = (foreground_mask(first.frames[0], scene), "median background")
        pose, init = initialise(
            args, prior.model, prior.template, size, first.frames[0], foreground, factors,
            None if keypoints is None else (keypoints[0][start], keypoints[1][start]))
        grey_scene = (video_background(args.video, scale=scale, start=start, max_frames=count,
                                       grey=True) if options.foreground else None)
    fps = probe.fps if np.isfinite(probe.fps) else None
    try:
        tracker = video_tracker(args.method, prior, args.particles, fps=fps,
                                likelihood=likelihood, refinement=options.refinement,
                                background=grey_scene)
        fitter = video_tracker("condensation", prior, FIT_PARTICLES, fps=fps,
                               likelihood=likelihood, background=grey_scene) \
            if args.method == "mht" and isinstance(likelihood, DetectionLikelihood) else None
    except ValueError as error:
        raise UserError(f"--model {args.model}: {one_line(error)}") from None
    density = None
    if isinstance(likelihood, DetectionLikelihood):
        tracker, density = detection_tracker(args, tracker, keypoints, factors, tracked, pose,
                                             start, tracked_end(args.video, stop), fitter)
    print(f"{args.video}: {size[0]}x{size[1]}" + (f" at {fps:.0f} fps" if fps else "")
          + f", tracked at {tracked[0]}x{tracked[1]}; initialised ({init['method']}"
          + (f", {init['source']} box, overlap {init['score']:.2f} against the "
             f"{init['foreground']}" if "score" in init else "") + ")", flush=True)
    init["markers"] = {name: [round(float(x), 2), round(float(y), 2)]
                       for name, (x, y) in zip(UPPER_BODY_12, pose, strict=True)}
    with pipeline_errors("jaxtrack track"):
        record = track_video(
            tracker, args.video, args.out, key=jr.PRNGKey(args.seed), initial_pose=pose,
            scale=scale, start=start, max_frames=count, masks=masks, keypoints=keypoints,
            marker_names=UPPER_BODY_12, seed=args.seed,
            detector_seconds=None if detector is None else detector["seconds"],
            extra_record={"options": record_options, "model": str(args.model), "init": init,
                          "detector": detector, "detections": density,
                          "masks_file": None if args.masks is None else str(args.masks[0]),
                          "keypoints_file": None if args.keypoints is None
                          else str(args.keypoints)})
    counts = ", ".join(f"{n} {name}" for name, n in record["status_counts"].items() if n)
    timings = record["timings"]
    print(f"tracked {record['frames_tracked']} frames: "
          f"{1e3 * timings['seconds_per_frame']:.2f} ms/frame (compile "
          f"{timings['compile_seconds']:.1f} s); frames: {counts}; total "
          f"{time.perf_counter() - started:.1f} s")
    print(f"  wrote {record['paths']['overlay']}\n  wrote {record['paths']['json']}")
    return 0
