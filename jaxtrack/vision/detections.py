"""A pose detector's output, read from the files detectors write, as the body's markers.

A per-frame detector (OpenPose, RTMPose through RTMLib, Sports2D and Pose2Sim, MediaPipe, any
COCO-style network) finds, in each frame on its own, every person it can and a set of keypoints
for each, with a confidence per keypoint. :class:`Detections` holds them for a whole sequence,
mapped onto the body's markers (``jaxtrack.body.SPM_MARKERS`` by default, optionally the knees
and ankles too): ``points`` ``(time, people, markers, 2)`` pixels (NaN where absent),
``confidence`` ``(time, people, markers)`` in ``[0, 1]`` (0 where absent) and ``people``
``(time,)``, how many people each frame holds (the rows past it are absent). The observation
model that scores a pose against them is :mod:`jaxtrack.likelihoods.detections`; the page
``docs/detections.md`` holds the formats and the model.

Readers, one per format:

- :func:`read_openpose`: a folder of OpenPose JSON files, one per frame (``*_keypoints.json``
  as OpenPose writes them, or any ``*.json`` numbered by frame, as Pose2Sim, Sports2D and
  RTMLib write them), any number of people per frame. The layout is told by the keypoint count:
  18 COCO_18, 17 COCO_17, 26 HALPE_26, 133 COCO_133; 25 is BODY_25 or BODY_25B, told apart by
  where the neck lies (:func:`openpose_layout`), or given.
- :func:`read_coco`: COCO keypoint JSON, the results format (a list of ``{"image_id",
  "keypoints": [x, y, v, ...]}``) or an annotation file's ``annotations``; one frame per image.
- :func:`read_mediapipe`: MediaPipe Pose's 33 landmarks, as ``jaxtrack/vision/mediapipe.py`` writes
  them (``landmarks`` in pixels with ``visibility``, or its 12 markers, ``keypoints``), or a
  plain ``(time, 33, 3 | 4)`` ``.npy``/``.npz`` of normalised x, y[, z], visibility with the
  frame size given.
- :func:`read_detections` / :func:`write_detections`: the library's own ``.npz``: ``points``,
  ``confidence``, ``people``, ``markers``, ``layout``, ``frame_size`` (width, height; NaN when
  unknown) and ``frame_ids``; written atomically.

:func:`load_detections` picks the reader from the path. :func:`follow_person` keeps one person
through the frames (the one inside a box the user draws on the first frame), for a tracker that
reads one person's keypoints.

**The mapping** (:data:`MARKER_RULES`, :func:`mapping_table`). A marker the format has is
taken as it is (shoulders, elbows, wrists, hips, knees, ankles; OpenPose's ``Neck``, BODY_25's
``MidHip``, HALPE_26's ``Hip``). A marker it lacks is derived by a stated rule, a fixed
weighted mean of its keypoints, or is absent; nothing else is guessed:

- ``pelvis`` = the hips' midpoint where the format has no hip centre (BODY_25B, COCO, MediaPipe);
- ``neck`` = OpenPose's ``Neck`` where it has one (BODY_25, COCO_18: the shoulders' midpoint by
  its training definition; BODY_25B, HALPE_26: the upper neck); otherwise ``S + (E − S) / 3``,
  S the shoulders' and E the ears' midpoint (COCO_17, COCO_133, MediaPipe, as
  ``jaxtrack/vision/mediapipe.py``);
- ``head`` (the base of the skull, ``jaxtrack.body.markers``) = ``Neck + 0.35 (Head − Neck)``
  where the format has the top of the head (BODY_25B, HALPE_26, as
  ``jaxtrack.evaluation.reference``); otherwise ``S + 0.9 (E − S)``;
- ``thorax`` = ``neck + 0.4 (pelvis − neck)`` (the rigs' chest joint sits 0.41 of the way).

A derived marker is present only where every keypoint it is made from is, with their least
confidence. A person whose keypoints are all absent is dropped.

**Absent keypoints and confidences.** OpenPose writes ``0, 0, 0`` for a keypoint it did not
find; COCO annotations ``v = 0``; MediaPipe has no person in the frame. Those, and any keypoint
of confidence 0, are absent. Confidences above 1 (some detectors' heatmap maxima) are taken as
1; COCO annotations' ``v`` (1 occluded, 2 visible: a labelled position) give confidence 1.

Bad files raise :class:`DetectionFileError` (a ``ValueError``), one line naming the file and
what to do.
"""

from __future__ import annotations

import json
import math
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxtrack._files import write_npz_atomically
from jaxtrack.body import SPM_MARKERS

__all__ = [
    "DETECTION_MARKERS", "LAYOUT_KEYPOINTS", "MARKER_RULES", "DetectionFileError", "Detections",
    "follow_person", "load_detections", "map_keypoints", "mapping_table", "openpose_layout",
    "read_coco", "read_detections", "read_mediapipe", "read_openpose", "write_detections",
]

DETECTION_MARKERS = (*SPM_MARKERS, "right_knee", "right_ankle", "left_knee", "left_ankle")
"""Every marker a reader can map to: the tracker's 12 (``SPM_MARKERS``), then knees and ankles."""

_COCO_17 = ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow",
            "RElbow", "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle")

