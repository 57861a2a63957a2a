"""A pseudo ground truth for the real Pose2Sim videos: triangulated keypoints projected per camera.

The Pose2Sim demo (``shared/data/pose2sim_demo_singleperson``) films one man balancing on a beam
with four synchronised, calibrated cameras at 60 fps. Its ``reference/`` folder holds the 21
OpenPose BODY_25B keypoints Pose2Sim triangulated from all four cameras (a ``.trc`` file, metres)
and the 2-D detections they came from. This module reads the ``.trc``, projects it into each
camera's video pixels and maps the keypoints to the tracker's 12 upper-body markers
(:data:`jaxtrack.body.UPPER_BODY_12`), so tracks of the real videos can be scored by
:func:`jaxtrack.evaluation.evaluate_track`. Conventions (``reference/SOURCE.txt``):

- axes: the ``.trc`` is Y-up, ``world = trc[..., [2, 0, 1]]`` is the Z-up frame of
  ``Calib.qca.txt``, read by :func:`jaxtrack.body.read_qca` (intrinsics ÷ 64,
  ``R = diag(1, −1, −1) M``, centre in mm). Pose2Sim triangulated without lens distortion, so
  the projection leaves it out too (it moves body points by under 3 px);
- frames: ``.trc`` row k is video frame k + 1 (three independent checks in SOURCE.txt);
- pixels: the videos' own; cam01 and cam02 are 1080 px wide where the calibration says 1088,
  with no crop shift;
- accuracy: about 10 px median against the detections (1 % of the person's height), worse in
  cam03. Errors of trackers are therefore meaningful down to a few % of the torso, not below.

The marker map (BODY_25B names as Pose2Sim writes them; its ``Neck`` is BODY_25B's upper neck,
its ``Head`` the top of the head):

============== ==========================================================================
marker         from
============== ==========================================================================
head           ``Neck + 0.35 (Head − Neck)``: the markers' head is the base of the skull
               (``body.markers``), about 0.2 m below the top of the head (the renderer's
               figure: 0.195 m; here Head − Neck is 0.29 m, so 0.33; the training rigs'
               head–neck distance, 0.22 torso, gives 0.42)
neck           ``Neck`` (6 cm above the shoulders' midpoint here; the rigs' neck is 0.1–0.24
               torso above it)
thorax         ``neck + 0.4 (pelvis − neck)`` (the rigs' chest joint sits 0.41 of the way)
pelvis         midpoint of ``RHip`` and ``LHip`` (the root, the hip centre)
shoulders …    ``RShoulder``, ``RElbow``, ``RWrist``, ``RHip`` and the left ones
============== ==========================================================================

Nothing here imports OpenCV; the videos themselves are read by ``jaxtrack.vision``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

__all__ = [
    "BODY_25B_INDEX", "HEAD_FRACTION", "THORAX_FRACTION", "TRC_KEYPOINTS", "CameraReference",
    "ReferenceDataError", "default_folder", "load_reference", "project_keypoints", "read_openpose",
    "read_trc", "to_upper_body", "trc_to_world",
]

DATASET = "pose2sim_demo_singleperson"
TRC_FILES = {False: "S00_P00_T01_BalancingTrial_0-100.trc",
             True: "S00_P00_T01_BalancingTrial_0-100_filt_butterworth.trc"}
"""The raw triangulation and Pose2Sim's Butterworth-filtered one, under ``reference/pose-3d``."""

TRC_KEYPOINTS = (
    "RHip", "RKnee", "RAnkle", "RBigToe", "RSmallToe", "RHeel", "LHip", "LKnee", "LAnkle",
    "LBigToe", "LSmallToe", "LHeel", "Neck", "Head", "Nose", "RShoulder", "RElbow", "RWrist",
    "LShoulder", "LElbow", "LWrist",
)
"""The ``.trc``'s 21 keypoints in file order."""

BODY_25B_INDEX = {
    "RHip": 12, "RKnee": 14, "RAnkle": 16, "RBigToe": 22, "RSmallToe": 23, "RHeel": 24,
    "LHip": 11, "LKnee": 13, "LAnkle": 15, "LBigToe": 19, "LSmallToe": 20, "LHeel": 21,
    "Neck": 17, "Head": 18, "Nose": 0, "RShoulder": 6, "RElbow": 8, "RWrist": 10,
    "LShoulder": 5, "LElbow": 7, "LWrist": 9,
}
"""Each ``.trc`` keypoint's index in an OpenPose BODY_25B detection (25 points)."""

HEAD_FRACTION = 0.35
"""The head marker's place from ``Neck`` (0) to ``Head``, the top of the head (1)."""
THORAX_FRACTION = 0.4
"""The thorax marker's place from the neck (0) to the pelvis (1)."""

FRAME_OFFSET = 1
"""``.trc`` row k is video frame k + FRAME_OFFSET (SOURCE.txt)."""

_DIRECT = {
    "neck": "Neck", "right_shoulder": "RShoulder", "right_elbow": "RElbow",
    "right_wrist": "RWrist", "right_hip": "RHip", "left_shoulder": "LShoulder",
    "left_elbow": "LElbow", "left_wrist": "LWrist", "left_hip": "LHip",
}


