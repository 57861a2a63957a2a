"""``jaxtrack track``'s detections for the image trackers (latent, CONDENSATION, MHT):
``--detector mediapipe`` runs MediaPipe Pose and writes ``DIR/detections.npz``; detections
(``--keypoints`` or the detector's) are scored by the normalised detection density
(:mod:`jaxtrack.likelihoods.detections`) times the image likelihood, fitted on the video
first (``--no-fit``, ``--fit-iterations``:
:func:`jaxtrack.experiments.detection_tracking.fit_on_keypoints`).

Before tracking, the detector runs on full frames (longer side at most ``--max-size``, through
files: ``jaxtrack.vision.mediapipe.detect_pose``); with ``--person``, frames whose detection is
not the person (nobody, or a jump away from their last detected pose, by
:func:`jaxtrack.vision.detections.follow_person`'s gate) are detected again on a square around
that pose (``region_around``, one ``MediaPipeDetector`` worker). The first pose is read from
these detections and the density is fitted on them: a fit needs the whole video's detections.

Tracker-guided detection (``--guided``; the default with ``--person``, since a named person is
one among others; off without it): while tracking, the detector also runs on every frame on the
region the tracker predicts (its last two estimates at constant velocity, grown by
``region_around``'s margin), inside the compiled scan, and the density's mixture over people
weighs that detection beside the one above, the other being a passer-by
(:mod:`jaxtrack.experiments._guided_detection`). ``track.json`` records per frame the region,
its source (``tracker prediction``, or ``full frame`` while the tracker holds no estimate) and
the detection followed, and the detector's time apart from the tracker's (``timings``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import UserError, integer, one_line

__all__ = ["DETECTIONS_FILE", "FIT_ITERATIONS", "FIT_PARTICLES", "add_detection_options",
           "check_detection_options", "detect_video", "detection_tracker", "guided"]

DETECTIONS_FILE = "detections.npz"
"""What ``--detector`` writes into ``--out`` (``jaxtrack.vision.detections.write_detections``;
``--keypoints`` reads it)."""
FIT_ITERATIONS = 15
"""Adam steps of the fit by default (each a filter run forward and backward): on the Pose2Sim
demo's detections the log-evidence rises most in the first ten (docs/detections.md)."""
FIT_PARTICLES = 200
"""Particles per filter run of the fit (fewer where the tracker has fewer)."""
FIT_LEARNING_RATE = 0.1
"""Adam's step in the fitted logarithms (logit for the outlier rate): about e^1.5 in 15 steps."""
GATE = 0.5
"""A detection farther than this many of the person's keypoint box diagonals (median over the
markers) from their last detected pose is not the person (as ``follow_person``)."""
MIN_SIZE = 0.05
"""The least box diagonal :data:`GATE` is taken of, a fraction of the frame's diagonal (a
person whose keypoints nearly coincide would otherwise move nowhere)."""


def add_detection_options(parser: argparse.ArgumentParser) -> None:
    """``--detector``, ``--no-fit`` and ``--fit-iterations``."""
    parser.add_argument("--detector", choices=("mediapipe",), default=None,
                        help="latent, condensation, mht: run a pose detector over the video "
                        "first (MediaPipe Pose, in its own venv: make detector), write its "
                        f"detections to DIR/{DETECTIONS_FILE} and track them as --keypoints")
    parser.add_argument("--guided", action=argparse.BooleanOptionalAction, default=None,
                        help="with --detector: while tracking, detect again on the region the "
                        "tracker predicts, and let the detection density choose between that "
                        "detection and the full frame's (default: on with --person)")
    parser.add_argument("--no-image", action="store_true",
                        help="with detections: score them alone, without the image likelihood "
                        "(--likelihood), so that no video frame is read by the tracker")
    parser.add_argument("--no-fit", action="store_true",
                        help="with detections: keep the detection density's hand-set "
                        "parameters instead of fitting them on the video")
    parser.add_argument("--fit-iterations", type=integer(1), default=None, metavar="N",
                        help="with detections: Adam steps of the fit of the detection "
                        f"density's scales, outlier rate and dynamics noise by the filter's "
                        f"log-evidence (default {FIT_ITERATIONS})")


