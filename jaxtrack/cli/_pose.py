"""The first-frame pose of ``jaxtrack track``'s image trackers (latent, CONDENSATION, MHT):
``--init manual:x,y,...`` (the 12 markers in video pixels, checked against the video's size),
``--init keypoints`` (a detector's first frame) or ``--init face`` (face and foreground-blob
head boxes, then a search of the prior's training poses: ``jaxtrack.trackers.autoinit``)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import UserError, one_line

__all__ = ["initialise", "manual_instead", "manual_markers", "manual_numbers", "person_box",
           "read_keypoints"]

MIN_TORSO_PX = 4.0  # a shorter neck-pelvis distance is no body the tracker can follow


def read_keypoints(path: Path, person: str | None = None, markers: tuple[str, ...] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``--keypoints FILE_OR_FOLDER``'s keypoints and confidences of one person, one row per
    video frame from the first, or a one-line error naming it.

    A ``.npz`` with ``keypoints`` is one person's already (:mod:`jaxtrack.vision.keypoints`,
    the 12 ``UPPER_BODY_12`` markers). Any other detections file or folder (OpenPose JSON,
    COCO, MediaPipe, jaxtrack's own: :func:`jaxtrack.vision.detections.load_detections`) may
    hold several people per frame: the one inside ``--person x0,y0,x1,y1`` in the first frame
    with anyone (else the most confident) is followed
    (:func:`jaxtrack.vision.detections.follow_person`); a file's frame numbers count from its
    first, which is the video's first frame. ``markers``: the markers read from such a file,
    in that order (default ``UPPER_BODY_12``)."""
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.vision.detections import DetectionFileError, follow_person, load_detections
    from jaxtrack.vision.keypoints import KeypointFileError, read_keypoints

    markers = tuple(UPPER_BODY_12 if markers is None else markers)
    box = None if person is None else person_box(person)
    if path.suffix == ".npz" and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as archive:
                single = "keypoints" in archive.files
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as error:
            raise UserError(f"--keypoints: {path}: not a readable .npz ({one_line(error)})"
                            ) from None
        if single:
            if box is not None:
                raise UserError(f"--person picks one of several people; --keypoints {path} "
                                f"holds one person's keypoints: leave --person out")
            try:
                return read_keypoints(path)
            except KeypointFileError as error:
                raise UserError(f"--keypoints: {error}") from None
    if not path.exists():
        raise UserError(f"--keypoints: {path}: no such file or folder")
    try:
        detections = load_detections(path, markers=markers)
        points, confidence = follow_person(detections, box)
    except (DetectionFileError, ValueError) as error:
        raise UserError(f"--keypoints: {' '.join(str(error).split())}") from None
    rows = detections.frame_ids - detections.frame_ids[0]
    keypoints = np.full((int(rows[-1]) + 1, len(markers), 2), np.nan)
    confidences = np.zeros(keypoints.shape[:2])
    keypoints[rows], confidences[rows] = points, confidence
    return keypoints, confidences