LAYOUT_KEYPOINTS: dict[str, tuple[str, ...]] = {
    "BODY_25": ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist",
                "MidHip", "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye",
                "REar", "LEar", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe",
                "RHeel"),
    "BODY_25B": (*_COCO_17, "Neck", "Head", "LBigToe", "LSmallToe", "LHeel", "RBigToe",
                 "RSmallToe", "RHeel"),
    "COCO_18": ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist",
                "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar",
                "LEar"),
    "COCO_17": _COCO_17,
    "HALPE_26": (*_COCO_17, "Head", "Neck", "Hip", "LBigToe", "RBigToe", "LSmallToe",
                 "RSmallToe", "LHeel", "RHeel"),
    # COCO-WholeBody (RTMLib's "whole body"): COCO_17, then feet, face and hands, unused here
    "COCO_133": (*_COCO_17, *(f"WholeBody{index}" for index in range(17, 133))),
    "MEDIAPIPE_33": ("Nose", "LEyeInner", "LEye", "LEyeOuter", "REyeInner", "REye", "REyeOuter",
                     "LEar", "REar", "MouthLeft", "MouthRight", "LShoulder", "RShoulder",
                     "LElbow", "RElbow", "LWrist", "RWrist", "LPinky", "RPinky", "LIndex",
                     "RIndex", "LThumb", "RThumb", "LHip", "RHip", "LKnee", "RKnee", "LAnkle",
                     "RAnkle", "LHeel", "RHeel", "LFootIndex", "RFootIndex"),
}
"""Each layout's keypoint names in the detector's order ("L"/"R": the person's left/right)."""

_OPENPOSE_COUNTS = {17: ("COCO_17",), 18: ("COCO_18",), 25: ("BODY_25", "BODY_25B"),
                    26: ("HALPE_26",), 133: ("COCO_133",)}

NECK_FRACTION, HEAD_FRACTION = 1 / 3, 0.9
"""Without a neck keypoint: neck = S + NECK_FRACTION (E − S), head = S + HEAD_FRACTION (E − S)
(S, E the shoulders' and ears' midpoints), as ``jaxtrack/vision/mediapipe.py``."""
HEAD_TOP_FRACTION = 0.35
"""With the top of the head: head = Neck + HEAD_TOP_FRACTION (Head − Neck), as
``jaxtrack.evaluation.reference``."""
THORAX_FRACTION = 0.4
"""thorax = neck + THORAX_FRACTION (pelvis − neck)."""


def _mix(*parts: tuple[float, dict[str, float]]) -> dict[str, float]:
    """Σ weight · rule, as one weighted mean of keypoints."""
    out: dict[str, float] = {}
    for weight, rule in parts:
        for name, value in rule.items():
            out[name] = out.get(name, 0.0) + weight * value
    return out


def _rules(layout: str) -> dict[str, tuple[dict[str, float], str]]:
    names = set(LAYOUT_KEYPOINTS[layout])
    rules: dict[str, tuple[dict[str, float], str]] = {}
    for side, letter in (("right", "R"), ("left", "L")):
        for part, word in (("shoulder", "Shoulder"), ("elbow", "Elbow"), ("wrist", "Wrist"),
                           ("hip", "Hip"), ("knee", "Knee"), ("ankle", "Ankle")):
            rules[f"{side}_{part}"] = ({letter + word: 1.0}, letter + word)
    shoulders = {"LShoulder": 0.5, "RShoulder": 0.5}
    ears = {"LEar": 0.5, "REar": 0.5}
    if "MidHip" in names:
        rules["pelvis"] = ({"MidHip": 1.0}, "MidHip")
    elif "Hip" in names:
        rules["pelvis"] = ({"Hip": 1.0}, "Hip (the hip centre)")
    else:
        rules["pelvis"] = ({"LHip": 0.5, "RHip": 0.5}, "the hips' midpoint")
    if "Neck" in names:
        rules["neck"] = ({"Neck": 1.0}, "Neck")
    else:
        rules["neck"] = (_mix((1 - NECK_FRACTION, shoulders), (NECK_FRACTION, ears)),
                         "S + (E − S) / 3, S the shoulders' and E the ears' midpoint")
    if "Head" in names:
        rules["head"] = (_mix((1 - HEAD_TOP_FRACTION, {"Neck": 1.0}),
                              (HEAD_TOP_FRACTION, {"Head": 1.0})),
                         "Neck + 0.35 (Head − Neck), Head the top of the head")
    else:
        rules["head"] = (_mix((1 - HEAD_FRACTION, shoulders), (HEAD_FRACTION, ears)),
                         "S + 0.9 (E − S)")
    rules["thorax"] = (_mix((1 - THORAX_FRACTION, rules["neck"][0]),
                            (THORAX_FRACTION, rules["pelvis"][0])),
                       "neck + 0.4 (pelvis − neck)")
    return rules


MARKER_RULES: dict[str, dict[str, tuple[dict[str, float], str]]] = {
    layout: _rules(layout) for layout in LAYOUT_KEYPOINTS
}
"""Per layout, per marker: (keypoint name -> weight, the rule in words). A marker is the
weighted mean of its keypoints, present where all of them are, with their least confidence."""


def mapping_table(layout: str, markers: tuple[str, ...] = DETECTION_MARKERS) -> list[str]:
    """The rule for each marker of ``layout``, one ``"marker = rule"`` line each."""
    return [f"{marker} = {MARKER_RULES[layout][marker][1]}" for marker in markers]


class DetectionFileError(ValueError):
    """A detections file or folder is missing, unreadable or not what its format says; the
    message names it and what to do, in one line."""


