"""The first-frame pose of ``jaxtrack track``'s image trackers (latent, CONDENSATION, MHT):
``--init manual:x,y,...`` (the 12 markers in video pixels, checked against the video's size),
``--init keypoints`` (a detector's first frame) or ``--init face`` (face and foreground-blob
head boxes, then a search of the prior's training poses: ``jaxtrack.trackers.autoinit``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxtrack.cli._common import UserError, one_line

__all__ = ["initialise", "manual_instead", "manual_markers", "manual_numbers", "read_keypoints"]

MIN_TORSO_PX = 4.0  # a shorter neck-pelvis distance is no body the tracker can follow


def read_keypoints(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``--keypoints FILE``'s keypoints and confidences, or a one-line error naming it."""
    from jaxtrack.vision.keypoints import KeypointFileError, read_keypoints

    try:
        return read_keypoints(path)
    except KeypointFileError as error:
        raise UserError(f"--keypoints: {error}") from None


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