def check_detection_options(args: argparse.Namespace) -> None:
    """Refuse, in one line and before any work, detection options without detections, both
    sources at once, fit options beside ``--keypoint-weight`` (the image likelihood's keypoint
    term, which is not fitted), and ``--detector`` without the detector's venv."""
    from jaxtrack.vision.mediapipe import mediapipe_python

    if args.keypoints is not None and args.detector is not None:
        raise UserError("--detector: give --keypoints (detections you have) or --detector (run "
                        "one), not both")
    if args.keypoints is None and args.detector is None:
        for option, given in (("--keypoint-weight", args.keypoint_weight is not None),
                              ("--init keypoints", args.init == "keypoints"),
                              ("--person", args.person is not None),
                              ("--no-fit", args.no_fit), ("--no-image", args.no_image),
                              ("--fit-iterations", args.fit_iterations is not None)):
            if given:
                raise UserError(f"{option}: it reads a detector's keypoints; give --keypoints "
                                f"FILE_OR_FOLDER or --detector mediapipe")
    if args.keypoint_weight is not None:
        for option, given in (("--no-fit", args.no_fit), ("--no-image", args.no_image),
                              ("--fit-iterations", args.fit_iterations is not None)):
            if given:
                raise UserError(f"{option}: --keypoint-weight scores the keypoints by the image "
                                f"likelihood's keypoint term, which is not fitted; leave one "
                                f"of them out")
    if getattr(args, "guided", None) and (args.detector is None
                                          or args.keypoint_weight is not None):
        raise UserError("--guided: it runs the detector on the region the tracker predicts, "
                        "for the detection density: give --detector mediapipe, without "
                        "--keypoint-weight")
    python = mediapipe_python()
    if args.detector == "mediapipe" and not python.exists():
        raise UserError(f"--detector mediapipe: no MediaPipe python at {python}; run `make "
                        f"detector` (or set JAXTRACK_MEDIAPIPE_PYTHON)")


def _not_the_person(points: np.ndarray, last: np.ndarray | None, smallest: float) -> bool:
    """Whether a frame's detected markers ``(12, 2)`` (NaN where absent) are not the person
    last seen at ``last``, whose box diagonal is taken as ``smallest`` pixels at least."""
    found = np.all(np.isfinite(points), -1)
    if not found.any():
        return True
    if last is None:
        return False
    both = found & np.all(np.isfinite(last), -1)
    if not both.any():
        return True
    known = last[np.all(np.isfinite(last), -1)]
    diagonal = float(np.hypot(*(known.max(0) - known.min(0))))
    distance = float(np.median(np.linalg.norm(points[both] - last[both], axis=-1)))
    return distance > GATE * max(diagonal, smallest)


