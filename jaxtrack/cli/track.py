"""``jaxtrack track``: the latent-space tracker (Tian, Li & Sclaroff 2005) over a video file.

(``--method linear-combination``: Ong & Gong's tracker over one or several calibrated videos,
``jaxtrack.cli._linear_combination``; ``--method mixed-state``: Kwatra et al.'s posture and body
parts, ``jaxtrack.cli._mixed_state``.) The latent tracker:

1. decode the frames (downscaled so the longer side is at most ``--max-size``),
2. initialise on the first frame, by hand (``--init manual:x,y,...``: the 12 markers in video
   pixels) or automatically (``--init face``: face and foreground-blob head boxes, then a search
   of the prior's training poses against a median-background foreground;
   ``jaxtrack.trackers.autoinit``), or from a detector's keypoints (``--init keypoints``),
3. track every frame, and write ``DIR/overlay.mp4`` (the estimate drawn on the video's own
   frames, at its own size) and ``DIR/track.json`` (what ran: the method and every option; per
   frame the markers in the video's own pixels, ESS, log-likelihood and a status, ok,
   degenerate, no person or lost, by the rules of ``jaxtrack.cli._status``; the
   initialisation and timings). Both are written atomically, the JSON last, and nothing is
   left when anything fails or Ctrl-C interrupts.

Every argument, output folder included (a probe file is created and removed in it), is checked
before the first frame is decoded.

A run on a real video, and the memory estimate's measurements: ``docs/real-video.md``,
``docs/tracking.md`` (section "Memory").
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import (
    UserError,
    check_seed,
    fit_mask_file,
    integer,
    one_line,
    output_directory,
    outputs_or_nothing,
    read_mask_files,
    real,
    seed,
)
from jaxtrack.cli._options import add_tracker_options, tracker_options

__all__ = ["add_parser"]

# peak memory of `track` grows by 10-14 kB per particle (measured with --max-size 160 and 1 000,
# 20 000 and 60 000 particles) over about 1.1 GB; the estimate rounds both up
_BYTES_PER_PARTICLE = 16_000
_BASE_BYTES = 1.5e9
_MIN_TORSO_PX = 4.0  # a shorter neck-pelvis distance is no body the tracker can follow


_LINEAR_COMBINATION_ONLY = ("calibration", "cameras", "view_selection", "skeleton", "skin",
                            "iterations")
"""``jaxtrack track``'s options that only ``--method linear-combination`` reads."""


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "track",
        help="track the upper body in a video with the latent-space tracker",
        description=(
            "Track a person's upper body (12 markers) through a video with CONDENSATION in a "
            "GPLVM latent space, initialised on the first frame by hand or automatically; "
            "writes DIR/overlay.mp4 and DIR/track.json."),
        epilog=(
            "--init face: face boxes (OpenCV Haar cascades) and head boxes from the top of "
            "moving foreground blobs (median background of the video; needs a static camera "
            "and a person who moves), then the prior's training poses are searched for the one "
            "that best covers the foreground. --init manual:x,y,...: the 24 numbers are the "
            "first frame's 12 markers in video pixels, in the order head, neck, thorax, pelvis, "
            "right shoulder, elbow, wrist, hip, left shoulder, elbow, wrist, hip. example, on "
            "the bundled Pose2Sim clip (jaxtrack.data.path('pose2sim/videos/cam03_half.mp4')): "
            "jaxtrack track --model jaxtrack-demo/gplvm_waves.npz --video CLIP.mp4 --out p2s"),
    )
    parser.add_argument("--method", choices=("latent", "linear-combination", "mixed-state"),
                        default="latent",
                        help="the tracker (default latent); --model must come from jaxtrack "
                        "train with the same --method")
    parser.add_argument("--model", required=True, type=Path, metavar="MODEL.npz",
                        help="a model from jaxtrack train (or jaxtrack-demo/gplvm_waves.npz)")
    parser.add_argument("--video", required=True, type=Path, nargs="+", metavar="FILE",
                        help="the video to track (anything OpenCV's FFmpeg reads: mp4, avi, "
                        "mov); linear-combination: one per calibrated camera")
    parser.add_argument("--init", default="face", metavar="face|keypoints|manual:x,y,...",
                        help="first-frame pose: found automatically (face, the default), the "
                        "first frame's --keypoints, or the 12 markers given by hand (see below)")
    parser.add_argument("--out", required=True, type=Path, metavar="DIR",
                        help="folder to write overlay.mp4 and track.json into (created)")
    parser.add_argument("--particles", type=integer(1), default=None,
                        help="particles of the filter (default 200 for latent, 300 for "
                        "linear-combination, 500 for mixed-state; latent: memory grows by "
                        f"about {_BYTES_PER_PARTICLE // 1000} kB per particle)")
    parser.add_argument("--seed", type=seed, default=0,
                        help="random seed of the particle filter, 0 to 2**32 - 1 (default 0)")
    add_tracker_options(parser)
    parser.add_argument("--max-size", type=integer(32), default=960, metavar="PX",
                        help="downscale so the longer side is at most PX (default 960)")
    parser.add_argument("--frames", metavar="START:STOP", help="frame range (default: all)")
    group = parser.add_argument_group("linear-combination and mixed-state")
    # linear-combination options
    group.add_argument("--calibration", type=Path, default=None, metavar="FILE",
                       help="linear-combination: the cameras' calibration (a Pose2Sim "
                       "Calib.qca.txt), one camera per --video in order")
    group.add_argument("--iterations", type=integer(1), default=None,
                       help="linear-combination: CONDENSATION iterations per frame (default 5)")
    group.add_argument("--cameras", type=integer(0), nargs="+", default=None, metavar="INDEX",
                       help="linear-combination: which cameras of --calibration (0-based, in "
                       "its order) filmed the --video files, one per video (default: all)")
    group.add_argument("--view-selection", choices=("ambiguity", "fitness", "paper"),
                       default=None,
                       help="linear-combination, several videos: pick each frame's view by its "
                       "least ambiguity over +-5 frames (the default, chosen on validation), "
                       "its greatest fitness over +-5 frames, or the paper's greatest fitness "
                       "x 1/ambiguity")
    group.add_argument("--skeleton", choices=("mean", "best"), default=None,
                       help="linear-combination: the 3-D skeleton reported, the particles' "
                       "weighted mean (the default, chosen on validation) or the best "
                       "particle's (the paper's)")
    parser.add_argument("--coverage-weight", type=real(0.0), default=None, metavar="NU",
                        help="latent, with --masks: also charge the masks for what the body "
                        "leaves unexplained, NU nats per unit of the coverage term "
                        "(jaxtrack.likelihoods.edges; default off)")
    parser.add_argument("--keypoints", type=Path, default=None, metavar="FILE",
                        help="latent: a per-frame detector's keypoints of the video, a .npz with "
                        "'keypoints' (frames, 12, 2) in the video's pixels in SPM_MARKERS order "
                        "(NaN where not found) and optionally 'confidence' (frames, 12), one "
                        "row per video frame from the first (jaxtrack.vision.keypoints); the "
                        "likelihood's keypoint term scores them")
    parser.add_argument("--keypoint-weight", type=real(0.0), default=None, metavar="ETA",
                        help="latent, with --keypoints: the keypoint term's weight (default "
                        "1.5, the Cauchy density's own: jaxtrack.likelihoods.edges)")
    parser.add_argument("--masks", type=Path, nargs="+", default=None, metavar="FILE",
                        help="the person's masks, one .npz ('masks') or .npy of (frames, height, "
                        "width) bool per --video, in order (a person segmenter's): the "
                        "silhouettes of linear-combination and mixed-state, the foreground of "
                        "latent's likelihood (default: the video's median background)")
    group.add_argument("--skin", default=None, metavar="R,G,B",
                       help="linear-combination: a sample of the person's skin colour (default: "
                       "a fixed chroma box)")
    # mixed-state options
    parser.set_defaults(handler=run)


