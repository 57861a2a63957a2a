"""Frontal faces with OpenCV's Haar cascade (Viola & Jones), to find the head in a frame.

A tracker can seed its first pose (or check the head marker) from a face box. The detector is
OpenCV's ``CascadeClassifier`` with the frontal-face cascade that the ``opencv-python`` wheels
ship in ``cv2.data.haarcascades``.

OpenCV 5 removed ``CascadeClassifier`` from its main modules and its wheels no longer ship the
cascade files; with it (or any build without them) :func:`face_detector_available` is False and
the detectors raise :class:`FaceDetectorUnavailableError`, which says what to install. A cascade
XML file elsewhere can be named with the ``cascade`` argument or the ``JAXTRACK_FACE_CASCADE``
environment variable, as long as ``cv2.CascadeClassifier`` exists.

OpenCV is imported inside the functions, so importing this module needs no cv2. How the
automatic initialisation uses the boxes: ``docs/real-video.md``.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

__all__ = ["CANDIDATE_CASCADES", "FaceDetectorUnavailableError", "detect_face", "detect_faces",
           "face_candidates", "face_detector_available"]

CASCADE_FILE = "haarcascade_frontalface_default.xml"
_ENVIRONMENT = "JAXTRACK_FACE_CASCADE"


class FaceDetectorUnavailableError(RuntimeError):
    """This OpenCV has no Haar cascade face detector (or its cascade file is missing)."""


def _cascade_path(cascade: str | os.PathLike | None) -> Path:

    if cascade is None:
        cascade = os.environ.get(_ENVIRONMENT)
    if cascade is not None:
        path = Path(cascade).expanduser()
        if not path.is_file():
            raise FaceDetectorUnavailableError(f"{path}: no such Haar cascade file")
        return path
    return _bundled_cascade(CASCADE_FILE, f", or name a cascade file with cascade=... or "
                                          f"${_ENVIRONMENT}")


def _bundled_cascade(name: str, hint: str = "") -> Path:
    """The path of one of the cascade files OpenCV's wheels ship in ``cv2.data.haarcascades``."""
    import cv2

    folder = getattr(getattr(cv2, "data", None), "haarcascades", None)
    path = Path(folder or ".") / name
    if folder is None or not path.is_file():
        raise FaceDetectorUnavailableError(
            f"OpenCV {cv2.__version__} ships no {name} (looked in {folder}); install "
            f"opencv-python-headless<5 (OpenCV 4 wheels include it){hint}")
    return path


@functools.cache
def _classifier(path: Path):
    import cv2

    if not hasattr(cv2, "CascadeClassifier"):
        raise FaceDetectorUnavailableError(
            f"OpenCV {cv2.__version__} has no cv2.CascadeClassifier (OpenCV 5 moved the Haar "
            f"cascade detector out of its main modules); install opencv-python-headless<5 "
            f"for face detection")
    classifier = cv2.CascadeClassifier(str(path))
    if classifier.empty():
        raise FaceDetectorUnavailableError(f"{path}: OpenCV cannot load it as a Haar cascade")
    return classifier


def face_detector_available(cascade: str | os.PathLike | None = None) -> bool:
    """Whether :func:`detect_faces` can run here (OpenCV importable, cascade found and loaded)."""
    try:
        _classifier(_cascade_path(cascade))
    except (FaceDetectorUnavailableError, ImportError):
        return False
    return True


