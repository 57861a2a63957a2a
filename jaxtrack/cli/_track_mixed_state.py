"""``jaxtrack track --method mixed-state``: Kwatra, Bobick & Johnson's mixed-state tracker
over one video, on the shared video pipeline (:func:`jaxtrack.experiments.pipeline.track_video`:
decoded and tracked in chunks): silhouettes by background subtraction against the video's
median background (or ``--masks``), the filter frame by frame, then the whole-sequence smoother
(§3.3) over every frame's particles, and ``DIR/overlay.mp4`` and ``DIR/track.json`` (the JSON
last). Per frame the JSON holds the posture and parts of the instantaneous estimate (the
extended Ghost), the filter and the smoother. A bad argument is a one-line :class:`UserError`,
raised before anything is computed or written.

``--keypoints FILE_OR_FOLDER`` (with ``--person x0,y0,x1,y1`` where it holds several people)
gives a per-frame detector's keypoints: where a keypoint is confident, its head, wrists and
ankles replace the silhouette's part hypotheses of every posture
(:func:`jaxtrack.vision.parts.detection_hypotheses`); elsewhere the silhouette's stay. A
detections file or folder (OpenPose JSON, COCO, MediaPipe, jaxtrack's own) is read with the
ankles (``markers=DETECTION_MARKERS``); a single person's ``.npz`` of ``keypoints`` holds the 12
upper-body markers, so the feet stay the silhouette's.
"""

from __future__ import annotations

import argparse
import collections
import time
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_memory,
    check_seed,
    one_line,
    output_directory,
    pipeline_errors,
    read_mask_files,
)
from jaxtrack.cli._mixed_state import (
    BASE_BYTES,
    DEFAULT_PARTICLES,
    HISTORY_BYTES,
    refuse_other_methods,
)

__all__ = ["track"]


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


