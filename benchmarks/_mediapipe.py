"""Run MediaPipe Pose (``_mediapipe_reference.py``) in its own venv, and map its landmarks to the
tracker's 12 markers.

MediaPipe never enters the jaxtrack venv. Create its venv once with ``make bench-mediapipe-env``
(``.venv-mediapipe``, ``benchmarks/requirements-mediapipe.txt``); ``JAXTRACK_MEDIAPIPE_PYTHON``
may name another python that has it.

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
from pathlib import Path

import numpy as np

from benchmarks._common import run_in_venv

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv-mediapipe"
SCRIPT = Path(__file__).resolve().parent / "_mediapipe_reference.py"
MASKS = Path(__file__).resolve().parent / "results" / "mediapipe_masks"
"""Where :func:`demo_masks` caches the Pose2Sim videos' person masks."""

LANDMARKS = {"nose": 0, "left_ear": 7, "right_ear": 8, "left_shoulder": 11,
             "right_shoulder": 12, "left_elbow": 13, "right_elbow": 14, "left_wrist": 15,
             "right_wrist": 16, "left_hip": 23, "right_hip": 24}
"""MediaPipe Pose landmark indices used."""
NECK_FRACTION, HEAD_FRACTION, THORAX_FRACTION = 1 / 3, 0.9, 0.4


def mediapipe_python() -> Path:
    """``$JAXTRACK_MEDIAPIPE_PYTHON`` or ``.venv-mediapipe/bin/python``."""
    override = os.environ.get("JAXTRACK_MEDIAPIPE_PYTHON")
    return Path(override) if override else VENV / "bin" / "python"


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
    """``(points (time, 12, 2), confidence (time, 12))`` of a :func:`run_mediapipe` result, as
    the keypoint term reads them (``jaxtrack.vision.keypoints``): the markers MediaPipe found
    in each frame (NaN and confidence 0 where it found no one; not filled in from other frames)
    and their confidences (:func:`keypoint_confidence`)."""
    found = np.asarray(result["found"], bool)
    points = to_upper_body(result["landmarks"])
    confidence = np.where(found[:, None], keypoint_confidence(result["visibility"]), 0.0)
    points = np.where((confidence > 0)[..., None] & np.isfinite(points), points, np.nan)
    return points, np.where(np.all(np.isfinite(points), -1), confidence, 0.0)


def run_mediapipe(frames: np.ndarray, *, model_complexity: int = 1,
                  timeout: float | None = 1800.0, segmentation: bool = False) -> dict:
    """MediaPipe Pose on ``frames`` (time, height, width, 3) uint8 RGB, in its venv.

    Returns the script's outputs (``landmarks``, ``visibility``, ``found``, ``seconds``,
    ``first_seconds``, ``version``; with ``segmentation`` also ``masks`` (time, height, width)
    bool, the person by MediaPipe's segmentation) plus ``markers`` (time, 12, 2) (frames without
    a person hold the last detection, or the next one before the first: ``filled`` counts them)
    and ``summary``, or ``{"skipped": reason}`` when its python is missing or the run fails.
    """
    python = mediapipe_python()
    if not python.exists():
        return {"skipped": f"no MediaPipe python at {python} (make bench-mediapipe-env)"}
    inputs = {"frames": np.asarray(frames, np.uint8),
              "model_complexity": np.int64(model_complexity),
              "segmentation": np.int64(segmentation)}
    result = run_in_venv(python, SCRIPT, inputs, output="out.npz", read=_read_npz,
                         label="MediaPipe", timeout=timeout)
    if "skipped" in result:
        return result
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
    from jaxtrack.vision import read_video

    height, width = read_video(video, max_frames=1).frames.shape[1:3]
    return read_video(video, scale=min(1.0, max_size / max(width, height))).frames, width


def person_masks(video: Path, out: Path, *, max_size: int = 640) -> Path | dict:
    """MediaPipe's person masks for every frame of ``video``, decoded so its longer side is at
    most ``max_size``, written to ``out`` (:func:`jaxtrack.vision.write_masks`; ``jaxtrack
    track --masks`` reads it) unless ``out`` is already there. Returns ``out``, or
    ``{"skipped": reason}`` when MediaPipe cannot run or finds no person."""
    from jaxtrack.vision import write_masks

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


def demo_masks(folder: Path, camera: str) -> Path | dict:
    """:func:`person_masks` of a Pose2Sim take's video (``folder/videos/CAMERA.mp4``), cached
    in :data:`MASKS` under the take's and the camera's names."""
    return person_masks(folder / "videos" / f"{camera}.mp4", MASKS / f"{folder.name}_{camera}.npz")
