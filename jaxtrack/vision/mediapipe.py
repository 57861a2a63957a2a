"""MediaPipe Pose as a detector jaxtrack runs itself, and its landmarks as the tracker's markers.

MediaPipe never enters jaxtrack's venv: 0.10.21, the last wheel that carries its pose models,
needs numpy < 2 and jaxtrack's jax numpy >= 2. It runs in its own venv (``make detector``
makes ``.venv-mediapipe`` from ``jaxtrack/vision/requirements-mediapipe.txt``;
``$JAXTRACK_MEDIAPIPE_PYTHON`` may name another python that has it), through the worker script
``jaxtrack/vision/_mediapipe_worker.py`` (numpy and mediapipe only), spoken to through files
(a whole video: :func:`detect_pose`, :func:`run_mediapipe`) or a pipe (frame by frame, each on
the whole frame or on a region a tracker predicts: :class:`MediaPipeDetector`). The detector's
own time per frame (``seconds``, measured in the worker around MediaPipe's call) is reported
apart from the transfer (``wall_seconds``). Where it cannot run, :class:`DetectorUnavailableError`
says so in one line, naming ``make detector``.

The landmark map (MediaPipe's 33 pose landmarks; "left" is the person's left, as in
``UPPER_BODY_12``): shoulders, elbows, wrists and hips are MediaPipe's own; MediaPipe has no neck
or base of the skull, so, between the shoulders' midpoint S and the ears' midpoint E,
``neck = S + 1/3 (E − S)`` and ``head = S + 0.9 (E − S)`` (for an adult the ears are about
0.18 m above the shoulder line; the Pose2Sim reference's neck is 0.06 m and its head about
0.16 m above it: ``jaxtrack.evaluation.reference``); ``pelvis`` is the hips' midpoint and
``thorax = neck + 0.4 (pelvis − neck)``, as in the reference.
"""

from __future__ import annotations

import os
import struct
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = [
    "LANDMARKS", "REQUIREMENTS", "WORKER", "DetectorUnavailableError", "MediaPipeDetector",
    "detect_pose", "detected_keypoints", "keypoint_confidence", "mediapipe_python",
    "region_around", "run_mediapipe", "to_upper_body",
]

ROOT = Path(__file__).resolve().parents[2]
VENV = ROOT / ".venv-mediapipe"
"""The detector's venv ``make detector`` makes (in a source checkout)."""
WORKER = Path(__file__).resolve().with_name("_mediapipe_worker.py")
"""The script the detector's python runs."""
REQUIREMENTS = Path(__file__).resolve().with_name("requirements-mediapipe.txt")
"""What ``make detector`` installs in :data:`VENV`."""
MASKS = ROOT / "benchmarks" / "results" / "mediapipe_masks"
"""Where :func:`demo_masks` caches the Pose2Sim videos' person masks."""

LANDMARKS = {"nose": 0, "left_ear": 7, "right_ear": 8, "left_shoulder": 11,
             "right_shoulder": 12, "left_elbow": 13, "right_elbow": 14, "left_wrist": 15,
             "right_wrist": 16, "left_hip": 23, "right_hip": 24}
"""MediaPipe Pose landmark indices used."""
NECK_FRACTION, HEAD_FRACTION, THORAX_FRACTION = 1 / 3, 0.9, 0.4
SERVE_TIMEOUT = 120.0
"""Seconds the frame-by-frame worker may take to answer one frame (the first loads the
models)."""


class DetectorUnavailableError(RuntimeError):
    """The detector cannot run here (no venv, or its worker failed); one line naming what to
    do (``make detector``)."""


def mediapipe_python() -> Path:
    """``$JAXTRACK_MEDIAPIPE_PYTHON`` or ``.venv-mediapipe/bin/python``."""
    override = os.environ.get("JAXTRACK_MEDIAPIPE_PYTHON")
    return Path(override) if override else VENV / "bin" / "python"