class ReferenceDataError(ValueError):
    """A reference file is missing, damaged or not what it should be."""


@dataclass(frozen=True)
class CameraReference:
    """The reference seen by one camera.

    Attributes:
        camera: the camera's name (``"cam01"``), also its video's stem.
        markers: ``(frames, 12, 2)`` the 12 markers (``UPPER_BODY_12`` order), video pixels.
        keypoints: ``(frames, 21, 2)`` the ``.trc`` keypoints projected (``TRC_KEYPOINTS``).
        frame_indices: ``(frames,)`` the video frame each row belongs to.
        rows: ``(frames,)`` the ``.trc`` row each came from.
        depth: ``(frames, 21)`` the keypoints' depth in front of the camera, metres.
    """

    camera: str
    markers: np.ndarray
    keypoints: np.ndarray
    frame_indices: np.ndarray
    rows: np.ndarray
    depth: np.ndarray

    def scaled(self, factor: float) -> CameraReference:
        """The same reference in a video resampled by ``factor`` (pixel centres aligned:
        ``p' = (p + 0.5) factor − 0.5``, as ``cv2.resize`` maps them)."""
        if not factor > 0:
            raise ValueError(f"factor must be positive, got {factor}")
        return replace(self, markers=(self.markers + 0.5) * factor - 0.5,
                       keypoints=(self.keypoints + 0.5) * factor - 0.5)

    def select(self, frame_indices) -> CameraReference:
        """The rows of the given video frames (each must be covered)."""
        wanted = np.asarray(frame_indices, dtype=np.int64)
        where = {int(frame): row for row, frame in enumerate(self.frame_indices)}
        missing = [int(frame) for frame in wanted if int(frame) not in where]
        if missing:
            raise ValueError(f"{self.camera}: the reference covers video frames "
                             f"{int(self.frame_indices[0])}..{int(self.frame_indices[-1])}, "
                             f"not {missing[:5]}")
        rows = np.array([where[int(frame)] for frame in wanted], dtype=np.int64)
        return replace(self, markers=self.markers[rows], keypoints=self.keypoints[rows],
                       frame_indices=self.frame_indices[rows], rows=self.rows[rows],
                       depth=self.depth[rows])


def default_folder() -> Path:
    """The Pose2Sim demo in the shared data collection (``$JAXTRACK_DATA`` or ``shared/data``).

    Raises:
        FileNotFoundError: there is no shared data collection, or it lacks the demo.
    """
    from jaxtrack.data import shared_folder

    shared = shared_folder()
    if shared is None or not (shared / DATASET).is_dir():
        raise FileNotFoundError(f"the {DATASET} folder is not in a shared data collection "
                                f"(set JAXTRACK_DATA to a folder holding it)")
    return shared / DATASET


def read_trc(path: str | Path) -> tuple[tuple[str, ...], np.ndarray, float]:
    """Read a ``.trc`` marker file (tab-separated, 5 header lines).

    Returns:
        ``(names, positions (rows, points, 3) in the file's axes and units, data rate)``.

    Raises:
        FileNotFoundError: no such file. ReferenceDataError: the file is not a readable ``.trc``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"reference .trc file not found: {path}")
    lines = path.read_text().splitlines()
    if len(lines) < 6 or not lines[0].startswith("PathFileType"):
        raise ReferenceDataError(f"{path} is not a .trc file (no PathFileType header)")
    try:
        header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=False))
        rate, count = float(header["DataRate"]), int(header["NumMarkers"])
        names = tuple(name for name in lines[3].split("\t")[2:] if name.strip())
        rows = [line.split("\t") for line in lines[5:] if line.strip()]
        values = np.array([[float(v) for v in row[2:2 + 3 * count]] for row in rows])
    except (KeyError, ValueError, IndexError) as error:
        raise ReferenceDataError(f"{path} is a damaged .trc file: {error!r}") from None
    if len(names) != count or values.ndim != 2 or values.shape[1] != 3 * count:
        raise ReferenceDataError(f"{path}: the header names {len(names)} of {count} markers but "
                             f"rows hold {values.shape[-1] if values.ndim == 2 else 0} numbers")
    if header.get("Units", "m") != "m":
        raise ReferenceDataError(f"{path}: units are {header['Units']!r}, expected 'm'")
    return names, values.reshape(len(values), count, 3), rate


def trc_to_world(positions: np.ndarray) -> np.ndarray:
    """``.trc`` (Y-up) points → the Z-up world of ``Calib.qca.txt``: ``world = trc[..., [2, 0,
    1]]``."""
    return np.asarray(positions, np.float64)[..., [2, 0, 1]]


def to_upper_body(keypoints: np.ndarray, names=TRC_KEYPOINTS) -> np.ndarray:
    """Map BODY_25B keypoints ``(..., points, D)`` (named ``names``) to the 12 markers
    ``(..., 12, D)`` of ``UPPER_BODY_12`` (the table in the module docstring)."""
    from jaxtrack.body import UPPER_BODY_12

    names = list(names)
    needed = {"Head", "Neck", *_DIRECT.values()}
    missing = sorted(needed - set(names))
    if missing:
        raise ValueError(f"the keypoints lack {missing} needed for the 12 markers")
    keypoints = np.asarray(keypoints, np.float64)

    def point(name):
        return keypoints[..., names.index(name), :]

    neck = point("Neck")
    pelvis = 0.5 * (point("RHip") + point("LHip"))
    derived = {
        "head": neck + HEAD_FRACTION * (point("Head") - neck),
        "thorax": neck + THORAX_FRACTION * (pelvis - neck),
        "pelvis": pelvis,
        **{marker: point(name) for marker, name in _DIRECT.items()},
    }
    return np.stack([derived[marker] for marker in UPPER_BODY_12], axis=-2)


def _cameras(path: Path) -> dict:
    from jaxtrack.body import read_qca

    if not path.is_file():
        raise FileNotFoundError(f"calibration file not found: {path}")
    try:
        cameras = read_qca(path, world_up="z")
    except ValueError as error:
        raise ReferenceDataError(" ".join(str(error).split())) from None
    return {camera.name: camera for camera in cameras}


def project_keypoints(camera, world: np.ndarray, *, distortion: bool = False
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Project Z-up world points ``(..., 3)`` (metres) with a :class:`~jaxtrack.body.Camera`:
    pixels ``(..., 2)`` and depth ``(...)``; without the lens distortion unless asked, as
    Pose2Sim triangulated."""
    from jaxtrack.body import Camera
    from jaxtrack.body._staging import project_numpy

    if not distortion:
        camera = Camera(camera.focal_length, camera.principal_point, camera.rotation,
                        camera.translation, np.zeros(5), camera.image_size, name=camera.name)
    return project_numpy(camera, world)