@dataclass(frozen=True, eq=False)
class Detections:
    """A detector's people and keypoints for a sequence, as the body's markers.

    Attributes:
        points: ``(time, people, markers, 2)`` pixel positions, NaN where absent.
        confidence: ``(time, people, markers)`` in ``[0, 1]``, 0 where absent.
        people: ``(time,)`` how many people each frame holds (rows past it are absent).
        markers: the markers' names, in the order of the ``markers`` axis.
        layout: the detector's keypoint layout the markers were mapped from (``"BODY_25B"``,
            ``"COCO_17"``, ``"MEDIAPIPE_33"``, ...; ``"markers"`` when the file held markers).
        frame_size: ``(width, height)`` of the frames in pixels, or None when the file does not
            say.
        frame_ids: ``(time,)`` each frame's number in the source (OpenPose file number, COCO
            image id, row).
        source: the file or folder read.
    """

    points: np.ndarray
    confidence: np.ndarray
    people: np.ndarray
    markers: tuple[str, ...]
    layout: str
    frame_size: tuple[float, float] | None = None
    frame_ids: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        name = self.source or "detections"
        points = np.asarray(self.points, np.float64)
        confidence = np.asarray(self.confidence, np.float64)
        people = np.asarray(self.people, np.int64)
        if points.ndim != 4 or points.shape[-1] != 2 or points.shape[2] != len(self.markers):
            raise ValueError(f"{name}: points must be (time, people, {len(self.markers)}, 2), "
                             f"got shape {points.shape}")
        if confidence.shape != points.shape[:3]:
            raise ValueError(f"{name}: confidence must be {points.shape[:3]}, got shape "
                             f"{confidence.shape}")
        if people.shape != points.shape[:1] or people.min(initial=0) < 0 or \
                people.max(initial=0) > points.shape[1]:
            raise ValueError(f"{name}: people must be ({points.shape[0]},) counts of at most "
                             f"{points.shape[1]}")
        if not np.all(np.isfinite(confidence)) or confidence.min(initial=0) < 0 or \
                confidence.max(initial=0) > 1:
            raise ValueError(f"{name}: confidence must lie in [0, 1]")
        beyond = np.arange(points.shape[1])[None, :] >= people[:, None]
        present = (confidence > 0) & np.all(np.isfinite(points), -1) & ~beyond[..., None]
        if self.frame_size is not None:
            width, height = (float(value) for value in self.frame_size)
            if not (width > 0 and height > 0 and math.isfinite(width) and
                    math.isfinite(height)):
                raise ValueError(f"{name}: frame_size must be a positive (width, height), got "
                                 f"{self.frame_size}")
            object.__setattr__(self, "frame_size", (width, height))
        ids = np.arange(points.shape[0]) if self.frame_ids is None else \
            np.asarray(self.frame_ids, np.int64)
        if ids.shape != points.shape[:1]:
            raise ValueError(f"{name}: frame_ids must be ({points.shape[0]},)")
        object.__setattr__(self, "points", np.where(present[..., None], points, np.nan))
        object.__setattr__(self, "confidence", np.where(present, confidence, 0.0))
        object.__setattr__(self, "people", people)
        object.__setattr__(self, "markers", tuple(self.markers))
        object.__setattr__(self, "frame_ids", ids)

    @property
    def num_frames(self) -> int:
        """How many frames."""
        return self.points.shape[0]

    @property
    def max_people(self) -> int:
        """The ``people`` axis' length: the most people any frame holds."""
        return self.points.shape[1]

    @property
    def present(self) -> np.ndarray:
        """``(time, people, markers)`` bool: where a keypoint was found."""
        return self.confidence > 0

    def marker(self, name: str) -> int:
        """The index of marker ``name`` on the ``markers`` axis."""
        try:
            return self.markers.index(name)
        except ValueError:
            raise ValueError(f"no marker {name!r} in these detections (they have "
                             f"{', '.join(self.markers)})") from None


# -- mapping -----------------------------------------------------------------------------------

def map_keypoints(keypoints: np.ndarray, layout: str,
                  markers: tuple[str, ...] = SPM_MARKERS) -> tuple[np.ndarray, np.ndarray]:
    """A detector's keypoints as markers, by :data:`MARKER_RULES`.

    Args:
        keypoints: ``(..., K, 3)`` x, y, confidence in ``layout``'s order (confidence 0 or
            a non-finite position: absent).
        layout: a key of :data:`LAYOUT_KEYPOINTS`.
        markers: the markers wanted (names of :data:`DETECTION_MARKERS`).

    Returns:
        ``points (..., markers, 2)`` (NaN where absent) and ``confidence (..., markers)``.
    """
    if layout not in MARKER_RULES:
        raise ValueError(f"unknown keypoint layout {layout!r}; known: "
                         f"{', '.join(LAYOUT_KEYPOINTS)}")
    unknown = [marker for marker in markers if marker not in MARKER_RULES[layout]]
    if unknown:
        raise ValueError(f"no rule maps {layout} keypoints to {', '.join(unknown)}; markers "
                         f"available: {', '.join(DETECTION_MARKERS)}")
    keypoints = np.asarray(keypoints, np.float64)
    index = {name: i for i, name in enumerate(LAYOUT_KEYPOINTS[layout])}
    xy, score = keypoints[..., :2], np.clip(np.nan_to_num(keypoints[..., 2]), 0.0, 1.0)
    found = (score > 0) & np.all(np.isfinite(xy), -1)
    xy = np.where(found[..., None], xy, 0.0)
    points, confidence = [], []
    for marker in markers:
        weights = MARKER_RULES[layout][marker][0]
        columns = [index[name] for name in weights]
        mix = np.array([weights[name] for name in weights])
        points.append(np.einsum("...kd,k->...d", xy[..., columns, :], mix))
        every = np.all(found[..., columns], -1)
        confidence.append(np.where(every, np.min(score[..., columns], -1), 0.0))
    confidence = np.stack(confidence, -1)
    points = np.where((confidence > 0)[..., None], np.stack(points, -2), np.nan)
    return points, confidence