def detect_video(args: argparse.Namespace, start: int, count: int | None,
                 box: tuple[float, float, float, float] | None) -> tuple[Path, dict]:
    """Run ``--detector`` over the frames tracked into ``DIR/detections.npz`` (a row per video
    frame; those before ``start`` hold nobody). Returns its path and ``track.json``'s record."""
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.vision import mediapipe
    from jaxtrack.vision.detections import Detections, write_detections
    from jaxtrack.vision.video import VideoError, read_video

    started = time.perf_counter()
    try:
        probe = read_video(args.video, start=start, max_frames=1)
        width, height = probe.image_size
        scale = min(1.0, args.max_size / max(width, height))
        frames = read_video(args.video, start=start, max_frames=count, scale=scale).frames
    except VideoError as error:
        raise UserError(f"--video: {one_line(error)}") from None
    decode_seconds = time.perf_counter() - started
    factors = np.array([frames.shape[2] / width, frames.shape[1] / height])
    try:
        result = mediapipe.detect_pose(frames, worker=mediapipe.WORKER)
    except mediapipe.DetectorUnavailableError as error:
        raise UserError(f"--detector mediapipe: {one_line(error)}") from None
    points, confidence = mediapipe.detected_keypoints(result)  # decoded pixels
    seconds = float(result.get("first_seconds", 0.0)) + float(np.sum(result["seconds"]))
    redetected, wall = [], float(result["wall_seconds"])
    if box is not None:
        points, confidence, redetected, more = _guided(frames, points, confidence, box, factors)
        seconds, wall = seconds + more[0], wall + more[1]
    # back to the video's own pixels (pixel centres: (p + 0.5) / factor - 0.5)
    points = (points + 0.5) / factors - 0.5
    total = start + len(frames)
    all_points = np.full((total, 1, len(UPPER_BODY_12), 2), np.nan)
    all_confidence = np.zeros((total, 1, len(UPPER_BODY_12)))
    all_points[start:, 0], all_confidence[start:, 0] = points, confidence
    people = (all_confidence[:, 0] > 0).any(-1).astype(np.int64)
    path = Path(args.out) / DETECTIONS_FILE
    Path(args.out).mkdir(parents=True, exist_ok=True)
    write_detections(path, Detections(all_points, all_confidence, people, UPPER_BODY_12,
                                      "MEDIAPIPE_33", (float(width), float(height)),
                                      source=f"MediaPipe {result.get('version', '')}"))
    record = {"name": "mediapipe", "version": str(result.get("version", "")),
              "file": str(path), "frames": len(frames), "decoded_size": frames.shape[2:0:-1],
              "frames_with_person": int(people[start:].sum()),
              "redetected_frames": [start + index for index in redetected],
              "seconds": round(seconds, 3), "wall_seconds": round(wall, 3),
              "decode_seconds": round(decode_seconds, 3)}
    print(f"{args.video}: MediaPipe found the person in {record['frames_with_person']} of "
          f"{len(frames)} frames ({len(redetected)} detected again around the person) in "
          f"{seconds:.1f} s of detector time ({wall:.1f} s with starting it); wrote {path}",
          flush=True)
    return path, record


def _guided(frames, points, confidence, box, factors):
    """Frames whose full-frame detection is not the person, detected again around the
    person's last detected pose (module docstring). Returns the points and confidences, the
    frames detected again, and ``(detector seconds, wall seconds)`` of doing so."""
    from jaxtrack.vision import mediapipe
    from jaxtrack.vision.detections import _box_of, _overlap

    scaled = np.asarray(box, np.float64) * np.r_[factors, factors]
    corners = scaled.reshape(2, 2)
    size = (frames.shape[2], frames.shape[1])
    smallest = MIN_SIZE * float(np.hypot(*size))
    # the box given is around the person already: detected on it grown by a tenth (a square
    # around it, region_around's, would take in whoever stands beside them)
    grown = np.clip(scaled + 0.1 * np.r_[-1, -1, 1, 1] * np.tile(np.ptp(corners, 0), 2), 0,
                    np.tile(size, 2))

    def inside(found) -> bool:  # a detection (12, 2) of the person in the box given
        own = _box_of(found)
        return own is not None and _overlap(scaled, own + [-1, -1, 1, 1]) >= 0.5

    last = points[0] if inside(points[0]) else None
    redone, seconds, wall = [], 0.0, 0.0
    detector = None
    try:
        for t in range(len(frames)):
            if not (_not_the_person(points[t], last, smallest) or last is None):
                last = np.where(np.isfinite(points[t]), points[t], last)
                continue
            if detector is None:
                detector = mediapipe.MediaPipeDetector(static=True, worker=mediapipe.WORKER)
            region = grown if last is None else mediapipe.region_around(last, size)
            found = detector.detect(frames[t], region)
            seconds, wall = seconds + float(found["seconds"]), wall + found["wall_seconds"]
            new_points, new_confidence = mediapipe.detected_keypoints(found)
            if (inside(new_points) if last is None
                    else not _not_the_person(new_points, last, smallest)):
                points[t], confidence[t] = new_points, new_confidence
                last = np.where(np.isfinite(points[t]), points[t], last if last is not None
                                else points[t])
            else:  # neither is the person: no detection of them here
                points[t], confidence[t] = np.nan, 0.0
            redone.append(t)
    except mediapipe.DetectorUnavailableError as error:
        raise UserError(f"--detector mediapipe: {one_line(error)}") from None
    finally:
        if detector is not None:
            detector.close()
    return points, confidence, redone, (seconds, wall)