def detect_faces(image_rgb: np.ndarray, *, scale_factor: float = 1.1, min_neighbors: int = 5,
                 min_size: tuple[int, int] = (24, 24),
                 cascade: str | os.PathLike | None = None) -> np.ndarray:
    """Frontal faces in an RGB image, largest first.

    Args:
        image_rgb: ``(height, width, 3)`` uint8 RGB (or ``(height, width)`` grey) image.
        scale_factor: image pyramid step of the sliding-window search (> 1; smaller finds more
            sizes, slower).
        min_neighbors: overlapping detections needed to keep a face (higher: fewer false
            positives, more misses).
        min_size: smallest face ``(width, height)`` in pixels searched for.
        cascade: a Haar cascade XML file; None uses ``$JAXTRACK_FACE_CASCADE`` or OpenCV's
            bundled frontal-face cascade.

    Returns:
        ``(faces, 4)`` int64 boxes ``(x, y, width, height)`` in pixels, sorted by area, largest
        first; ``(0, 4)`` when there is none.

    Raises:
        FaceDetectorUnavailableError: this OpenCV has no Haar cascade detector or file.
        ValueError: the image is not ``(height, width, 3)`` or ``(height, width)``.
    """
    import cv2

    image = np.asarray(image_rgb)
    if image.dtype != np.uint8:
        raise ValueError(f"detect_faces expects a uint8 image, got {image.dtype}")
    if image.ndim == 3 and image.shape[-1] == 3:
        grey = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    elif image.ndim == 2:
        grey = np.ascontiguousarray(image)
    else:
        raise ValueError(f"detect_faces expects an RGB (height, width, 3) or grey image, got "
                         f"shape {image.shape}")
    classifier = _classifier(_cascade_path(cascade))
    # equalising makes the cascade's fixed thresholds work in dim or washed-out frames
    grey = cv2.equalizeHist(grey)
    boxes = classifier.detectMultiScale(grey, scaleFactor=scale_factor,
                                        minNeighbors=min_neighbors, minSize=tuple(min_size))
    boxes = np.asarray(boxes, np.int64).reshape(-1, 4)
    order = np.argsort(-(boxes[:, 2] * boxes[:, 3]), kind="stable")
    return boxes[order]


def detect_face(image_rgb: np.ndarray, **options) -> np.ndarray | None:
    """The largest frontal face ``(x, y, width, height)`` (int64, shape ``(4,)``), or None.

    Options are those of :func:`detect_faces`.
    """
    boxes = detect_faces(image_rgb, **options)
    return boxes[0] if len(boxes) else None


#: the bundled cascades :func:`face_candidates` runs by default: two frontal and one profile
CANDIDATE_CASCADES = ("haarcascade_frontalface_default.xml", "haarcascade_frontalface_alt2.xml",
                      "haarcascade_profileface.xml")


def _overlap(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Intersection over the smaller box's area, of ``box`` with each of ``boxes``."""
    x0 = np.maximum(box[0], boxes[:, 0])
    y0 = np.maximum(box[1], boxes[:, 1])
    x1 = np.minimum(box[0] + box[2], boxes[:, 0] + boxes[:, 2])
    y1 = np.minimum(box[1] + box[3], boxes[:, 1] + boxes[:, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    return inter / np.minimum(box[2] * box[3], boxes[:, 2] * boxes[:, 3])


def face_candidates(image_rgb: np.ndarray, *, cascades: tuple[str, ...] = CANDIDATE_CASCADES,
                    min_neighbors: int = 3, max_faces: int = 8,
                    min_size: tuple[int, int] = (16, 16)) -> np.ndarray:
    """Every plausible face box from several bundled cascades, for a caller that checks them.

    A frontal cascade alone misses turned, small, blurred or pixelated faces; this runs each of
    ``cascades`` (profile cascades also on the mirrored image, as they find one side only) with
    a permissive ``min_neighbors``, merges boxes that overlap by more than half and keeps the
    ``max_faces`` with the most detections behind them. It trades false positives for recall:
    the automatic initialisation (``jaxtrack.trackers.autoinit``) scores a body pose under each
    box and keeps the one a person explains.

    Returns:
        ``(faces, 4)`` int64 boxes ``(x, y, width, height)``, most-supported first.
    """
    image = np.asarray(image_rgb)
    width = image.shape[1]
    found = []
    for name in cascades:
        path = _bundled_cascade(name)
        options = dict(min_neighbors=min_neighbors, min_size=min_size, cascade=path)
        found.append(detect_faces(image, **options))
        if "profile" in name:  # the profile cascade finds faces turned one way only
            mirrored = detect_faces(np.ascontiguousarray(image[:, ::-1]), **options)
            mirrored[:, 0] = width - mirrored[:, 0] - mirrored[:, 2]
            found.append(mirrored)
    boxes = np.concatenate(found) if found else np.zeros((0, 4), np.int64)
    merged, support = [], []
    for box in boxes:
        if merged:
            overlap = _overlap(box, np.asarray(merged))
            best = int(np.argmax(overlap))
            if overlap[best] > 0.5:
                support[best] += 1
                continue
        merged.append(box)
        support.append(1)
    if not merged:
        return np.zeros((0, 4), np.int64)
    order = np.argsort(-np.asarray(support), kind="stable")[:max_faces]
    return np.asarray(merged, np.int64)[order]