def _assemble(frames: list[np.ndarray], layout: str, markers, *, source: str,
              frame_ids=None, frame_size=None) -> Detections:
    """Per frame ``(people, K, 3)`` keypoints -> :class:`Detections` (people with no marker
    present dropped)."""
    mapped = []
    for keypoints in frames:
        points, confidence = map_keypoints(keypoints.reshape(-1, *keypoints.shape[-2:]),
                                           layout, markers)
        keep = np.any(confidence > 0, -1)
        mapped.append((points[keep], confidence[keep]))
    most = max((len(points) for points, _ in mapped), default=0)
    shape = (len(mapped), most, len(markers))
    points = np.full((*shape, 2), np.nan)
    confidence = np.zeros(shape)
    for t, (p, c) in enumerate(mapped):
        points[t, :len(p)], confidence[t, :len(c)] = p, c
    return Detections(points, confidence, np.array([len(p) for p, _ in mapped], np.int64),
                      tuple(markers), layout, frame_size, frame_ids, source)


def _check_markers(markers) -> tuple[str, ...]:
    markers = tuple(markers)
    unknown = [marker for marker in markers if marker not in DETECTION_MARKERS]
    if unknown or not markers:
        raise ValueError(f"markers must be names of {', '.join(DETECTION_MARKERS)}; got "
                         f"{', '.join(unknown) or 'none'}")
    return markers


# -- OpenPose ----------------------------------------------------------------------------------

def openpose_layout(keypoints: np.ndarray, *, name: str = "detections") -> str:
    """``"BODY_25"`` or ``"BODY_25B"``: which layout 25-keypoint detections are in.

    The count cannot tell them apart; where the neck and the eyes lie can. BODY_25 has its neck
    at 1, shoulders at 2 and 5, nose at 0 and eyes at 15 and 16; BODY_25B its neck at 17,
    shoulders at 5 and 6, nose at 0 and eyes at 1 and 2. Under each reading, every person gives
    its neck's distance from the shoulders' midpoint and its farther eye's distance from the
    nose, in shoulder widths (where those keypoints were found; the eyes are not, seen from
    behind); the reading whose median of these is small (under 0.5 widths and 0.6 times the
    other reading's, or under 0.45 where the other reading has no such person) is the layout:
    under the wrong one they are other joints (BODY_25B's ankles, BODY_25's neck and shoulder)
    far from where a neck or an eye would be (0.5 widths and more).

    Args:
        keypoints: ``(..., 25, 3)`` x, y, confidence.
        name: what to call them in the message.

    Raises:
        DetectionFileError: neither reading is clearly right (too few people found with both
            shoulders and the neck or eyes): pass the layout explicitly.
    """
    keypoints = np.asarray(keypoints, np.float64).reshape(-1, 25, 3)

    def distances(point: int, one: int, other: int, right: int, left: int,
                  farther: bool) -> np.ndarray:
        rows = keypoints[np.all(keypoints[:, [point, one, other, right, left], 2] > 0, -1)]
        width = np.linalg.norm(rows[:, right, :2] - rows[:, left, :2], axis=-1)
        if farther:  # the farther of two points from `point`
            distance = np.maximum(np.linalg.norm(rows[:, one, :2] - rows[:, point, :2], axis=-1),
                                  np.linalg.norm(rows[:, other, :2] - rows[:, point, :2],
                                                 axis=-1))
        else:  # `point` from the midpoint of two
            distance = np.linalg.norm(rows[:, point, :2] - 0.5 * (rows[:, one, :2] +
                                                                  rows[:, other, :2]), axis=-1)
        return distance / np.maximum(width, 1e-9)

    def misfit(values: np.ndarray) -> float:
        return float(np.median(values)) if len(values) else math.nan

    body_25 = misfit(np.concatenate([distances(1, 2, 5, 2, 5, False),
                                     distances(0, 15, 16, 2, 5, True)]))
    body_25b = misfit(np.concatenate([distances(17, 6, 5, 6, 5, False),
                                      distances(0, 1, 2, 6, 5, True)]))
    for layout, mine, other in (("BODY_25", body_25, body_25b), ("BODY_25B", body_25b, body_25)):
        if mine < 0.45 if math.isnan(other) else (mine < 0.5 and mine < 0.6 * other):
            return layout
    raise DetectionFileError(f"{name}: cannot tell BODY_25 from BODY_25B (neck and eyes misfit "
                             f"{body_25:.2f} vs {body_25b:.2f} shoulder widths); pass "
                             f"layout='BODY_25' or layout='BODY_25B'")


_NUMBER = re.compile(r"(\d+)(?!.*\d)")


def _openpose_files(folder: Path) -> list[tuple[int, Path]]:
    if not folder.is_dir():
        raise DetectionFileError(f"{folder}: no such folder; give the folder of per-frame JSON "
                                 f"files OpenPose (--write_json), Pose2Sim or Sports2D wrote")
    files = sorted(folder.glob("*_keypoints.json")) or sorted(folder.glob("*.json"))
    if not files:
        raise DetectionFileError(f"{folder}: no OpenPose JSON files (*_keypoints.json or "
                                 f"*.json) in this folder; give the folder the detector wrote")
    numbered = []
    for file in files:
        stem = file.name[:-len(".json")].removesuffix("_keypoints")
        match = _NUMBER.search(stem)
        if match is None:
            raise DetectionFileError(f"{file}: no frame number in the name; name the files by "
                                     f"frame (name_000000000012_keypoints.json) or move it out")
        numbered.append((int(match.group(1)), file))
    numbered.sort()
    for (previous, before), (number, after) in zip(numbered, numbered[1:], strict=False):
        if number == previous:
            raise DetectionFileError(f"{after}: frame {number} also in {before.name}; keep one "
                                     f"file per frame in the folder")
        if number != previous + 1:
            missing = (f"frame {previous + 1}" if number == previous + 2 else
                       f"frames {previous + 1}..{number - 1}")
            raise DetectionFileError(f"{folder}: {missing} missing (the files jump from "
                                     f"{before.name} to {after.name}); write the missing "
                                     f"frames (an empty \"people\" list where no one was "
                                     f"found) or read the runs apart")
    return numbered