def _read_detections(path: Path, person: str | None
                     ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """``--keypoints``' points ``(rows, markers, 2)`` in video pixels (NaN where absent),
    confidences ``(rows, markers)`` and the markers' names, one row per video frame from the
    first, or a one-line error naming the file.

    A single person's ``.npz`` of ``keypoints`` is read by :func:`jaxtrack.cli._pose.read_keypoints`
    (its 12 markers); any other detections file or folder with the knees and ankles too
    (:data:`jaxtrack.vision.detections.DETECTION_MARKERS`; jaxtrack's own ``.npz``: those of
    them it holds), the person inside ``--person`` in
    the first frame with anyone (else the most confident) followed
    (:func:`jaxtrack.vision.detections.follow_person`)."""
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.cli._pose import read_keypoints
    from jaxtrack.vision.detections import DETECTION_MARKERS
    from jaxtrack.vision.parts import DETECTION_PART_MARKERS

    single, markers = False, DETECTION_MARKERS
    if path.suffix == ".npz" and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as archive:
                single = "keypoints" in archive.files
                if "markers" in archive.files:  # jaxtrack's own: the markers it holds
                    markers = tuple(name for name in DETECTION_MARKERS
                                    if name in {str(held) for held in archive["markers"]})
        except (OSError, ValueError) as error:
            raise UserError(f"--keypoints: {path}: not a readable .npz ({error})") from None
    if single:
        markers = tuple(UPPER_BODY_12)
    points, confidence = read_keypoints(path, person, markers or DETECTION_MARKERS)
    if not any(name in markers for names in DETECTION_PART_MARKERS for name in names):
        raise UserError(f"--keypoints: {path} holds none of the head, wrists and ankles "
                        f"(it holds {', '.join(markers)}); the mixed-state tracker takes those")
    points = np.asarray(points, np.float64)
    confidence = np.nan_to_num(np.asarray(confidence, np.float64), nan=0.0)
    return points, confidence, markers


def _annotate(result, smoothed, factors):
    """The pipeline's ``annotate``: per frame the posture, its probability and the parts of each
    estimate (instantaneous, filtered, smoothed) in the video's pixels, and the smoothed posture
    as the overlay's label."""
    import numpy as np

    from jaxtrack.priors.postures import POSTURE_NAMES
    from jaxtrack.vision.histograms import FRAME_OK, STATUS_NAMES
    from jaxtrack.vision.parts import PART_NAMES

    filtered = result.estimates
    ok = np.asarray(filtered.silhouette) == FRAME_OK
    if not np.any(ok):
        raise ValueError("no frame has a silhouette (a static camera and a person who moves are "
                         "needed, or give --masks); nothing written")
    kinds = {"instantaneous": (filtered.instant_posture, filtered.instant_parts, None),
             "filtered": (filtered.posture, filtered.markers, filtered.posture_probability),
             "smoothed": (smoothed.posture, smoothed.markers, smoothed.posture_probability)}
    kinds = {kind: tuple(None if value is None else np.asarray(value) for value in values)
             for kind, values in kinds.items()}
    entries, labels = [], []
    for t in range(len(ok)):
        entry = {"silhouette": STATUS_NAMES[int(filtered.silhouette[t])],
                 "posture": {}, "posture_probability": {}, "parts": {}}
        for kind, (posture, parts, probability) in kinds.items():
            # the instantaneous estimate reads the frame's silhouette alone: none without one
            known = kind != "instantaneous" or ok[t]
            entry["posture"][kind] = POSTURE_NAMES[int(posture[t])] if known else None
            entry["parts"][kind] = {
                name: [round(float(x), 2), round(float(y), 2)]
                for name, (x, y) in zip(PART_NAMES, parts[t] / factors, strict=True)
            } if known else None
            if probability is not None:
                entry["posture_probability"][kind] = round(float(probability[t]), 4)
        entries.append(entry)
        labels.append(entry["posture"]["smoothed"].replace("_", " "))
    return entries, labels


def _refuse_detection_options(args: argparse.Namespace) -> None:
    """``--person`` needs ``--keypoints``; ``--detector`` and the detection density's fit
    options are the image trackers' (one line each)."""
    if getattr(args, "detector", None) is not None:
        raise UserError("--detector does not apply to --method mixed-state; run it with "
                        "--method latent (it writes DIR/detections.npz) and give that file "
                        "as --keypoints")
    for option, given in (("--no-fit", getattr(args, "no_fit", False)),
                          ("--fit-iterations", getattr(args, "fit_iterations", None)
                           is not None),
                          ("--guided", getattr(args, "guided", None) is not None)):
        if given:
            raise UserError(f"{option} does not apply to --method mixed-state (its detections "
                            f"replace part hypotheses; nothing is fitted)")
    if getattr(args, "person", None) is not None and args.keypoints is None:
        raise UserError("--person: it picks the person in --keypoints; give --keypoints "
                        "FILE_OR_FOLDER")


def track(args: argparse.Namespace) -> int:
    """``jaxtrack track --method mixed-state``: posture and parts through one video."""
    from jaxtrack.cli._track_image import frame_range, options_record, tracked_end

    started = time.perf_counter()
    record_options = options_record(args)
    # --keypoints is the other methods' option that mixed-state reads too (module docstring)
    refuse_other_methods(args, "track")
    _refuse_detection_options(args)
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
    start, stop = frame_range(args.frames)
    saved = _load_model(args.model)
    keypoints, markers = None, None
    if args.keypoints is not None:
        points, confidence, markers = _read_detections(args.keypoints, args.person)
        keypoints = (points, confidence)
    if not video_path.exists():
        raise UserError(f"--video {video_path}: no such video file")

    import jax.random as jr

    from jaxtrack.experiments.pipeline import track_video
    from jaxtrack.priors.postures import POSTURE_NAMES
    from jaxtrack.trackers.mixed_state import MixedStateModel, MixedStateTracker
    from jaxtrack.vision.histograms import FRAME_OK, STATUS_NAMES
    from jaxtrack.vision.parts import PART_NAMES

    end = tracked_end(video_path, stop)  # one past the last frame tracked
    if end is not None:  # the smoother keeps every frame's particles: checked before work
        frames = max(0, end - start)
        check_memory(int(BASE_BYTES + frames * particles * HISTORY_BYTES),
                     f"smoothing {frames} frames with {particles} particles",
                     "--particles/--frames")
        last = end - 1
        if given_masks is not None and len(given_masks) <= last:
            raise UserError(f"--masks {masks_path}: holds {len(given_masks)} masks, but video "
                            f"frame {last} is tracked (one mask per video frame, from its "
                            f"first)")
    if keypoints is not None and end is not None and len(keypoints[0]) < end:
        # frames past the detections' last: nothing detected there
        missing = end - len(keypoints[0])
        keypoints = (np.concatenate([keypoints[0], np.full((missing, *keypoints[0].shape[1:]),
                                                           np.nan)]),
                     np.concatenate([keypoints[1], np.zeros((missing, len(markers)))]))
    num_bins = (saved.model.num_features - 1) // 2
    tracker = MixedStateTracker(MixedStateModel(saved.model), particles, num_bins,
                                keep_history=True, keypoint_markers=markers)
    with pipeline_errors(f"--video {video_path}"):
        record = track_video(
            tracker, video_path, args.out, key=jr.PRNGKey(args.seed), max_size=args.max_size,
            start=start, max_frames=None if stop is None else stop - start, masks=given_masks,
            keypoints=keypoints, marker_names=PART_NAMES, seed=args.seed, smooth=True,
            annotate=_annotate,
            extra_record={"options": record_options, "model": str(args.model),
                          "silhouettes": ("median background" if masks_path is None
                                          else f"masks {masks_path}"),
                          "num_bins": num_bins, "posture_names": list(POSTURE_NAMES),
                          "part_names": list(PART_NAMES),
                          "posture_model": saved.description,
                          "detections": None if keypoints is None else {
                              "file": str(args.keypoints), "markers": list(markers),
                              "min_confidence": tracker.keypoint_confidence,
                              "person": args.person}})
    timings = record["timings"]
    frames = record["frames"]  # the per-frame entries _annotate wrote
    counts = collections.Counter(frame["posture"]["smoothed"] for frame in frames)
    shown = ", ".join(f"{name} {counts[name]}" for name in POSTURE_NAMES if counts[name])
    silhouettes = sum(frame["silhouette"] == STATUS_NAMES[FRAME_OK] for frame in frames)
    print(f"tracked {record['frames_tracked']} frames ({silhouettes} with a "
          f"silhouette): {1e3 * timings['seconds_per_frame']:.2f} ms/frame (compile "
          f"{timings['compile_seconds']:.1f} s); smoothed postures: {shown}; total "
          f"{time.perf_counter() - started:.1f} s")
    print(f"  wrote {record['paths']['overlay']}\n  wrote {record['paths']['json']}")
    return 0