def person_box(text: str) -> tuple[float, float, float, float]:
    """``--person x0,y0,x1,y1``: four finite numbers, x0 < x1 and y0 < y1."""
    try:
        values = [float(value) for value in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 4 or not all(np.isfinite(values)) or values[2] <= values[0] or \
            values[3] <= values[1]:
        raise UserError(f"--person must be x0,y0,x1,y1 (a box in the first frame's pixels, "
                        f"x0 < x1, y0 < y1), got {text!r}")
    return tuple(values)


def manual_numbers(text: str) -> np.ndarray:
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


def manual_markers(text: str, size: tuple[int, int]) -> np.ndarray:
    """The 12 markers ``(12, 2)`` of ``--init manual:...`` in video pixels, checked against the
    video's ``(width, height)`` before anything is tracked: 24 finite numbers, every marker
    inside the frame (those outside are named), and a torso of a few pixels at least."""
    from jaxtrack.body import UPPER_BODY_12

    markers = manual_numbers(text)
    width, height = size
    outside = [f"{name} ({x:g}, {y:g})" for name, (x, y) in zip(UPPER_BODY_12, markers,
                                                                 strict=True)
               if not (0 <= x <= width and 0 <= y <= height)]
    if outside:
        raise UserError(f"--init manual: {len(outside)} marker(s) outside the {width}x{height} "
                        f"video (x 0-{width}, y 0-{height}, video pixels): {', '.join(outside)}")
    neck, pelvis = UPPER_BODY_12.index("neck"), UPPER_BODY_12.index("pelvis")
    torso = float(np.linalg.norm(markers[pelvis] - markers[neck]))
    if torso < MIN_TORSO_PX:
        raise UserError(f"--init manual: the torso (neck to pelvis) is {torso:.1f} px long, "
                        f"less than {MIN_TORSO_PX:g} px: not a body pose; the numbers are x, y "
                        f"of {', '.join(UPPER_BODY_12)} in video pixels")
    return markers


def manual_instead() -> str:
    """What to give when ``--init face`` finds nobody: the other two initialisations, with the
    markers' order."""
    from jaxtrack.body import UPPER_BODY_12

    return (f"give the first frame's pose instead: --init manual:x,y,... (24 numbers, x and y "
            f"of {', '.join(UPPER_BODY_12)}, in video pixels) or --init keypoints --keypoints "
            f"FILE (a detector's keypoints)")


def initialise(args, model, template, size: tuple[int, int], first_frame=None,
               foreground=None, factors=None, keypoints=None) -> tuple[np.ndarray, dict]:
    """The first tracked frame's 12 markers ``(12, 2)`` in video pixels and how they were found.

    Args:
        args: the command's arguments (``--init``, ``--keypoints``, ``--masks``, ``--video``).
        model, template: the GPLVM prior and its SPM template (``--init face`` searches its
            training poses).
        size: the video's ``(width, height)``.
        first_frame: ``(height, width, 3)`` uint8, the first tracked frame at tracking size
            (``--init face``).
        foreground: ``(mask (height, width) bool, source)`` of that frame (``--init face``).
        factors: ``(2,)`` tracking pixels per video pixel along x and y.
        keypoints: the detector's ``(points (12, 2), confidence (12,))`` of the first tracked
            frame, in video pixels (``--init keypoints``).
    """
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.trackers.autoinit import AutoInitError, auto_initialise
    from jaxtrack.vision import FaceDetectorUnavailableError

    if args.init.startswith("manual:"):
        return manual_markers(args.init[len("manual:"):], size), {"method": "manual"}
    if args.init == "keypoints":
        points, confidence = keypoints
        if not np.all(confidence > 0):
            missing = [name for name, sure in zip(UPPER_BODY_12, confidence, strict=True)
                       if not sure > 0]
            raise UserError(f"--init keypoints: {args.keypoints} has no {', '.join(missing)} "
                            f"in the first frame tracked; give --init face or manual:...")
        return np.asarray(points, np.float64), {"method": "keypoints",
                                                "file": str(args.keypoints)}
    mask, source = foreground
    if source == "masks" and not mask.any():
        raise UserError(f"--init face: the first frame's mask in {args.masks[0]} is empty; "
                        f"give masks that hold the person there, or {manual_instead()}")
    try:
        found = auto_initialise(model, template, first_frame, mask)
    except AutoInitError as error:
        reason = one_line(error).removesuffix("; give the first pose by hand")
        raise UserError(f"--init face found nobody on {args.video}: {reason}; "
                        f"{manual_instead()}") from None
    except FaceDetectorUnavailableError as error:
        raise UserError(f"--init face: {error}") from None
    scale = float(np.mean(factors))
    return found.markers / factors, {
        "method": "face", "source": found.source, "score": found.score, "foreground": source,
        "box": (found.face / scale).round(1).tolist(), "torso_px": found.torso / scale,
        "boxes_tried": (found.faces / scale).round(1).tolist()}