def _openpose_frame(file: Path) -> np.ndarray:
    """One OpenPose JSON file's people: ``(people, K, 3)``."""
    def constant(word):
        raise ValueError(f"{word} where a number must be")
    try:
        data = json.loads(file.read_text(), parse_constant=constant)
        people = data["people"]
        if not isinstance(people, list):
            raise TypeError("'people' is not a list")
        rows = [np.asarray(person["pose_keypoints_2d"], np.float64) for person in people]
    except (OSError, UnicodeDecodeError) as error:
        raise DetectionFileError(f"{file}: unreadable ({error.strerror or error}); check the "
                                 f"file") from None
    except json.JSONDecodeError as error:
        raise DetectionFileError(f"{file}: not JSON ({error.msg} at line {error.lineno}); "
                                 f"write the frame again") from None
    except (KeyError, TypeError, ValueError) as error:
        what = f"no {error}" if isinstance(error, KeyError) else str(error)
        raise DetectionFileError(f"{file}: not OpenPose JSON ({what}); each frame must be "
                                 f"{{\"people\": [{{\"pose_keypoints_2d\": [x, y, c, ...]}}]}}"
                                 ) from None
    sizes = {row.size for row in rows}
    if any(row.ndim != 1 for row in rows) or len(sizes) > 1 or \
            any(size % 3 for size in sizes):
        raise DetectionFileError(f"{file}: pose_keypoints_2d must be one flat list of x, y, c "
                                 f"per keypoint, the same length for every person, got lengths "
                                 f"{sorted(row.size for row in rows)}")
    if rows and not all(np.all(np.isfinite(row)) for row in rows):
        raise DetectionFileError(f"{file}: NaN or infinity where a number must be (OpenPose "
                                 f"writes 0, 0, 0 for a keypoint not found); fix the file")
    count = sizes.pop() // 3 if sizes else 0
    return np.stack(rows).reshape(len(rows), count, 3) if rows else np.zeros((0, 0, 3))


def read_openpose(folder: str | os.PathLike, *, layout: str | None = None,
                  markers: tuple[str, ...] = SPM_MARKERS,
                  frame_size: tuple[float, float] | None = None) -> Detections:
    """Detections from a folder of OpenPose JSON files, one per frame (module docstring).

    Args:
        folder: the folder (``*_keypoints.json``, else ``*.json``), numbered by frame without
            gaps.
        layout: the keypoint layout; None: told by the keypoint count (and, for 25, by
            :func:`openpose_layout`).
        markers: the markers wanted (default the tracker's 12).
        frame_size: ``(width, height)`` of the video, which the files do not hold (optional).

    Returns:
        The :class:`Detections`, ``layout`` saying which layout was read.

    Raises:
        DetectionFileError: no such folder, no JSON in it, a gap in the frame numbers, a file
            that is not OpenPose JSON or holds NaN, an unknown keypoint count, or a count that
            differs between files or from ``layout``.
    """
    folder = Path(folder)
    markers = _check_markers(markers)
    numbered = _openpose_files(folder)
    frames = [_openpose_frame(file) for _, file in numbered]
    counts = {frame.shape[1]: file for frame, (_, file) in zip(frames, numbered, strict=True)
              if len(frame)}
    if len(counts) > 1:
        (first, one), (second, other) = list(counts.items())[:2]
        raise DetectionFileError(f"{other}: {second} keypoints per person but {one.name} has "
                                 f"{first}; keep one detector's output per folder")
    count = next(iter(counts), None)
    if count is not None and count not in _OPENPOSE_COUNTS:
        known = ", ".join(f"{n} {' or '.join(a)}" for n, a in sorted(_OPENPOSE_COUNTS.items()))
        raise DetectionFileError(f"{counts[count]}: {count} keypoints per person is no known "
                                 f"layout ({known}); export one of those")
    if layout is not None:
        if layout not in LAYOUT_KEYPOINTS:
            raise ValueError(f"layout must be one of {', '.join(LAYOUT_KEYPOINTS)}, got "
                             f"{layout!r}")
        if count is not None and len(LAYOUT_KEYPOINTS[layout]) != count:
            raise DetectionFileError(f"{counts[count]}: {count} keypoints per person, but "
                                     f"{layout} has {len(LAYOUT_KEYPOINTS[layout])}; pass the "
                                     f"layout the detector wrote")
    elif count is None:
        raise DetectionFileError(f"{folder}: no person in any frame, so the layout is unknown; "
                                 f"pass layout=")
    elif len(_OPENPOSE_COUNTS[count]) == 1:
        layout = _OPENPOSE_COUNTS[count][0]
    else:
        layout = openpose_layout(np.concatenate([f for f in frames if len(f)]), name=str(folder))
    size = len(LAYOUT_KEYPOINTS[layout])
    frames = [frame if len(frame) else np.zeros((0, size, 3)) for frame in frames]
    return _assemble(frames, layout, markers, source=str(folder),
                     frame_ids=np.array([number for number, _ in numbered]),
                     frame_size=frame_size)


# -- COCO --------------------------------------------------------------------------------------