def load_reference(folder: str | Path | None = None, *, filtered: bool = False,
                   num_video_frames: int | None = None, frame_offset: int = FRAME_OFFSET
                   ) -> dict[str, CameraReference]:
    """The reference of every camera of the Pose2Sim demo, in its video's pixels.

    Args:
        folder: the ``pose2sim_demo_singleperson`` folder (default :func:`default_folder`).
        filtered: use Pose2Sim's Butterworth-filtered ``.trc`` instead of the raw one.
        num_video_frames: drop rows that map past the videos' last frame (the videos have 100
            frames, the ``.trc`` 100 rows, so with the +1 alignment the last row has no frame).
        frame_offset: ``.trc`` row k is video frame ``k + frame_offset``.

    Returns:
        camera name (``"cam01"`` …) → :class:`CameraReference`.

    Raises:
        FileNotFoundError: a file is missing. ReferenceDataError: a file is damaged, or the
            keypoints lie behind a camera.
    """
    folder = Path(folder) if folder is not None else default_folder()
    trc = folder / "reference" / "pose-3d" / TRC_FILES[bool(filtered)]
    names, positions, _ = read_trc(trc)
    if tuple(names) != TRC_KEYPOINTS:
        raise ReferenceDataError(f"{trc}: keypoints {names} are not the 21 BODY_25B ones "
                             f"{TRC_KEYPOINTS}")
    if not np.isfinite(positions).all():
        raise ReferenceDataError(f"{trc} has non-finite coordinates")
    world = trc_to_world(positions)
    rows = np.arange(len(world))
    frames = rows + int(frame_offset)
    keep = frames >= 0
    if num_video_frames is not None:
        keep &= frames < int(num_video_frames)
    if not keep.any():
        raise ReferenceDataError(f"no .trc row maps to a video frame (offset {frame_offset}, "
                             f"{num_video_frames} frames)")
    world, rows, frames = world[keep], rows[keep], frames[keep]
    markers_world = to_upper_body(world)
    references = {}
    for name, camera in _cameras(folder / "Calib.qca.txt").items():
        keypoints, depth = project_keypoints(camera, world)
        if not (depth > 0).all():
            raise ReferenceDataError(f"{name}: the reference lies behind the camera; is "
                                 f"{folder / 'Calib.qca.txt'} this capture's calibration?")
        markers, _ = project_keypoints(camera, markers_world)
        references[name] = CameraReference(name, markers, keypoints, frames, rows, depth)
    return references


def read_openpose(folder: str | Path) -> list[np.ndarray]:
    """OpenPose JSON detections, one file per frame in name order: per frame ``(people, 25,
    3)`` (x, y, confidence; BODY_25B indices :data:`BODY_25B_INDEX`).

    Raises:
        FileNotFoundError: no such folder or no JSON in it. ReferenceDataError: a damaged file.
    """
    folder = Path(folder)
    files = sorted(folder.glob("*.json")) if folder.is_dir() else []
    if not files:
        raise FileNotFoundError(f"no OpenPose .json files in {folder}")
    detections = []
    for file in files:
        try:
            people = json.loads(file.read_text())["people"]
            points = np.array([person["pose_keypoints_2d"] for person in people], np.float64)
            detections.append(points.reshape(len(people), -1, 3))
        except (OSError, KeyError, TypeError, ValueError) as error:
            raise ReferenceDataError(f"{file} is not an OpenPose detection file: "
                                     f"{error!r}") from None
    return detections
