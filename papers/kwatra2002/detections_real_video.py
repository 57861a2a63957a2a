"""Kwatra et al.'s mixed-state tracker on the four real Pose2Sim videos with a per-frame
detector's keypoints as part hypotheses beside the silhouette's, against the silhouette alone
and against the detector's own keypoints, scored against the triangulated reference.

The videos, their silhouettes (background subtraction against each video's median, as ``jaxtrack
track --method mixed-state`` takes them), the truth (the reference's head top, wrists and ankles
projected into each camera, hands and feet under the best left/right assignment per frame) and
the scores are :mod:`papers.kwatra2002.mixed_state_real_video`'s. The detections are MediaPipe
Pose's, cached in ``tests/data/detections/mediapipe_pose2sim/`` (never OpenPose's: the reference
was triangulated from OpenPose), read with ``markers=DETECTION_MARKERS`` and scaled to the
tracked frames; a keypoint of visibility at least ``--min-confidence`` replaces the silhouette's
hypothesis of that part in every posture (:func:`jaxtrack.vision.parts.detection_hypotheses`).
The posture model is the one ``jaxtrack track --method mixed-state`` uses (the bundled
``postures.npz``), with the tracker's defaults.

Estimates, each scored on the frames with a silhouette (the tracker's frames):

- ``silhouette``: the paper's tracker; instantaneous (extended Ghost), filtered, smoothed;
- ``silhouette+detections``: the same tracker on the merged hypotheses, parts projected onto
  the silhouette and the confident keypoints (:func:`jaxtrack.trackers.mixed_state.
  with_detections`), as ``jaxtrack track --method mixed-state --keypoints`` runs it;
- ``silhouette+detections posterior``: the same with the parts drawn from the posterior
  (``part_proposal="posterior"``, not the default);
- with ``--projections``, the same tracker with the parts projected onto the silhouette alone
  (``silhouette+detections silhouette-projection``, the paper's step) or not projected
  (``silhouette+detections no-projection``): what chose the projection of ``with_detections``;
- ``mediapipe``: MediaPipe's own head (the base of the skull by the readers' rule, the best head
  point they give; the truth is the head's top), wrists and ankles;
- ``mediapipe butterworth``: those after Pose2Sim's Butterworth filter (filtfilt, 6 Hz, order 4).

    python -m papers.kwatra2002.detections_real_video [--particles 500] [--max-size 640]
        [--cameras cam01 ...] [--min-confidence 0.5] [--seed 1] [--projections]

Prints a table per camera and over all cameras (MSE per part in px² at the tracked size, the
fraction of parts within 20 px), names every baseline that beats the tracker with detections,
and writes ``papers/kwatra2002/results/detections_real_video.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, print_table, write_json
from papers.kwatra2002.mixed_state_real_video import CAMERAS, KINDS, truth_parts, truth_postures

RESULTS = Path(__file__).parent / "results"
DETECTIONS = Path(__file__).resolve().parents[2] / "tests" / "data" / "detections" / (
    "mediapipe_pose2sim")
FPS = 60.0  # the Pose2Sim demo's videos
PART_MARKERS = ("head", "right_wrist", "left_wrist", "right_ankle", "left_ankle")
"""The detector's markers scored as the five parts (``vision.parts.DETECTION_PART_MARKERS``)."""
TRACKERS = ("silhouette", "silhouette+detections", "silhouette+detections posterior")
BASELINES = ("mediapipe", "mediapipe butterworth")
GROUPS = {"head": [0], "hands": [1, 2], "feet": [3, 4], "all": [0, 1, 2, 3, 4]}