def read_coco(path: str | os.PathLike, *, markers: tuple[str, ...] = SPM_MARKERS,
              frame_size: tuple[float, float] | None = None) -> Detections:
    """Detections from a COCO keypoint JSON file: one frame per image, in image-id order.

    The results format (a list of ``{"image_id", "keypoints": [x, y, score, ...]}``): each
    keypoint's third value is the detector's score (clipped to ``[0, 1]``; 0: absent). An
    annotation file (``{"images", "annotations"}``): ``v`` 0 is absent, 1 or 2 a labelled
    position (confidence 1); its images, also those with no one, are the frames, and their size
    is ``frame_size`` when all share one. 17 keypoints per person (COCO_17) or 133
    (COCO-WholeBody, its first 17 read).

    Args:
        path: the JSON file.
        markers: the markers wanted.
        frame_size: ``(width, height)``, for files that do not say it.

    Raises:
        DetectionFileError: no such file, not JSON, neither format, an entry without
            ``image_id`` or with another keypoint count, or NaN where a number must be.
    """
    path = Path(path)
    markers = _check_markers(markers)
    if not path.is_file():
        raise DetectionFileError(f"{path}: no such COCO keypoint file; give the path of the "
                                 f"results or annotation JSON")

    def constant(word):
        raise DetectionFileError(f"{path}: {word} where a number must be; fix the file")
    try:
        data = json.loads(path.read_text(), parse_constant=constant)
    except (OSError, UnicodeDecodeError) as error:
        raise DetectionFileError(f"{path}: unreadable ({error}); check the file") from None
    except json.JSONDecodeError as error:
        raise DetectionFileError(f"{path}: not JSON ({error.msg} at line {error.lineno}); "
                                 f"give a COCO keypoint results or annotation file") from None
    annotated = isinstance(data, dict) and "annotations" in data
    entries = data["annotations"] if annotated else data
    if not isinstance(entries, list):
        raise DetectionFileError(f"{path}: neither a COCO results list nor an annotation file "
                                 f"with 'annotations'; give one of those")
    images, sizes = {}, set()
    if annotated:
        for image in data.get("images", []):
            if isinstance(image, dict) and "id" in image:
                images[int(image["id"])] = []
                if "width" in image and "height" in image:
                    sizes.add((float(image["width"]), float(image["height"])))
    count = None
    for number, entry in enumerate(entries):
        try:
            image_id = int(entry["image_id"])
            keypoints = np.asarray(entry["keypoints"], np.float64)
        except (KeyError, TypeError, ValueError) as error:
            what = f"no {error}" if isinstance(error, KeyError) else str(error)
            raise DetectionFileError(f"{path}: entry {number} is not a COCO keypoint entry "
                                     f"({what}); each needs image_id and keypoints [x, y, v, "
                                     f"...]") from None
        if keypoints.ndim != 1 or keypoints.size not in (51, 399) or \
                (count is not None and keypoints.size != count):
            raise DetectionFileError(f"{path}: entry {number} has {keypoints.size} keypoint "
                                     f"values; COCO_17 has 51 (17 × x, y, v), COCO-WholeBody "
                                     f"399, the same in every entry")
        if not np.all(np.isfinite(keypoints)):
            raise DetectionFileError(f"{path}: entry {number}: NaN or infinity where a number "
                                     f"must be; fix the file")
        count = keypoints.size
        keypoints = keypoints.reshape(-1, 3)
        if annotated:
            keypoints[:, 2] = (keypoints[:, 2] > 0).astype(np.float64)
        images.setdefault(image_id, []).append(keypoints)
    if not images:
        raise DetectionFileError(f"{path}: no images and no keypoint entries; give a file that "
                                 f"holds detections")
    layout = "COCO_133" if count == 399 else "COCO_17"
    size = len(LAYOUT_KEYPOINTS[layout])
    ids = sorted(images)
    frames = [np.stack(images[i]) if images[i] else np.zeros((0, size, 3)) for i in ids]
    if frame_size is None and len(sizes) == 1:
        frame_size = sizes.pop()
    return _assemble(frames, layout, markers, source=str(path), frame_ids=np.array(ids),
                     frame_size=frame_size)


# -- MediaPipe ---------------------------------------------------------------------------------