def _python_or_raise(python: Path | None) -> Path:
    python = Path(python) if python is not None else mediapipe_python()
    if not python.exists():
        raise DetectorUnavailableError(f"no MediaPipe python at {python}: run `make detector` "
                                       f"(or set JAXTRACK_MEDIAPIPE_PYTHON)")
    return python


def to_upper_body(landmarks: np.ndarray) -> np.ndarray:
    """``(..., 33, 2)`` MediaPipe landmarks → ``(..., 12, 2)`` markers (``UPPER_BODY_12``)."""
    from jaxtrack.body import UPPER_BODY_12

    landmarks = np.asarray(landmarks, np.float64)

    def point(name):
        return landmarks[..., LANDMARKS[name], :]

    shoulders = 0.5 * (point("left_shoulder") + point("right_shoulder"))
    ears = 0.5 * (point("left_ear") + point("right_ear"))
    neck = shoulders + NECK_FRACTION * (ears - shoulders)
    pelvis = 0.5 * (point("left_hip") + point("right_hip"))
    named = {"head": shoulders + HEAD_FRACTION * (ears - shoulders), "neck": neck,
             "thorax": neck + THORAX_FRACTION * (pelvis - neck), "pelvis": pelvis}
    for side in ("right", "left"):
        for part in ("shoulder", "elbow", "wrist", "hip"):
            named[f"{side}_{part}"] = point(f"{side}_{part}")
    return np.stack([named[name] for name in UPPER_BODY_12], axis=-2)


def keypoint_confidence(visibility: np.ndarray) -> np.ndarray:
    """``(..., 33)`` MediaPipe landmark visibilities → ``(..., 12)`` confidences of the markers
    :func:`to_upper_body` makes: each marker's least visibility over the landmarks it is made
    from (the head, neck and thorax from the shoulders and ears, the thorax also from the hips,
    the pelvis from the hips)."""
    from jaxtrack.body import UPPER_BODY_12

    visibility = np.clip(np.nan_to_num(np.asarray(visibility, np.float64)), 0.0, 1.0)

    def least(*names):
        return np.min(np.stack([visibility[..., LANDMARKS[name]] for name in names]), axis=0)

    head = ("left_shoulder", "right_shoulder", "left_ear", "right_ear")
    named = {"head": least(*head), "neck": least(*head),
             "thorax": least(*head, "left_hip", "right_hip"),
             "pelvis": least("left_hip", "right_hip")}
    for side in ("right", "left"):
        for part in ("shoulder", "elbow", "wrist", "hip"):
            named[f"{side}_{part}"] = least(f"{side}_{part}")
    return np.stack([named[name] for name in UPPER_BODY_12], axis=-1)