def detection_tracker(args, tracker, keypoints, factors, tracked_size, pose, start: int,
                      end: int | None, fitting_tracker=None):
    """The tracker the video pipeline runs on detections (``ChunkDetections``), its density
    fitted on the frames tracked unless ``--no-fit``; and ``track.json``'s record of it."""
    import jax.random as jr

    from jaxtrack.experiments.detection_tracking import (
        ChunkDetections,
        fit_on_keypoints,
        fit_record,
    )

    hand_set = tracker.likelihood.detections
    record = {"likelihood": "detection density x " + tracker.likelihood.image.kind
              if tracker.likelihood.image is not None else "detection density", "fit": None}
    if not args.no_fit:
        stop = len(keypoints[0]) if end is None else end
        points = keypoints[0][start:stop] * factors
        particles = min(FIT_PARTICLES, args.particles) if args.method != "mht" \
            else FIT_PARTICLES
        iterations = args.fit_iterations or FIT_ITERATIONS
        print(f"fitting the detection density on {stop - start} frames ({iterations} "
              f"iterations, {particles} particles)", flush=True)
        try:
            tracker, fit = fit_on_keypoints(
                tracker, jr.fold_in(jr.PRNGKey(args.seed), 1), points,
                keypoints[1][start:stop], tracked_size, np.asarray(pose) * factors,
                iterations=iterations, num_particles=particles,
                learning_rate=FIT_LEARNING_RATE, fitting_tracker=fitting_tracker)
        except ValueError as error:
            raise UserError(f"--keypoints: the fit failed: {one_line(error)}; give --no-fit"
                            ) from None
        record["fit"] = fit_record(fit, hand_set)
        fitted = record["fit"]["fitted"]
        print(f"  fitted in {fit.seconds:.1f} s (+ {fit.compile_seconds:.1f} s compiling): "
              f"log-evidence {record['fit']['log_evidence_first']:.1f} -> "
              f"{record['fit']['log_evidence_final']:.1f}; sigma0 {fitted['pixel_noise']:.2f} "
              f"px, outlier rate {fitted['outlier_rate']:.3f}, noise "
              f"x{fitted['noise_factor']:.2f}", flush=True)
    chunked = ChunkDetections(tracker, (float(tracked_size[0]), float(tracked_size[1])))
    if not guided(args):
        record["guided"] = None
        return chunked, record
    from jaxtrack.experiments._guided_detection import GuidedDetections, RegionGuide
    from jaxtrack.vision import mediapipe

    def open_detector():  # on every frame its own region: MediaPipe's static mode
        return mediapipe.MediaPipeDetector(static=True, worker=mediapipe.WORKER)

    record["guided"] = ("while tracking, the detector also runs on the region the tracker "
                        "predicts; the density weighs that detection beside the one before "
                        "tracking (track.json: guided_detection)")
    return GuidedDetections(chunked, RegionGuide(open_detector)), record


def guided(args: argparse.Namespace) -> bool:
    """Whether the tracking pass runs the detector on the tracker's predicted region:
    ``--guided``, or by default with ``--detector`` and ``--person`` (module docstring)."""
    if getattr(args, "detector", None) is None:
        return False
    choice = getattr(args, "guided", None)
    if choice is None:  # --keypoint-weight scores keypoints by the image likelihood instead
        return args.person is not None and getattr(args, "keypoint_weight", None) is None
    return bool(choice)