def _load_arrays(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise DetectionFileError(f"{path}: no such file; give the path of the detections file")
    try:
        data = np.load(path, allow_pickle=False)
        if isinstance(data, np.ndarray):
            return {"": data}
        with data:
            return {key: np.asarray(data[key]) for key in data.files}
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as error:
        raise DetectionFileError(f"{path}: not a readable .npy/.npz ({type(error).__name__}: "
                                 f"{' '.join(str(error).split())}); write it again with "
                                 f"numpy.save / numpy.savez") from None


def read_mediapipe(path: str | os.PathLike, *, frame_size: tuple[float, float] | None = None,
                   markers: tuple[str, ...] = SPM_MARKERS) -> Detections:
    """Detections from MediaPipe Pose's landmarks (one person per frame at most).

    Accepts what ``jaxtrack/vision/mediapipe.py`` writes: its run's ``.npz`` (``landmarks``
    ``(time, 33, 2)`` pixels, NaN where no one was found, ``visibility`` ``(time, 33)``), or its
    keypoints file (``keypoints`` ``(time, 12, 2)`` already the tracker's markers, with
    ``confidence``); and a plain ``(time, 33, 3 | 4)`` ``.npy`` or single-array ``.npz`` of
    MediaPipe's normalised x, y (fractions of the width and height), z, and visibility when a
    4th column is there (1 otherwise), which needs ``frame_size``. A frame whose landmarks are
    all NaN or all 0 holds no one.

    Args:
        path: the ``.npz`` or ``.npy`` file.
        frame_size: ``(width, height)`` of the frames in pixels (needed for normalised
            landmarks).
        markers: the markers wanted.

    Raises:
        DetectionFileError: no such file, unreadable, arrays of the wrong shape, NaN visibility,
            or normalised landmarks without ``frame_size``.
    """
    path = Path(path)
    markers = _check_markers(markers)
    arrays = _load_arrays(path)
    fail = lambda reason: DetectionFileError(f"{path}: {reason}")  # noqa: E731
    if "keypoints" in arrays:  # the 12 markers jaxtrack/vision/mediapipe.py's keypoints file holds
        from jaxtrack.vision.keypoints import read_keypoints

        try:
            points, confidence = read_keypoints(path)
        except ValueError as error:
            raise DetectionFileError(str(error)) from None
        missing = [marker for marker in markers if marker not in SPM_MARKERS]
        if missing:
            raise fail(f"holds the tracker's 12 markers only, not {', '.join(missing)}; ask "
                       f"for markers among {', '.join(SPM_MARKERS)}")
        columns = [SPM_MARKERS.index(marker) for marker in markers]
        points, confidence = points[:, None, columns], confidence[:, None, columns]
        found = np.any(confidence > 0, -1)[:, 0]
        return Detections(points, confidence, found.astype(np.int64), markers, "markers",
                          frame_size, None, str(path))
    if "landmarks" in arrays and arrays["landmarks"].ndim == 3 and \
            arrays["landmarks"].shape[-1] == 2:
        landmarks = np.asarray(arrays["landmarks"], np.float64)
        if landmarks.shape[1] != 33:
            raise fail(f"landmarks must be (time, 33, 2), got shape {landmarks.shape}")
        if "visibility" not in arrays or arrays["visibility"].shape != landmarks.shape[:2]:
            raise fail(f"pixel landmarks need visibility ({landmarks.shape[0]}, 33) beside them")
        visibility = np.asarray(arrays["visibility"], np.float64)
        if not np.all(np.isfinite(visibility)):
            raise fail("NaN or infinity in visibility, where a number must be; fix the file")
        keypoints = np.concatenate([landmarks, visibility[..., None]], -1)
    else:
        named = [key for key in arrays if key in ("", "landmarks")] or list(arrays)
        if len(named) != 1:
            raise fail(f"holds {', '.join(arrays) or 'no arrays'}; give one (time, 33, 3 | 4) "
                       f"array of normalised landmarks, or MediaPipe's landmarks + visibility")
        landmarks = np.asarray(arrays[named[0]], np.float64)
        if landmarks.ndim != 3 or landmarks.shape[1] != 33 or landmarks.shape[2] not in (3, 4):
            raise fail(f"MediaPipe landmarks must be (time, 33, 3 | 4) normalised x, y, z"
                       f"[, visibility], got shape {landmarks.shape}")
        if frame_size is None:
            raise fail("normalised landmarks need frame_size=(width, height) in pixels")
        width, height = frame_size
        keypoints = np.stack([landmarks[..., 0] * width, landmarks[..., 1] * height,
                              landmarks[..., 3] if landmarks.shape[2] == 4 else
                              np.ones(landmarks.shape[:2])], -1)
        if landmarks.shape[2] == 4 and not np.all(np.isfinite(landmarks[..., 3]) |
                                                  np.all(np.isnan(landmarks), -1)):
            raise fail("NaN visibility where a number must be; fix the file")
    empty = np.all(~np.isfinite(keypoints[..., :2]), (-1, -2)) | \
        np.all(keypoints[..., :2] == 0, (-1, -2))
    keypoints = np.where(empty[:, None, None], np.array([0.0, 0.0, 0.0]), keypoints)
    return _assemble([frame[None] for frame in keypoints], "MEDIAPIPE_33", markers,
                     source=str(path), frame_size=frame_size)


# -- the library's own .npz --------------------------------------------------------------------

def write_detections(path: str | os.PathLike, detections: Detections) -> Path:
    """Write ``detections`` to a ``.npz`` (:func:`read_detections` reads it) atomically; return
    the path."""
    size = (math.nan, math.nan) if detections.frame_size is None else detections.frame_size
    return write_npz_atomically(path, {
        "points": detections.points.astype(np.float32),
        "confidence": detections.confidence.astype(np.float32),
        "people": detections.people.astype(np.int64),
        "markers": np.array(detections.markers),
        "layout": np.array(detections.layout),
        "frame_size": np.array(size, np.float64),
        "frame_ids": detections.frame_ids.astype(np.int64),
    })


def read_detections(path: str | os.PathLike, *,
                    markers: tuple[str, ...] | None = None) -> Detections:
    """Detections from the library's own ``.npz`` (:func:`write_detections`; module
    docstring), checked.

    Args:
        path: the ``.npz``.
        markers: the markers wanted, among those the file holds (default all, in its order).

    Raises:
        DetectionFileError: no such file, unreadable, an array missing, or arrays of the wrong
            shapes or values.
    """
    path = Path(path)
    arrays = _load_arrays(path)
    needed = ("points", "confidence", "layout", "frame_size")
    missing = [key for key in needed if key not in arrays]
    if missing:
        raise DetectionFileError(f"{path}: no array {', '.join(missing)} (it has "
                                 f"{', '.join(arrays) or 'none'}); write it with "
                                 f"write_detections")
    points = arrays["points"]
    if points.ndim != 4:
        raise DetectionFileError(f"{path}: points must be (time, people, markers, 2), got "
                                 f"shape {points.shape}")
    stored = tuple(str(m) for m in arrays["markers"]) if "markers" in arrays else \
        SPM_MARKERS[:points.shape[2]]
    confidence = arrays["confidence"]
    if confidence.shape == points.shape[:3] and not np.all(np.isfinite(confidence)):
        raise DetectionFileError(f"{path}: NaN in confidence where a number must be")
    people = arrays.get("people")
    if people is None:
        people = np.sum(np.any(confidence > 0, -1), -1) if confidence.ndim == 3 else None
    size = np.asarray(arrays["frame_size"], np.float64).reshape(-1)
    frame_size = None if size.size == 2 and np.all(np.isnan(size)) else tuple(size)
    try:
        detections = Detections(points, confidence, people, stored, str(arrays["layout"]),
                                frame_size, arrays.get("frame_ids"), str(path))
        if markers is None or tuple(markers) == detections.markers:
            return detections
        columns = [detections.marker(marker) for marker in markers]
    except ValueError as error:
        message = str(error)
        raise DetectionFileError(message if message.startswith(str(path)) else
                                 f"{path}: {message}") from None
    return Detections(detections.points[:, :, columns], detections.confidence[:, :, columns],
                      detections.people, tuple(markers), detections.layout,
                      detections.frame_size, detections.frame_ids, detections.source)


def load_detections(path: str | os.PathLike, **options) -> Detections:
    """Detections from any supported file, the reader chosen from the path: a folder
    (:func:`read_openpose`), ``.json`` (:func:`read_coco`), a ``.npz`` with ``points``
    (:func:`read_detections`), another ``.npz`` or ``.npy`` (:func:`read_mediapipe`).
    ``options`` go to that reader."""
    path = Path(path)
    if path.is_dir():
        return read_openpose(path, **options)
    if path.suffix == ".json":
        return read_coco(path, **options)
    if path.suffix == ".npz" and "points" in _load_arrays(path):
        return read_detections(path, **options)
    if path.suffix in (".npz", ".npy"):
        return read_mediapipe(path, **options)
    raise DetectionFileError(f"{path}: not a detections file (a folder of OpenPose JSON, a "
                             f"COCO .json, MediaPipe's .npz/.npy, or a detections .npz)")


# -- one person through the frames ---------------------------------------------------------------

def _box_of(points: np.ndarray) -> np.ndarray | None:
    """``(x0, y0, x1, y1)`` of the finite rows of ``points`` ``(markers, 2)``, or None."""
    found = points[np.all(np.isfinite(points), axis=-1)]
    if len(found) == 0:
        return None
    return np.concatenate([found.min(axis=0), found.max(axis=0)])


def _overlap(box: np.ndarray, other: np.ndarray) -> float:
    """Intersection over the smaller box's area (a person's keypoint box inside a drawn one
    scores 1 whatever the drawn box's margin)."""
    width = min(box[2], other[2]) - max(box[0], other[0])
    height = min(box[3], other[3]) - max(box[1], other[1])
    if width <= 0 or height <= 0:
        return 0.0
    area = lambda b: max((b[2] - b[0]) * (b[3] - b[1]), 1e-9)  # noqa: E731
    return float(width * height / min(area(box), area(other)))


def follow_person(detections: Detections, box: tuple[float, float, float, float] | None = None,
                  *, gate: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """One person's keypoints through the sequence, for a tracker that reads one person.

    In the first frame where anyone is detected, the person is the one whose keypoints' box
    overlaps ``box`` most (the overlap over the smaller box's area), or without ``box`` the one
    of greatest total confidence. In each later frame it is the detected person nearest to
    where it was last seen: the median distance over the markers both have, at most ``gate``
    times the diagonal of its last keypoint box. A frame where nobody is that near, or nobody
    is detected, has no keypoints for it (a passer-by is never taken for it).

    Args:
        detections: :class:`Detections` of the sequence.
        box: ``(x0, y0, x1, y1)`` pixels around the person in the first frame with anyone.
        gate: the largest jump between frames, as a fraction of the person's box diagonal.

    Returns:
        ``points (time, markers, 2)`` (NaN where absent) and ``confidence (time, markers)``
        (0 where absent), in the order of ``detections.markers``.

    Raises:
        DetectionFileError: nobody is detected in any frame, or nobody lies inside ``box``.
    """
    count, _, num_markers, _ = detections.points.shape
    points = np.full((count, num_markers, 2), np.nan)
    confidence = np.zeros((count, num_markers))
    frames = [t for t in range(count) if detections.people[t] > 0]
    if not frames:
        raise DetectionFileError(f"{detections.source or 'detections'}: nobody is detected in "
                                 f"any frame")
    first = frames[0]
    people = detections.points[first, :detections.people[first]]
    if box is not None:
        drawn = np.asarray(box, np.float64)
        if drawn.shape != (4,) or not np.all(np.isfinite(drawn)) or drawn[2] <= drawn[0] or \
                drawn[3] <= drawn[1]:
            raise ValueError(f"box must be (x0, y0, x1, y1) with x0 < x1 and y0 < y1, got {box}")
        scores = [0.0 if (own := _box_of(person)) is None else _overlap(drawn, own)
                  for person in people]
        if max(scores) == 0.0:
            raise DetectionFileError(
                f"{detections.source or 'detections'}: nobody detected in frame "
                f"{int(detections.frame_ids[first])} lies inside the box "
                f"{', '.join(f'{v:g}' for v in drawn)}; give a box around the person")
    else:
        scores = detections.confidence[first, :detections.people[first]].sum(axis=-1)
    chosen = int(np.argmax(scores))
    last = people[chosen]
    for t in frames:
        candidates = detections.points[t, :detections.people[t]]
        if t == first:
            index = chosen
        else:
            size = _box_of(last)
            diagonal = float(np.hypot(size[2] - size[0], size[3] - size[1]))
            distances = []
            for person in candidates:
                both = np.all(np.isfinite(person), -1) & np.all(np.isfinite(last), -1)
                distances.append(np.median(np.linalg.norm(person[both] - last[both], axis=-1))
                                 if both.any() else np.inf)
            index = int(np.argmin(distances))
            if not distances[index] <= gate * max(diagonal, 1.0):
                continue
        points[t] = candidates[index]
        confidence[t] = detections.confidence[t, index]
        last = np.where(np.isfinite(candidates[index]), candidates[index], last)
    return points, confidence