def detected_keypoints(result: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(points (time, 12, 2), confidence (time, 12))`` of a :func:`detect_pose` result, as
    the keypoint term reads them (``jaxtrack.vision.keypoints``): the markers MediaPipe found
    in each frame (NaN and confidence 0 where it found no one; not filled in from other frames)
    and their confidences (:func:`keypoint_confidence`). One frame's answer
    (:meth:`MediaPipeDetector.detect`'s, ``found`` a scalar) gives ``(12, 2)`` and ``(12,)``."""
    if np.ndim(result["found"]) == 0:
        points, confidence = detected_keypoints(
            {key: np.asarray(result[key])[None] for key in ("found", "landmarks", "visibility")})
        return points[0], confidence[0]
    found = np.asarray(result["found"], bool)
    points = to_upper_body(result["landmarks"])
    confidence = np.where(found[:, None], keypoint_confidence(result["visibility"]), 0.0)
    points = np.where((confidence > 0)[..., None] & np.isfinite(points), points, np.nan)
    return points, np.where(np.all(np.isfinite(points), -1), confidence, 0.0)


def _regions(regions, num_frames: int) -> np.ndarray | None:
    if regions is None:
        return None
    boxes = np.asarray(regions, np.float64)
    if boxes.shape == (4,):
        boxes = np.broadcast_to(boxes, (num_frames, 4))
    if boxes.shape != (num_frames, 4) or not np.isfinite(boxes).all():
        raise ValueError(f"regions must be finite (4,) or ({num_frames}, 4) boxes x0, y0, x1, "
                         f"y1, got shape {np.shape(regions)}")
    if np.any(boxes[:, 2] <= boxes[:, 0]) or np.any(boxes[:, 3] <= boxes[:, 1]):
        raise ValueError("regions: every box needs x1 > x0 and y1 > y0")
    return np.ascontiguousarray(boxes)


def region_around(markers, frame_size: tuple[int, int], *, margin: float = 0.5) -> np.ndarray:
    """A detection region ``(x0, y0, x1, y1)`` around a pose's markers ``(markers, 2)`` pixels
    (e.g. a tracker's prediction for the next frame), for :meth:`MediaPipeDetector.detect`:
    their bounding box grown by ``margin`` times its longer side on every side (MediaPipe
    wants the whole person, and the prediction is not exact), made square (its pose detector
    works on square crops), clipped to the frame ``(width, height)``. Missing (NaN) markers are
    left out; with none finite the whole frame."""
    width, height = (float(v) for v in frame_size)
    points = np.asarray(markers, np.float64).reshape(-1, 2)
    points = points[np.isfinite(points).all(-1)]
    if len(points) == 0:
        return np.array([0.0, 0.0, width, height])
    low, high = points.min(0), points.max(0)
    centre, side = 0.5 * (low + high), float((high - low).max())
    half = 0.5 * side + margin * side + 1.0
    box = np.r_[centre - half, centre + half]
    return np.clip(box, 0.0, [width, height, width, height])


def _check_frames(frames) -> np.ndarray:
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.shape[0] == 0:
        raise ValueError(f"frames must be (time, height, width, 3) RGB, got shape {frames.shape}")
    return np.ascontiguousarray(frames, np.uint8)


def detect_pose(frames: np.ndarray, *, regions=None, model_complexity: int = 1,
                static: bool = False, segmentation: bool = False,
                timeout: float | None = 1800.0, python: Path | None = None,
                worker: Path = WORKER) -> dict:
    """MediaPipe Pose on a whole video in one run of its worker.

    Args:
        frames: ``(time, height, width, 3)`` uint8 RGB.
        regions: None (full frames), or boxes ``x0, y0, x1, y1`` pixels, ``(4,)`` for every
            frame or ``(time, 4)``: each frame is detected on its crop only.
        model_complexity: 0 or 1 (the models inside the wheel).
        static: every frame on its own instead of MediaPipe's video mode.
        segmentation: also return the person's masks.
        timeout: seconds for the whole run.
        python, worker: the detector's python (default :func:`mediapipe_python`) and script.

    Returns:
        ``landmarks`` (time, 33, 2) frame pixels (NaN where no one was found), ``visibility``
        (time, 33), ``found`` (time,), ``seconds`` (time − 1,) MediaPipe's own time per frame
        after the first, ``first_seconds``, ``wall_seconds`` (the whole run, with starting the
        venv and the transfers), ``version``, ``summary``; with ``segmentation`` ``masks``.

    Raises:
        DetectorUnavailableError: no detector python, or the worker failed or timed out.
        ValueError: bad ``frames`` or ``regions``.
    """
    frames = _check_frames(frames)
    boxes = _regions(regions, len(frames))
    python = _python_or_raise(python)
    inputs = {"frames": frames, "model_complexity": np.int64(model_complexity),
              "segmentation": np.int64(segmentation), "static": np.int64(static)}
    if boxes is not None:
        inputs["regions"] = boxes
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="jaxtrack-detector-") as folder:
        in_path, out_path = Path(folder) / "in.npz", Path(folder) / "out.npz"
        np.savez(in_path, **inputs)
        command = [str(python), str(worker), str(in_path), str(out_path)]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise DetectorUnavailableError(f"MediaPipe run timed out after {timeout:g} s") from None
        except OSError as error:
            raise DetectorUnavailableError(f"cannot run {python}: {error}; run `make detector`"
                                           ) from None
        if done.returncode != 0 or not out_path.exists():
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            raise DetectorUnavailableError(
                f"MediaPipe run failed ({done.returncode}): {' | '.join(tail)}; check the "
                f"detector's venv (`make detector`)")
        result = _read_npz(out_path)
    result["wall_seconds"] = time.perf_counter() - started
    result["summary"] = done.stdout.strip()
    return result


def run_mediapipe(frames: np.ndarray, *, model_complexity: int = 1,
                  timeout: float | None = 1800.0, segmentation: bool = False) -> dict:
    """:func:`detect_pose` on full frames, plus ``markers`` (time, 12, 2) (frames without a
    person hold the last detection, or the next one before the first: ``filled`` counts them);
    or ``{"skipped": reason}`` when the detector cannot run or finds no person."""
    try:
        result = detect_pose(frames, model_complexity=model_complexity, timeout=timeout,
                             segmentation=segmentation)
    except DetectorUnavailableError as error:
        return {"skipped": str(error)}
    found = np.asarray(result["found"], bool)
    if not found.any():
        return {"skipped": "MediaPipe found no person in any frame", **result}
    markers = to_upper_body(result["landmarks"])
    index = np.where(found, np.arange(len(found)), -1)
    index = np.maximum.accumulate(index)                      # the last detection so far
    index = np.where(index < 0, int(np.argmax(found)), index)  # before the first: the first
    result["markers"] = markers[index]
    result["filled"] = int((~found).sum())
    return result


def _read_npz(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as data:
        return {key: (data[key].item() if data[key].ndim == 0 else data[key])
                for key in data.files}


class MediaPipeDetector:
    """MediaPipe Pose frame by frame through a pipe to one worker process, so a tracker can ask
    for each frame on the region it predicts (tracker-guided detection) without reloading the
    models. Use as a context manager, or call :meth:`close`.

    Args:
        model_complexity, static, segmentation: as :func:`detect_pose`.
        python, worker: the detector's python (default :func:`mediapipe_python`) and script.

    Raises:
        DetectorUnavailableError: no detector python, or the worker does not start.
    """

    def __init__(self, *, model_complexity: int = 1, static: bool = False,
                 segmentation: bool = False, python: Path | None = None,
                 worker: Path = WORKER):
        python = _python_or_raise(python)
        self.version = None
        self._options = tempfile.NamedTemporaryFile(prefix="jaxtrack-detector-", suffix=".npz",
                                                    delete=False)
        with self._options as handle:
            np.savez(handle, model_complexity=np.int64(model_complexity),
                     segmentation=np.int64(segmentation), static=np.int64(static))
        self._errors = tempfile.TemporaryFile()
        try:
            self._process = subprocess.Popen(
                [str(python), str(worker), "--serve", self._options.name],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._errors)
        except OSError as error:
            self._cleanup()
            raise DetectorUnavailableError(f"cannot run {python}: {error}; run `make detector`"
                                           ) from None

    def __enter__(self) -> MediaPipeDetector:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _failure(self, what: str) -> DetectorUnavailableError:
        self._errors.seek(0)
        tail = self._errors.read().decode(errors="replace").strip().splitlines()[-3:]
        self.close()
        return DetectorUnavailableError(f"MediaPipe worker {what}: {' | '.join(tail)}; check "
                                        f"the detector's venv (`make detector`)")

    def detect(self, frame: np.ndarray, region=None) -> dict:
        """One frame ``(height, width, 3)`` uint8 RGB, whole or on ``region`` ``(x0, y0, x1,
        y1)`` pixels: ``landmarks`` (33, 2) frame pixels (NaN where no one was found),
        ``visibility`` (33,), ``found``, ``seconds`` (MediaPipe's own time), ``wall_seconds``
        (with the transfer) (and ``mask``)."""
        import io

        from jaxtrack.vision._mediapipe_worker import crop_box

        frame = _check_frames(np.asarray(frame)[None])[0]
        height, width = frame.shape[:2]
        # only the region goes down the pipe (the worker's own crop, so the same pixels)
        x0, y0, x1, y1 = crop_box(None if region is None else _regions(region, 1)[0],
                                  height, width)
        request = {"frame": np.ascontiguousarray(frame[y0:y1, x0:x1])}
        if self._process is None or self._process.poll() is not None:
            raise self._failure("is not running")
        started = time.perf_counter()
        buffer = io.BytesIO()
        np.savez(buffer, **request)
        payload = buffer.getvalue()
        try:
            self._process.stdin.write(struct.pack("<Q", len(payload)) + payload)
            self._process.stdin.flush()
            header = self._process.stdout.read(8)
            if len(header) < 8:
                raise self._failure("stopped")
            answer = self._process.stdout.read(struct.unpack("<Q", header)[0])
        except (BrokenPipeError, OSError):
            raise self._failure("stopped") from None
        with np.load(io.BytesIO(answer), allow_pickle=False) as data:
            result = {key: (data[key].item() if data[key].ndim == 0 else data[key])
                      for key in data.files}
        if "error" in result:
            raise ValueError(f"MediaPipe worker refused the frame: {result['error']}")
        self.version = result.pop("version", self.version)
        result["landmarks"] = result["landmarks"] + np.array([x0, y0], np.float64)
        if "mask" in result:
            mask = np.zeros((height, width), bool)
            mask[y0:y1, x0:x1] = result["mask"]
            result["mask"] = mask
        result["wall_seconds"] = time.perf_counter() - started
        return result

    def _cleanup(self) -> None:
        self._errors.close()
        Path(self._options.name).unlink(missing_ok=True)

    def close(self) -> None:
        """End the worker (an empty request) and remove its files."""
        process, self._process = getattr(self, "_process", None), None
        if process is not None:
            try:
                if process.poll() is None:
                    process.stdin.write(struct.pack("<Q", 0))
                    process.stdin.flush()
                process.stdin.close()
                process.wait(timeout=30)
            except (BrokenPipeError, OSError, subprocess.TimeoutExpired):
                process.kill()
                process.wait()
            process.stdout.close()
            self._cleanup()


def mask_array(images: np.ndarray) -> np.ndarray | dict:
    """MediaPipe's person masks ``(time, height, width)`` bool of ``images`` ``(time, height,
    width, 3)`` uint8 RGB, or ``{"skipped": reason}`` when MediaPipe cannot run."""
    result = run_mediapipe(images, segmentation=True)
    return result if "skipped" in result else np.asarray(result["masks"], bool)


def masks_or_exit(images: np.ndarray, name: str) -> np.ndarray:
    """:func:`mask_array`, or exit with the reason (naming ``name``, the sequence) where
    MediaPipe cannot run."""
    masks = mask_array(images)
    if isinstance(masks, dict):
        raise SystemExit(f"--masks mediapipe, {name}: {masks['skipped']}")
    return masks


def add_mask_options(parser) -> None:
    """``--masks``, ``--foreground-weight`` and ``--coverage-weight``: the limbs+edges
    likelihood's foreground from MediaPipe's person masks per frame, its weight μ, and the
    weight ν of its coverage term, which reads the masks (checked by
    :func:`check_mask_options`)."""
    parser.add_argument("--masks", choices=("none", "mediapipe"), default="none",
                        help="limbs+edges' foreground from MediaPipe's person masks per frame "
                             "(its venv) instead of the median background")
    parser.add_argument("--foreground-weight", type=float, default=None, metavar="MU",
                        help="limbs+edges' foreground weight (default the likelihood's)")
    parser.add_argument("--coverage-weight", type=float, default=None, metavar="NU",
                        help="limbs+edges' coverage term's weight, which charges the mask for "
                             "what the body leaves unexplained (needs --masks; default off)")


def check_mask_options(parser, args) -> str:
    """Refuse a bad ``--foreground-weight`` or ``--coverage-weight`` in one line (the latter
    needs ``--masks``); return the output name's suffix for the options (``-masks``,
    ``-muMU``, ``-nuNU``)."""
    for option, weight in (("--foreground-weight", args.foreground_weight),
                           ("--coverage-weight", args.coverage_weight)):
        if weight is not None and not (np.isfinite(weight) and weight >= 0):
            parser.error(f"{option} must be a non-negative number, got {weight}")
    if args.coverage_weight and args.masks == "none":
        parser.error("--coverage-weight: the coverage term reads the person's masks; give "
                     "--masks mediapipe")
    return (("-masks" if args.masks != "none" else "")
            + (f"-mu{args.foreground_weight:g}" if args.foreground_weight is not None else "")
            + (f"-nu{args.coverage_weight:g}" if args.coverage_weight is not None else ""))


def likelihood_options(args) -> dict:
    """The ``jaxtrack.trackers.Likelihood`` settings the mask options give (those set)."""
    return {name: value for name, value in (("foreground_weight", args.foreground_weight),
                                            ("coverage_weight", args.coverage_weight))
            if value is not None}


def _decoded(video: Path, max_size: int) -> tuple[np.ndarray, int]:
    """Every frame of ``video``, downscaled so its longer side is at most ``max_size``, and the
    video's own width."""
    from jaxtrack.vision.video import read_video

    height, width = read_video(video, max_frames=1).frames.shape[1:3]
    return read_video(video, scale=min(1.0, max_size / max(width, height))).frames, width


def person_masks(video: Path, out: Path, *, max_size: int = 640) -> Path | dict:
    """MediaPipe's person masks for every frame of ``video``, decoded so its longer side is at
    most ``max_size``, written to ``out`` (:func:`jaxtrack.vision.write_masks`; ``jaxtrack
    track --masks`` reads it) unless ``out`` is already there. Returns ``out``, or
    ``{"skipped": reason}`` when MediaPipe cannot run or finds no person."""
    from jaxtrack.vision.masks import write_masks

    if out.is_file():
        return out
    masks = mask_array(_decoded(video, max_size)[0])
    if isinstance(masks, dict):
        return masks
    out.parent.mkdir(parents=True, exist_ok=True)
    return write_masks(out, masks)


def person_keypoints(video: Path, out: Path, *, max_size: int = 960) -> Path | dict:
    """MediaPipe's keypoints of every frame of ``video`` (decoded so its longer side is at most
    ``max_size``), in the video's own pixels with their confidences, written to ``out``
    (:func:`jaxtrack.vision.keypoints.write_keypoints`; ``jaxtrack track --keypoints`` reads
    it). Returns ``out``, or ``{"skipped": reason}`` when MediaPipe cannot run or finds no
    person."""
    from jaxtrack.vision.keypoints import write_keypoints

    frames, width = _decoded(video, max_size)
    result = run_mediapipe(frames)
    if "skipped" in result:
        return result
    points, confidence = detected_keypoints(result)
    out.parent.mkdir(parents=True, exist_ok=True)
    return write_keypoints(out, points * (width / frames.shape[2]), confidence)


def demo_masks(folder: Path, camera: str, cache: Path = MASKS) -> Path | dict:
    """:func:`person_masks` of a Pose2Sim take's video (``folder/videos/CAMERA.mp4``), cached
    in ``cache`` under the take's and the camera's names."""
    return person_masks(folder / "videos" / f"{camera}.mp4", cache / f"{folder.name}_{camera}.npz")