def camera_detections(camera: str, scale: float, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """MediaPipe's ``points (frames, markers, 2)`` in tracked pixels and ``confidence (frames,
    markers)`` of one camera, :data:`jaxtrack.vision.detections.DETECTION_MARKERS` order."""
    from jaxtrack.vision.detections import DETECTION_MARKERS, follow_person, load_detections

    detections = load_detections(DETECTIONS / f"{camera}.npz", markers=DETECTION_MARKERS)
    points, confidence = follow_person(detections)
    rows = detections.frame_ids - detections.frame_ids[0]
    out = np.full((frames, len(DETECTION_MARKERS), 2), np.nan)
    sure = np.zeros((frames, len(DETECTION_MARKERS)))
    keep = rows < frames
    out[rows[keep]], sure[rows[keep]] = points[keep] * scale, confidence[keep]
    return out, sure


def _score(parts: np.ndarray, truth: np.ndarray, valid: np.ndarray) -> dict:
    """Squared errors per part (the paper's superposition for hands and feet), MSE per group
    and the fraction within 20 px, over the ``valid`` frames."""
    from jaxtrack.experiments import mixed_state as ms

    squared = ms.part_squared_errors(parts, truth)[valid]
    distance = np.sqrt(squared)
    return {"squared": squared,
            "mse": {name: float(squared[:, idx].mean()) for name, idx in GROUPS.items()},
            "within_20": {name: float(np.mean(distance[:, idx] <= 20))
                          for name, idx in GROUPS.items()},
            "frames": int(valid.sum())}


def camera_scores(folder: Path, camera: str, model, *, max_size: int, particles: int,
                  seed: int, min_confidence: float, projections: bool = False) -> dict:
    """Track one camera with the silhouette alone and with the detections; score them and the
    detector's own keypoints against the reference."""
    import dataclasses

    import jax.numpy as jnp
    import jax.random as jr

    from jaxtrack.evaluation.reference import TRC_FILES, load_reference, read_trc
    from jaxtrack.experiments import mixed_state as ms
    from jaxtrack.trackers.mixed_state import (
        MixedStateModel,
        observations_from_silhouettes,
        with_detections,
    )
    from jaxtrack.vision import median_background, read_video
    from jaxtrack.vision.detections import DETECTION_MARKERS
    from jaxtrack.vision.histograms import FRAME_OK, silhouettes
    from jaxtrack.vision.smoothing import butterworth_filter

    path = folder / "videos" / f"{camera}.mp4"
    height, width = read_video(path, max_frames=1).frames.shape[1:3]
    video = read_video(path, scale=min(1.0, max_size / max(width, height)))
    scale = video.frames.shape[2] / width  # the decoder rounds the size
    masks = silhouettes(video.frames, median_background(video.frames))
    num_bins = (model.postures.num_features - 1) // 2
    observations = observations_from_silhouettes(masks, num_bins=num_bins)
    points, confidence = camera_detections(camera, scale, len(video.frames))
    merged = with_detections(observations, points, confidence, DETECTION_MARKERS,
                             min_confidence=min_confidence)
    reference = load_reference(folder, num_video_frames=len(video.frames))[camera]
    indices = reference.frame_indices
    truth = truth_parts(reference.scaled(scale).keypoints)
    _, trc, _ = read_trc(folder / "reference" / "pose-3d" / TRC_FILES[False])
    labels = truth_postures(np.asarray(trc, np.float64)[reference.rows], reference.keypoints)
    posterior = MixedStateModel(model.postures, model.part_likelihood,
                                part_proposal="posterior")
    tracked = {"silhouette": ms.track(jr.PRNGKey(seed), model, observations, particles),
               "silhouette+detections": ms.track(jr.PRNGKey(seed), model, merged, particles),
               "silhouette+detections posterior": ms.track(jr.PRNGKey(seed), posterior,
                                                           merged, particles)}
    if projections:
        height, width = masks.shape[1:]
        ys, xs = np.mgrid[:height, :width]
        itself = np.broadcast_to(np.stack([xs, ys], axis=-1).astype(np.int16),
                                 np.shape(observations.nearest))
        for name, nearest in (("silhouette-projection", observations.nearest),
                              ("no-projection", jnp.asarray(itself))):
            variant = dataclasses.replace(merged, nearest=nearest)
            tracked[f"silhouette+detections {name}"] = ms.track(jr.PRNGKey(seed), model,
                                                                variant, particles)
    ok = np.asarray(tracked["silhouette"]["status"])[indices] == FRAME_OK
    estimates, postures = {}, {}
    for name, result in tracked.items():
        for kind in KINDS:
            estimates[f"{name} {kind}"] = result[kind]["parts"][indices]
            postures[f"{name} {kind}"] = float(np.mean(
                result[kind]["posture"][indices][ok] != labels[ok]))
    detected = points[:, [DETECTION_MARKERS.index(name) for name in PART_MARKERS]]
    estimates["mediapipe"] = detected[indices]
    estimates["mediapipe butterworth"] = butterworth_filter(detected, FPS)[indices]
    scores = {name: _score(parts, truth, ok) for name, parts in estimates.items()}
    for name, value in postures.items():
        scores[name]["posture_error"] = value
    confident = confidence[:, [DETECTION_MARKERS.index(name) for name in PART_MARKERS]]
    return {"size": [int(video.frames.shape[2]), int(video.frames.shape[1])],
            "frames": int(len(indices)), "frames_with_silhouette": int(ok.sum()),
            "confident_parts": float(np.mean(confident[indices][ok] >= min_confidence)),
            "seconds": {name: result["seconds"] for name, result in tracked.items()},
            "scores": scores}


def pooled(per_camera: dict) -> dict:
    """Every camera's scored frames together."""
    names = next(iter(per_camera.values()))["scores"]
    out = {}
    for name in names:
        squared = np.concatenate([camera["scores"][name]["squared"]
                                  for camera in per_camera.values()])
        distance = np.sqrt(squared)
        out[name] = {"squared": squared,
                     "mse": {group: float(squared[:, idx].mean())
                             for group, idx in GROUPS.items()},
                     "within_20": {group: float(np.mean(distance[:, idx] <= 20))
                                   for group, idx in GROUPS.items()},
                     "frames": int(len(squared))}
        errors = [camera["scores"][name].get("posture_error") for camera in per_camera.values()]
        if errors[0] is not None:
            frames = [camera["scores"][name]["frames"] for camera in per_camera.values()]
            out[name]["posture_error"] = float(np.dot(errors, frames) / sum(frames))
    return out


def beaten_by(scores: dict) -> dict:
    """For each estimate of the tracker with detections, the baselines (MediaPipe, and the
    tracker on the silhouette alone) whose MSE over all parts is lower."""
    others = [name for name in scores if not name.startswith("silhouette+detections")]
    return {name: [other for other in others
                   if scores[other]["mse"]["all"] < scores[name]["mse"]["all"]]
            for name in scores if name.startswith("silhouette+detections")}


_COLUMNS = [("estimate", "estimate", "s"), ("mse_head", "MSE head", ".0f"),
            ("mse_hands", "MSE hands", ".0f"), ("mse_feet", "MSE feet", ".0f"),
            ("mse_all", "MSE all", ".0f"), ("within_all", "parts ≤ 20 px %", ".0f"),
            ("posture_error", "posture error %", "s")]


def rows(scores: dict) -> list[dict]:
    """One table row per estimate."""
    return [{"estimate": name, **{f"mse_{group}": value["mse"][group] for group in GROUPS},
             "within_all": 100 * value["within_20"]["all"],
             "posture_error": (f"{100 * value['posture_error']:.0f}"
                               if "posture_error" in value else "-")}
            for name, value in scores.items()]


def _without_squared(scores: dict) -> dict:
    return {name: {key: value for key, value in entry.items() if key != "squared"}
            for name, entry in scores.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--max-size", type=int, default=640,
                        help="downscale so the longer side is at most PX")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--cameras", nargs="+", choices=CAMERAS, default=list(CAMERAS))
    parser.add_argument("--min-confidence", type=float, default=None,
                        help="the least visibility of a keypoint that replaces the silhouette's "
                        "hypothesis (default: the tracker's keypoint_confidence)")
    parser.add_argument("--projections", action="store_true",
                        help="also the tracker with detections projecting the parts onto the "
                        "silhouette alone, and not projecting them")
    parser.add_argument("--out", default=str(RESULTS / "detections_real_video.json"))
    args = parser.parse_args(argv)
    from jaxtrack.data.models import default_model
    from jaxtrack.evaluation.reference import default_folder
    from jaxtrack.priors.postures import load_posture_model
    from jaxtrack.trackers.mixed_state import KEYPOINT_CONFIDENCE, MixedStateModel

    min_confidence = (KEYPOINT_CONFIDENCE if args.min_confidence is None
                      else args.min_confidence)
    if not 0 <= min_confidence <= 1:
        parser.error(f"--min-confidence must lie in [0, 1], got {min_confidence}")
    folder = default_folder()
    if not (folder / "videos").is_dir():
        raise SystemExit(f"{folder / 'videos'}: the Pose2Sim demo's videos are not there")
    begin = time.perf_counter()
    model_file = default_model("mixed-state")
    model = MixedStateModel(load_posture_model(model_file).model)
    per_camera = {}
    for camera in args.cameras:
        tick = time.perf_counter()
        per_camera[camera] = camera_scores(folder, camera, model, max_size=args.max_size,
                                           particles=args.particles, seed=args.seed,
                                           min_confidence=min_confidence,
                                           projections=args.projections)
        result = per_camera[camera]
        print(f"\n{camera}: {result['frames']} frames at {result['size'][0]}x"
              f"{result['size'][1]}, {result['frames_with_silhouette']} with a silhouette; "
              f"{100 * result['confident_parts']:.0f} % of MediaPipe's parts confident; px² "
              f"against the reference's head top, wrists and ankles "
              f"({time.perf_counter() - tick:.0f} s)")
        print_table(rows(result["scores"]), _COLUMNS)
    overall = pooled(per_camera)
    print(f"\nall cameras ({', '.join(args.cameras)}), {overall['mediapipe']['frames']} "
          f"frames; device: {device_description()}")
    print_table(rows(overall), _COLUMNS)
    beaten = beaten_by(overall)
    for name, others in beaten.items():
        print(f"{name}: beaten (MSE all parts) by {', '.join(others) if others else 'none'}")
    print(f"{time.perf_counter() - begin:.0f} s")
    write_json(args.out, {
        "benchmark": "detections_real_video", "device": device_description(),
        "arguments": vars(args), "min_confidence": min_confidence,
        "posture_model": str(model_file.name), "detections": str(DETECTIONS.name),
        "detection_markers": list(PART_MARKERS), "tracker": model.options(),
        "cameras": {camera: {**{key: value for key, value in result.items()
                                if key != "scores"},
                             "scores": _without_squared(result["scores"])}
                    for camera, result in per_camera.items()},
        "all": _without_squared(overall), "beaten_by": beaten})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
