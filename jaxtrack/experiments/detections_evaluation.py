"""A detector's keypoints on the real Pose2Sim videos, scored against the triangulated reference
as they come and after each smoothing baseline, in 2-D per view and in 3-D from the four views.

    python -m jaxtrack.experiments.detections_evaluation --json OUT.json

The setting (:func:`load_setting`): the Pose2Sim demo (``shared/data/pose2sim_demo_singleperson``,
four calibrated 60 fps views of a man balancing on a beam, BSD-3), its reference
(:mod:`jaxtrack.evaluation.reference`: 21 keypoints Pose2Sim triangulated from OpenPose, ``.trc``
row k = video frame k + 1, so video frames 1..99 are scored) and MediaPipe Pose's landmarks of
every frame of each video (:mod:`jaxtrack.vision.mediapipe`, video mode, full frames, model
complexity 1), mapped to the 12 markers. The detections are cached, one ``.npz`` per view as
the detector's worker writes them, in ``--detections`` (default
``tests/data/detections/mediapipe_pose2sim``); a view whose file is missing is detected there
and then (``make detector``), and its detector time reported apart.

Rows (:func:`baseline_estimates`), each on the same detections:

- ``raw``: the markers as detected (NaN where MediaPipe found no one);
- ``butterworth``: Pose2Sim's filter, order 4 (2 per pass, forward and backward), 6 Hz;
- ``one-euro``: Casiez et al. 2012 with their defaults (1 Hz, β = 0, 1 Hz);
- ``kalman-rts``: constant-velocity Kalman filter and RTS smoother, noise levels of the
  greatest log-evidence (:func:`jaxtrack.vision.smoothing.fit_kalman_noise`, per view), every
  detected marker observed; ``kalman-rts vis>=0.5``: the same with markers of visibility below
  ``--min-confidence`` (0.5, MediaPipe's own drawing threshold) treated as missing and filled
  by the smoother;
- 3-D: ``dlt`` (each frame's markers triangulated from the four views, weighted by their
  visibility: :func:`jaxtrack.vision.triangulation.triangulate`), ``dlt+butterworth`` (then
  Pose2Sim's filter in 3-D: Pose2Sim's own pipeline), ``dlt of kalman-rts`` (the smoothed 2-D
  tracks triangulated).

Scores (:func:`score_2d`, :func:`score_3d`): per frame the mean distance over the 12 markers to
the reference's; ``within_15``: the fraction of the scored frames whose error is at most 15 % of
the reference's torso (neck to pelvis: in the view's pixels for 2-D, in metres for 3-D); a
frame where the estimate lacks a marker is not within; ``error_torso``: the mean error in
torso lengths over the frames with every marker; ``error_px`` / ``error_mm`` likewise.

More rows: :func:`evaluate` takes ``extra_2d`` (name → view → ``(frames, 12, 2)`` estimate of
:attr:`Setting.frame_indices`) and ``extra_3d`` (name → ``(frames, 12, 3)`` world metres), so a
tracker's estimates are scored as these are.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["DEFAULT_DETECTIONS", "MIN_CONFIDENCE", "VIEWS", "Setting", "baseline_estimates",
           "detect_views", "evaluate", "left_right_swaps", "load_setting", "main", "score_2d",
           "score_3d", "table"]

VIEWS = ("cam01", "cam02", "cam03", "cam04")
DEFAULT_DETECTIONS = (Path(__file__).resolve().parents[2] / "tests" / "data" / "detections"
                      / "mediapipe_pose2sim")
"""The cached MediaPipe detections of the four videos (BSD-3 video, the detector's output)."""
MIN_CONFIDENCE = 0.5
"""Visibility below which the second Kalman row treats a marker as missing: MediaPipe's own
drawing threshold (``drawing_utils._VISIBILITY_THRESHOLD``)."""
DETECTOR_SCALE = 0.5
"""The videos are decoded at this scale for the detector (1080x1920 → 540x960)."""
WITHIN = 0.15
"""The headline threshold, a fraction of the torso."""


@dataclass(frozen=True)
class Setting:
    """What every row is scored on.

    Attributes:
        views: camera names (``VIEWS``).
        frame_indices: ``(frames,)`` the video frames scored (those the reference covers).
        fps: the videos' frame rate.
        truth_2d: view → ``(frames, 12, 2)`` the reference's markers in that view's pixels.
        truth_3d: ``(frames, 12, 3)`` the reference's markers, world metres (Z up).
        detections: view → ``(points (frames, 12, 2), confidence (frames, 12))``.
        cameras: the views' :class:`jaxtrack.body.Camera` (``Calib.qca.txt``).
        detector: view → the detector's run record (version, ms per frame, first frame's s).
    """

    views: tuple[str, ...]
    frame_indices: np.ndarray
    fps: float
    truth_2d: dict
    truth_3d: np.ndarray
    detections: dict
    cameras: list
    detector: dict


def detect_views(folder: Path, out: Path, views=VIEWS, progress=None) -> dict:
    """MediaPipe on every frame of each view's video, written to ``out/VIEW.npz`` (the worker's
    format, landmarks and visibility as float32); views already there are read, not rerun.
    Returns view → the file's arrays."""
    from jaxtrack._files import write_npz_atomically
    from jaxtrack.vision import read_video
    from jaxtrack.vision.mediapipe import detect_pose

    found = {}
    for view in views:
        path = Path(out) / f"{view}.npz"
        if not path.is_file():
            # decoded at half size (960 px tall, as jaxtrack.vision.mediapipe.person_keypoints
            # does): MediaPipe resizes every frame to 256 px itself, so nothing is lost but
            # memory; the landmarks are mapped back to the video's pixels
            video = read_video(Path(folder) / "videos" / f"{view}.mp4", scale=DETECTOR_SCALE)
            result = detect_pose(video.frames)
            landmarks = (result["landmarks"] + 0.5) / DETECTOR_SCALE - 0.5
            arrays = {"landmarks": landmarks.astype(np.float32),
                      "visibility": result["visibility"].astype(np.float32),
                      "found": result["found"], "seconds": result["seconds"],
                      "first_seconds": np.float64(result["first_seconds"]),
                      "wall_seconds": np.float64(result["wall_seconds"]),
                      "version": np.str_(result["version"]),
                      "frame_indices": video.frame_indices,
                      "scale": np.float64(DETECTOR_SCALE)}
            Path(out).mkdir(parents=True, exist_ok=True)
            write_npz_atomically(path, arrays, compress=True)
        with np.load(path, allow_pickle=False) as data:
            found[view] = {key: data[key] for key in data.files}
        if progress is not None:
            progress.update(1)
    return found


def load_setting(folder: Path | None = None, detections: Path = DEFAULT_DETECTIONS,
                 progress=None) -> Setting:
    """The Pose2Sim demo's reference and the detections of its four views (module docstring).

    Raises:
        FileNotFoundError: no data folder. jaxtrack.vision.mediapipe.DetectorUnavailableError:
            a view's detections are neither cached nor can be made.
    """
    from jaxtrack.body import read_qca
    from jaxtrack.evaluation.reference import (
        TRC_FILES,
        default_folder,
        load_reference,
        read_trc,
        to_upper_body,
        trc_to_world,
    )
    from jaxtrack.vision.mediapipe import detected_keypoints

    folder = Path(folder) if folder is not None else default_folder()
    references = load_reference(folder, num_video_frames=100)
    first = references[VIEWS[0]]
    _, positions, rate = read_trc(folder / "reference" / "pose-3d" / TRC_FILES[False])
    truth_3d = to_upper_body(trc_to_world(positions))[first.rows]
    runs = detect_views(folder, detections, VIEWS, progress)
    found, detector = {}, {}
    for view in VIEWS:
        run = runs[view]
        frames = [int(i) for i in run["frame_indices"]]
        rows = [frames.index(int(i)) for i in first.frame_indices]
        points, confidence = detected_keypoints({key: run[key][rows] for key in
                                                 ("landmarks", "visibility", "found")})
        found[view] = (points, confidence)
        detector[view] = {"version": str(run["version"]),
                          "ms_per_frame": 1e3 * float(np.median(run["seconds"])),
                          "first_frame_seconds": float(run["first_seconds"]),
                          "frames_without_person": int((~run["found"].astype(bool)).sum())}
    cameras = {camera.name: camera for camera in read_qca(folder / "Calib.qca.txt")}
    return Setting(VIEWS, np.asarray(first.frame_indices), float(rate),
                   {view: references[view].markers for view in VIEWS}, truth_3d, found,
                   [cameras[view] for view in VIEWS], detector)


def _torso(markers: np.ndarray) -> np.ndarray:
    from jaxtrack.body import UPPER_BODY_12

    names = list(UPPER_BODY_12)
    return np.linalg.norm(markers[:, names.index("neck")] - markers[:, names.index("pelvis")],
                          axis=-1)


def _score(estimate: np.ndarray, truth: np.ndarray) -> dict:
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    if estimate.shape != truth.shape:
        raise ValueError(f"an estimate must have shape {truth.shape} (frames, 12 markers, "
                         f"coordinates), got {estimate.shape}")
    errors = np.linalg.norm(estimate - truth, axis=-1).mean(-1)  # NaN where a marker is missing
    torso = _torso(truth)
    complete = np.isfinite(errors)
    relative = errors / torso
    return {"frames": int(len(errors)), "frames_complete": int(complete.sum()),
            "within_15": float(np.mean(complete & (np.nan_to_num(relative, nan=np.inf)
                                                   <= WITHIN))),
            "error_torso": float(np.mean(relative[complete])) if complete.any() else None,
            "errors": np.where(complete, errors, np.nan), "torso": torso}


def score_2d(estimate, truth) -> dict:
    """One view's ``(frames, 12, 2)`` estimate against the reference's markers (pixels):
    ``frames``, ``frames_complete``, ``within_15``, ``error_torso``, ``error_px``."""
    scored = _score(estimate, truth)
    errors = scored.pop("errors")
    scored.pop("torso")
    scored["error_px"] = float(np.nanmean(errors)) if np.isfinite(errors).any() else None
    return scored


def score_3d(estimate, truth) -> dict:
    """A ``(frames, 12, 3)`` estimate against the reference (metres): as :func:`score_2d` with
    ``error_mm`` for ``error_px``."""
    scored = _score(estimate, truth)
    errors = scored.pop("errors")
    scored.pop("torso")
    scored["error_mm"] = 1e3 * float(np.nanmean(errors)) if np.isfinite(errors).any() else None
    return scored


def baseline_estimates(setting: Setting, *, min_confidence: float = MIN_CONFIDENCE
                       ) -> tuple[dict, dict, dict]:
    """The baselines' estimates: ``(rows_2d, rows_3d, notes)``, rows_2d name → view →
    ``(frames, 12, 2)``, rows_3d name → ``(frames, 12, 3)``, notes (the fitted noise levels,
    seconds per row)."""
    from jaxtrack.vision.smoothing import butterworth_filter, kalman_smoother, one_euro_filter
    from jaxtrack.vision.triangulation import triangulate

    confident = f"kalman-rts vis>={min_confidence:g}"
    rows = {name: {} for name in ("raw", "butterworth", "one-euro", "kalman-rts", confident)}
    notes = {"kalman_noise": {}, "seconds": {name: 0.0 for name in rows}}
    for view in setting.views:
        points, confidence = setting.detections[view]
        for name, smooth in (("raw", lambda p, c: p),
                             ("butterworth", lambda p, c: butterworth_filter(p, setting.fps)),
                             ("one-euro", lambda p, c: one_euro_filter(p, setting.fps)),
                             ("kalman-rts", 0.0), (confident, min_confidence)):
            started = time.perf_counter()
            if not callable(smooth):
                estimate, _, noise = kalman_smoother(points, setting.fps, confidence=confidence,
                                                     min_confidence=smooth)
                notes["kalman_noise"].setdefault(name, {})[view] = noise
            else:
                estimate = smooth(points, confidence)
            rows[name][view] = estimate
            notes["seconds"][name] += time.perf_counter() - started
    stacked = np.stack([setting.detections[view][1] for view in setting.views])

    def dlt(per_view):
        world, _ = triangulate(np.stack([per_view[view] for view in setting.views]),
                               setting.cameras, confidence=stacked)
        return world

    raw_world = dlt(rows["raw"])
    rows_3d = {"dlt": raw_world,
               "dlt+butterworth": butterworth_filter(raw_world, setting.fps)}
    # the smoothed tracks have no confidence of their own: every view weighs 1
    rows_3d["dlt of kalman-rts"] = triangulate(
        np.stack([rows["kalman-rts"][view] for view in setting.views]), setting.cameras)[0]
    return rows, rows_3d, notes


def evaluate(setting: Setting, *, extra_2d: Mapping | None = None,
             extra_3d: Mapping | None = None, min_confidence: float = MIN_CONFIDENCE) -> dict:
    """Every row scored: ``{"rows_2d": {name: {view: score, "all": mean over views}},
    "rows_3d": {name: score}, "detector": ..., "notes": ...}``. ``extra_2d`` / ``extra_3d``
    add rows (module docstring)."""
    rows_2d, rows_3d, notes = baseline_estimates(setting, min_confidence=min_confidence)
    for name, per_view in (extra_2d or {}).items():
        missing = [view for view in setting.views if view not in per_view]
        if missing:
            raise ValueError(f"extra row {name!r} lacks views {missing}")
        rows_2d[name] = per_view
    rows_3d.update(extra_3d or {})
    swaps = {view: left_right_swaps(rows_2d["raw"][view], setting.truth_2d[view])
             for view in setting.views}
    scored_2d = {}
    for name, per_view in rows_2d.items():
        views = {view: score_2d(per_view[view], setting.truth_2d[view])
                 for view in setting.views}
        scored_2d[name] = {**views, "all": _mean_over_views(views)}
    return {"rows_2d": scored_2d,
            "rows_3d": {name: score_3d(world, setting.truth_3d)
                        for name, world in rows_3d.items()},
            "raw_left_right_swaps": swaps, "detector": setting.detector, "notes": notes,
            "frames": [int(i) for i in setting.frame_indices], "fps": setting.fps,
            "min_confidence": min_confidence}


def left_right_swaps(estimate, truth) -> dict:
    """How often a ``(frames, 12, 2)`` estimate is nearer ``truth`` with its left and right
    markers exchanged: ``frames`` (their count) and ``error_torso_undone`` (its mean error in
    torso lengths with those frames exchanged back)."""
    from jaxtrack.body import UPPER_BODY_12

    names = list(UPPER_BODY_12)
    mirror = [names.index(name.replace("left", "@").replace("right", "left").replace("@", "right"))
              for name in names]
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    as_is = np.linalg.norm(estimate - truth, axis=-1).mean(-1)
    exchanged = np.linalg.norm(estimate[:, mirror] - truth, axis=-1).mean(-1)
    swapped = exchanged < as_is
    undone = np.where(swapped[:, None, None], estimate[:, mirror], estimate)
    return {"frames": int(swapped.sum()), "error_torso_undone": score_2d(undone, truth)[
        "error_torso"]}


def _mean_over_views(views: Mapping) -> dict:
    out = {}
    for key in ("within_15", "error_torso", "error_px"):
        values = [score[key] for score in views.values() if score[key] is not None]
        out[key] = float(np.mean(values)) if len(values) == len(views) else None
    return out


def _cell(value, scale: float = 100.0, digits: int = 1) -> str:
    return "–" if value is None else f"{scale * value:.{digits}f}"


def table(results: Mapping) -> str:
    """Markdown: 2-D rows, per view and over the views, "error % torso / within 15 %"; then the
    3-D rows."""
    views = [view for view in next(iter(results["rows_2d"].values())) if view != "all"]
    lines = ["| 2-D | " + " | ".join(views) + " | all views |",
             "|---|" + "---|" * (len(views) + 1)]
    for name, row in results["rows_2d"].items():
        cells = [f"{_cell(row[key]['error_torso'])} / {_cell(row[key]['within_15'], digits=0)}"
                 for key in (*views, "all")]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", "| 3-D (four views) | error % torso | within 15 % | error mm | frames complete |",
              "|---|---|---|---|---|"]
    for name, row in results["rows_3d"].items():
        lines.append(f"| {name} | {_cell(row['error_torso'])} | {_cell(row['within_15'], digits=0)}"
                     f" | {_cell(row['error_mm'], 1.0)} | {row['frames_complete']}/"
                     f"{row['frames']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring)."""
    from tqdm import tqdm

    from jaxtrack._files import write_json_atomically

    parser = argparse.ArgumentParser(prog="python -m jaxtrack.experiments.detections_evaluation",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    parser.add_argument("--data", type=Path, default=None,
                        help="the pose2sim_demo_singleperson folder (default: the shared data)")
    parser.add_argument("--detections", type=Path, default=DEFAULT_DETECTIONS,
                        help="the cached detections, VIEW.npz; missing views are detected "
                             "(make detector)")
    parser.add_argument("--min-confidence", type=float, default=MIN_CONFIDENCE,
                        help="visibility below which the second Kalman row treats a marker "
                             "as missing")
    args = parser.parse_args(argv)
    if not 0 <= args.min_confidence <= 1:
        parser.error(f"--min-confidence must lie in [0, 1], got {args.min_confidence}")
    if args.json is not None and args.json.suffix != ".json":
        parser.error(f"--json {args.json}: give a .json file name")
    from jaxtrack.vision.mediapipe import DetectorUnavailableError

    try:
        with tqdm(total=len(VIEWS), desc="detections", file=sys.stderr) as progress:
            setting = load_setting(args.data, args.detections, progress)
    except (FileNotFoundError, DetectorUnavailableError) as error:
        parser.exit(1, f"{parser.prog}: {' '.join(str(error).split())}\n")
    started = time.perf_counter()
    results = evaluate(setting, min_confidence=args.min_confidence)
    results["seconds"] = time.perf_counter() - started
    results["command"] = ("python -m jaxtrack.experiments.detections_evaluation"
                          + (f" --json {args.json}" if args.json else ""))
    print(table(results))
    for view, record in setting.detector.items():
        print(f"{view}: MediaPipe {record['version']} {record['ms_per_frame']:.1f} ms/frame "
              f"(first {record['first_frame_seconds']:.2f} s), "
              f"{record['frames_without_person']} frames without a person, left and right "
              f"exchanged in {results['raw_left_right_swaps'][view]['frames']} (undone: "
              f"{_cell(results['raw_left_right_swaps'][view]['error_torso_undone'])} % torso)")
    if args.json is not None:
        write_json_atomically(args.json, results)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