def _read_keypoints(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``--keypoints FILE``'s keypoints and confidences, or a one-line error naming it."""
    from jaxtrack.vision.keypoints import KeypointFileError, read_keypoints

    try:
        return read_keypoints(path)
    except KeypointFileError as error:
        raise UserError(f"--keypoints: {error}") from None


def _keypoints_for_frames(keypoints, path: Path, frame_indices, scale: float
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The keypoints of the video frames tracked, in tracking pixels."""
    points, confidence = keypoints
    last = int(np.max(frame_indices))
    if len(points) <= last:
        raise UserError(f"--keypoints: {path} holds {len(points)} frames; the video frames "
                        f"tracked run to frame {last}")
    chosen = np.asarray(frame_indices)
    return points[chosen] * scale, confidence[chosen]


def _load_prior(path: Path):
    import jax.numpy as jnp

    from jaxtrack.body import SPMTemplate
    from jaxtrack.priors.gplvm import GPLVMFormatError, load_gplvm

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
    return saved.model, template


def _check_particle_memory(particles: int) -> None:
    from jaxtrack._files import NotEnoughMemoryError, check_memory

    try:
        check_memory(_BASE_BYTES + _BYTES_PER_PARTICLE * particles,
                     f"tracking with {particles} particles")
    except NotEnoughMemoryError as error:
        most = max(0, int((error.available - _BASE_BYTES) // _BYTES_PER_PARTICLE))
        raise UserError(f"--particles: {error}; at most about {most} particles fit") from None


def _frame_range(text: str | None) -> tuple[int, int | None]:
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


def _manual_numbers(text: str) -> np.ndarray:
    """The 12 markers ``(12, 2)`` of ``--init manual:...`` in video pixels: 24 finite
    numbers, checked before anything is loaded."""
    from jaxtrack.body import UPPER_BODY_12

    try:
        values = np.array([float(value) for value in text.split(",")])
    except ValueError:
        raise UserError(f"--init manual: expects 24 comma-separated numbers, got "
                        f"{text!r}") from None
    if values.size != 24:
        raise UserError(f"--init manual: expects 24 numbers (12 markers x, y), got "
                        f"{values.size}")
    if not np.all(np.isfinite(values)):
        bad = [f"{UPPER_BODY_12[i // 2]} {'xy'[i % 2]} ({text.split(',')[i].strip()})"
               for i in np.flatnonzero(~np.isfinite(values))]
        raise UserError(f"--init manual: expects finite numbers; not finite: {', '.join(bad)}")
    return values.reshape(12, 2)


def _manual_markers(text: str, size: tuple[int, int]) -> np.ndarray:
    """The 12 markers ``(12, 2)`` of ``--init manual:...`` in video pixels, checked against the
    video's ``(width, height)`` before anything is tracked: 24 finite numbers, every marker
    inside the frame (those outside are named), and a torso of a few pixels at least."""
    from jaxtrack.body import UPPER_BODY_12

    markers = _manual_numbers(text)
    width, height = size
    outside = [f"{name} ({x:g}, {y:g})" for name, (x, y) in zip(UPPER_BODY_12, markers,
                                                                 strict=True)
               if not (0 <= x <= width and 0 <= y <= height)]
    if outside:
        raise UserError(f"--init manual: {len(outside)} marker(s) outside the {width}x{height} "
                        f"video (x 0-{width}, y 0-{height}, video pixels): {', '.join(outside)}")
    neck, pelvis = UPPER_BODY_12.index("neck"), UPPER_BODY_12.index("pelvis")
    torso = float(np.linalg.norm(markers[pelvis] - markers[neck]))
    if torso < _MIN_TORSO_PX:
        raise UserError(f"--init manual: the torso (neck to pelvis) is {torso:.1f} px long, "
                        f"less than {_MIN_TORSO_PX:g} px: not a body pose; the numbers are x, y "
                        f"of {', '.join(UPPER_BODY_12)} in video pixels")
    return markers


def manual_instead() -> str:
    """What to give when ``--init face`` finds nobody: the other two initialisations, with the
    markers' order."""
    from jaxtrack.body import UPPER_BODY_12

    return (f"give the first frame's pose instead: --init manual:x,y,... (24 numbers, x and y "
            f"of {', '.join(UPPER_BODY_12)}, in video pixels) or --init keypoints --keypoints "
            f"FILE (a detector's keypoints)")


def _initialise(args, model, template, frames, scale, original, masks=None, keypoints=None
                ) -> tuple[np.ndarray, dict]:
    """First-frame markers (tracking pixels) and a description of how they were found; with
    ``masks`` (the person's masks of the tracked frames) ``--init face`` reads the first frame's
    mask as its foreground instead of the difference from the video's median; ``--init
    keypoints`` takes ``keypoints``' first frame (the detector's, tracking pixels)."""
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.trackers.autoinit import AutoInitError, auto_initialise
    from jaxtrack.vision import FaceDetectorUnavailableError, foreground_mask, median_background

    if args.init.startswith("manual:"):
        markers = _manual_markers(args.init[len("manual:"):], original) * scale
        return markers, {"method": "manual"}
    if args.init == "keypoints":
        points, confidence = keypoints
        if not np.all(confidence[0] > 0):
            missing = [name for name, sure in zip(UPPER_BODY_12, confidence[0], strict=True)
                       if not sure > 0]
            raise UserError(f"--init keypoints: {args.keypoints} has no {', '.join(missing)} "
                            f"in the first frame tracked; give --init face or manual:...")
        return points[0].astype(np.float64), {"method": "keypoints",
                                              "file": str(args.keypoints)}
    if args.init != "face":
        raise UserError(f"--init must be face, keypoints or manual:x,y,... (24 numbers), got "
                        f"{args.init!r}")
    if masks is not None:
        foreground, source = np.asarray(masks[0], bool), "masks"
        if not foreground.any():
            raise UserError(f"--init face: the first frame's mask in {args.masks[0]} is empty; "
                            f"give masks that hold the person there, or {manual_instead()}")
    else:
        if len(frames) < 3:
            raise UserError("--init face needs at least 3 frames (a median background)")
        foreground = foreground_mask(frames[0], median_background(frames))
        source = "median background"
    try:
        found = auto_initialise(model, template, frames[0], foreground)
    except AutoInitError as error:
        reason = one_line(error).removesuffix("; give the first pose by hand")
        raise UserError(f"--init face found nobody on {args.video}: {reason}; "
                        f"{manual_instead()}") from None
    except FaceDetectorUnavailableError as error:
        raise UserError(f"--init face: {error}") from None
    return found.markers, {
        "method": "face", "source": found.source, "score": found.score, "foreground": source,
        "box": (found.face / scale).round(1).tolist(), "torso_px": found.torso / scale,
        "boxes_tried": (found.faces / scale).round(1).tolist()}


def _options_record(args: argparse.Namespace) -> dict:
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


def run(args: argparse.Namespace) -> int:
    import time

    import jax.random as jr

    from jaxtrack._files import write_json_atomically
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.cli._status import LOST_RULE, frame_statuses, status_counts, status_legend
    from jaxtrack.trackers import Engine, latent_tracker, track
    from jaxtrack.vision import (
        VideoError,
        median_grey_background,
        read_video,
        to_grey,
    )
    from jaxtrack.vision.overlay import write_overlay_video_from_file

    if args.method == "linear-combination":
        from jaxtrack.cli import _linear_combination

        return _linear_combination.track(args)
    if args.method == "mixed-state":
        from jaxtrack.cli import _mixed_state

        return _mixed_state.track(args)
    for name in _LINEAR_COMBINATION_ONLY:  # refused, not ignored
        if getattr(args, name) is not None:
            raise UserError(f"--{name.replace('_', '-')} does not apply to --method latent "
                            f"(it is a linear-combination setting)")
    if len(args.video) != 1:
        raise UserError(f"--video: --method latent tracks one video, got {len(args.video)}")
    options_record = _options_record(args)
    given_masks = read_mask_files(args.masks, 1)[0]
    args.video = args.video[0]
    if args.particles is None:
        args.particles = 200
    started = time.perf_counter()
    if args.particles < 1:
        raise UserError(f"--particles must be positive, got {args.particles}")
    check_seed(args.seed)
    _check_particle_memory(args.particles)
    if args.init.startswith("manual:"):
        _manual_numbers(args.init[len("manual:"):])  # refused before anything is loaded
    elif args.init not in ("face", "keypoints"):
        raise UserError(f"--init must be face, keypoints or manual:x,y,... (24 numbers), got "
                        f"{args.init!r}")
    if args.keypoints is None:
        for option, given in (("--keypoint-weight", args.keypoint_weight is not None),
                              ("--init keypoints", args.init == "keypoints")):
            if given:
                raise UserError(f"{option}: it reads a detector's keypoints; give --keypoints")
    given_keypoints = None if args.keypoints is None else _read_keypoints(args.keypoints)
    if args.max_size < 32:
        raise UserError(f"--max-size must be at least 32, got {args.max_size}")
    options = tracker_options(args)
    if given_masks is not None and not options.likelihood.needs_edges:
        raise UserError(f"--masks: the {options.likelihood.kind!r} likelihood has no foreground "
                        f"term to read them (the default limbs+edges has)")
    likelihood = options.likelihood
    terms = {}
    if args.coverage_weight is not None:
        if given_masks is None:
            raise UserError("--coverage-weight: the coverage term reads the person's masks; "
                            "give --masks")
        terms["coverage_weight"] = ("--coverage-weight", args.coverage_weight)
    if given_keypoints is not None:
        from jaxtrack.likelihoods.edges import CAUCHY_KEYPOINT_WEIGHT

        if not likelihood.needs_edges:
            raise UserError(f"--keypoints: the {likelihood.kind!r} likelihood has no keypoint "
                            f"term to read them (the default limbs+edges has)")
        terms["keypoint_weight"] = ("--keypoint-weight", CAUCHY_KEYPOINT_WEIGHT
                                    if args.keypoint_weight is None else args.keypoint_weight)
    for name, (option, value) in terms.items():  # the other settings are kept as they are
        try:
            likelihood = dataclasses.replace(likelihood, **{name: value})
        except ValueError as error:
            raise UserError(f"{option}: {error}") from None
    output_directory(args.out, "--out")  # probed before any frame is read
    start, stop = _frame_range(args.frames)
    if not args.model.is_file():
        raise UserError(f"--model {args.model}: no such file")
    try:
        probe = read_video(args.video, start=start, max_frames=1)
    except VideoError as error:
        raise UserError(f"--video: {' '.join(str(error).split())}") from None
    height, width = probe.frames.shape[1:3]
    if args.init.startswith("manual:"):  # against the video's own size, before any work
        _manual_markers(args.init[len("manual:"):], (width, height))
    model, template = _load_prior(args.model)
    try:
        scale = min(1.0, args.max_size / max(height, width))
        video = read_video(args.video, start=start,
                           max_frames=None if stop is None else stop - start, scale=scale)
    except VideoError as error:
        raise UserError(f"--video: {' '.join(str(error).split())}") from None
    frames = video.frames
    scale = frames.shape[2] / width  # the decoder rounds the size
    if len(frames) < 2:
        raise UserError(f"--video {args.video}: {len(frames)} frame(s) from frame {start}; "
                        f"tracking needs at least 2")
    fps = video.fps if math.isfinite(video.fps) else None
    print(f"{args.video}: {len(frames)} frames {width}x{height}"
          + (f" at {fps:.0f} fps" if fps else "") + f", tracked at {frames.shape[2]}x"
          f"{frames.shape[1]}", flush=True)
    masks = None if given_masks is None else fit_mask_file(
        given_masks, args.masks[0], video.frame_indices, (frames.shape[2], frames.shape[1]))
    keypoints = None if given_keypoints is None else _keypoints_for_frames(
        given_keypoints, args.keypoints, video.frame_indices, scale)
    markers, init = _initialise(args, model, template, frames, scale, (width, height), masks,
                                keypoints)
    print(f"initialised ({init['method']}"
          + (f", {init['source']} box, overlap {init['score']:.2f} against the "
             f"{init['foreground']}" if "score" in init else "")
          + ")", flush=True)
    grey = to_grey(frames)
    # a median of one or two frames holds the person
    foreground = options.foreground and len(grey) >= 3
    tracker = latent_tracker(model, template, engine=Engine(args.particles), fps=fps,
                             likelihood=likelihood, refinement=options.refinement,
                             background=median_grey_background(grey) if foreground else None)
    result = track(tracker, jr.PRNGKey(args.seed), grey, markers, masks=masks,
                   keypoints=keypoints)
    if not (np.all(np.isfinite(result.markers)) and np.all(np.isfinite(result.best_markers))):
        bad = int(np.argmax(~np.isfinite(result.markers).all(axis=(1, 2))))
        raise UserError(f"tracking produced non-finite markers from frame {bad}; nothing written")
    statuses = frame_statuses(
        result.markers, (frames.shape[2], frames.shape[1]), degenerate=result.degenerate,
        no_person=None if masks is None else ~np.asarray(masks).any(axis=(1, 2)),
        log_likelihood=result.log_likelihood)

    def named(points):
        return {name: [round(float(x) / scale, 2), round(float(y) / scale, 2)]
                for name, (x, y) in zip(UPPER_BODY_12, points, strict=True)}

    init["markers"] = named(markers)
    per_frame = [{
        "frame": int(index), "time_s": float(index / video.source_fps)
        if math.isfinite(video.source_fps) else None,
        "status": statuses[t].value,
        "markers": named(result.markers[t]), "best_markers": named(result.best_markers[t]),
        "ess": float(result.ess[t]), "log_likelihood": float(result.log_likelihood[t]),
        "degenerate": bool(result.degenerate[t]),
    } for t, index in enumerate(video.frame_indices)]
    counts = status_counts(statuses)
    with outputs_or_nothing(args.out) as written:  # all or nothing, Ctrl-C included
        try:  # at the video's own size: the markers scaled back from the tracked frames
            written.append(write_overlay_video_from_file(
                args.video, video.frame_indices, {"latent": result.markers / scale},
                args.out / "overlay.mp4", fps=fps or 30.0, marker_names=UPPER_BODY_12,
                labels=[f"{t + 1}/{len(statuses)} {status.value}"
                        for t, status in enumerate(statuses)]))
        except (OSError, VideoError) as error:
            raise UserError(f"cannot write {args.out / 'overlay.mp4'}: {one_line(error)}"
                            ) from None
        video_path = written[-1]
        written.append(write_json_atomically(args.out / "track.json", {
            "method": "latent", "options": options_record,
            "video": str(args.video), "model": str(args.model), "size": [width, height],
            "tracked_size": [frames.shape[2], frames.shape[1]], "fps": fps,
            "particles": args.particles, "seed": args.seed, "tracker": result.options,
            "masks": None if args.masks is None else str(args.masks[0]),
            "keypoints": None if args.keypoints is None else str(args.keypoints),
            "init": init, "statuses": status_legend(), "lost_rule": LOST_RULE,
            "status_counts": counts,
            "seconds_per_frame": result.seconds_per_frame,
            "compile_seconds": result.compile_seconds, "frames": per_frame}))
        json_path = written[-1]
    shown = ", ".join(f"{count} {name}" for name, count in counts.items() if count)
    print(f"tracked {len(frames)} frames: {1e3 * result.seconds_per_frame:.2f} ms/frame "
          f"(compile {result.compile_seconds:.1f} s); frames: {shown}; total "
          f"{time.perf_counter() - started:.1f} s")
    print(f"  wrote {video_path}\n  wrote {json_path}")
    return 0
