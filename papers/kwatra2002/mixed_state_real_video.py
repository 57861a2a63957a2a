"""Kwatra et al.'s mixed-state tracker on the four real Pose2Sim videos, scored against the
triangulated reference: the instantaneous estimate (extended Ghost) against temporal
integration (filtered and smoothed).

Each camera's video (``shared/data/pose2sim_demo_singleperson/videos``, 100 frames at 60 fps, a
man balancing on a beam) is downscaled so its longer side is at most ``--max-size`` pixels (640
by default, the paper's resolution), its silhouettes are taken from each source of
``--silhouettes``, and the posture model of
``papers.kwatra2002.mixed_state_evaluation`` (trained on the training clips, cached beside its JSON)
with the tracker's defaults filters and smooths them. The truth is the reference
(``jaxtrack.evaluation.reference``) projected into each camera: the top of the head (BODY_25B
``Head``, where Ghost's head is, at the silhouette's top), the wrists and the ankles, as the
issue that asked for this score names them; hands and feet under the best left/right assignment
per frame (the paper's superposition). The true posture of each frame comes from the reference's
3-D keypoints by the rule that labels the training clips
(:func:`jaxtrack.priors.postures.posture_labels`): the man stands in 54 of the 99 scored frames
and bends (torso more than 30° from vertical, in a lunge) in the other 45.

The silhouettes' sources:

- ``background``: background subtraction against the whole video's median, as ``jaxtrack track
  --method mixed-state`` takes them by default. The man barely leaves his place, so the median
  holds him and his silhouette is fragments.
- ``mediapipe``: MediaPipe's person segmentation (``jaxtrack/vision/mediapipe.py``, in its own venv,
  ``make detector``; skipped where that venv is missing), the masks a user without an
  empty plate of the scene would bring with ``jaxtrack track --masks``. They are made at 640
  pixels on the longer side, cached in ``benchmarks/results/mediapipe_masks/`` and resized to
  the tracked frames.

    python -m papers.kwatra2002.mixed_state_real_video [--particles 500] [--max-size 640]
        [--silhouettes background mediapipe]

Prints a table per camera and source and overall per source (mean squared error per part in px²
at the tracked size, the fraction of frames within 20 px, the posture error) and writes
``papers/kwatra2002/results/mixed_state_real_video.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, print_table, write_json

RESULTS = Path(__file__).parent / "results"
SOURCES = ("background", "mediapipe")
"""Where the silhouettes come from (module docstring)."""
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
KINDS = ("instantaneous", "filtered", "smoothed")
TRUTH_KEYPOINTS = ("Head", "RWrist", "LWrist", "RAnkle", "LAnkle")
"""The reference keypoints that stand for the five parts (``vision.parts.PART_NAMES``)."""


def truth_parts(keypoints: np.ndarray) -> np.ndarray:
    """``(time, 5, 2)`` head, hands and feet from ``(time, 21, 2)`` reference keypoints."""
    from jaxtrack.evaluation.reference import TRC_KEYPOINTS

    return keypoints[:, [TRC_KEYPOINTS.index(name) for name in TRUTH_KEYPOINTS]]


LABEL_KEYPOINTS = {"head": ("Head",), "neck": ("Neck",), "pelvis": ("LHip", "RHip"),
                   "left_hip": ("LHip",), "left_knee": ("LKnee",), "left_ankle": ("LAnkle",),
                   "right_hip": ("RHip",), "right_knee": ("RKnee",), "right_ankle": ("RAnkle",)}
"""The markers :func:`jaxtrack.priors.postures.posture_labels` needs, each the mean of these
reference keypoints (the pelvis is the hips' midpoint)."""


def label_markers(keypoints: np.ndarray) -> np.ndarray:
    """``(..., 9, D)`` the :data:`LABEL_KEYPOINTS` markers of ``(..., 21, D)`` reference
    keypoints (``TRC_KEYPOINTS`` order)."""
    from jaxtrack.evaluation.reference import TRC_KEYPOINTS

    return np.stack([np.mean([keypoints[..., TRC_KEYPOINTS.index(name), :] for name in names],
                             axis=0) for names in LABEL_KEYPOINTS.values()], axis=-2)


def truth_postures(trc_keypoints: np.ndarray, image_keypoints: np.ndarray) -> np.ndarray:
    """``(rows,)`` the posture of every ``.trc`` row by the training clips' labelling rule, from
    its ``(rows, 21, 3)`` keypoints (the ``.trc``'s own Y-up axes, metres) and their ``(rows,
    21, 2)`` image positions in one camera (which only decide a lying figure's side)."""
    from jaxtrack.priors.postures import posture_labels

    return posture_labels(label_markers(trc_keypoints), label_markers(image_keypoints),
                          list(LABEL_KEYPOINTS))


def posture_model(folder: Path, spec=None):
    """The training clips' posture model of ``spec`` (``papers.kwatra2002.mixed_state_evaluation``'s
    ``K,COVARIANCE,RIDGE,VIEWS`` tuple; None: the library's), shared with that benchmark's
    cache in ``folder``."""
    from papers.kwatra2002.mixed_state_evaluation import default_spec, trained_models

    spec = default_spec() if spec is None else spec
    return trained_models(folder, [spec])[spec]


def camera_scores(folder: Path, camera: str, model, *, max_size: int, particles: int,
                  seed: int, masks_file: Path | None = None) -> dict:
    """Track one camera's video and score every estimate against the reference; the
    silhouettes from ``masks_file`` (:func:`jaxtrack.vision.read_masks`) where given, else
    against the video's median background."""
    import jax.random as jr

    from jaxtrack.evaluation.reference import TRC_FILES, load_reference, read_trc
    from jaxtrack.experiments import mixed_state as ms
    from jaxtrack.trackers.mixed_state import observations_from_silhouettes
    from jaxtrack.vision import masks_for_frames, median_background, read_masks, read_video
    from jaxtrack.vision.foreground import largest_component
    from jaxtrack.vision.histograms import FRAME_OK, silhouettes

    path = folder / "videos" / f"{camera}.mp4"
    height, width = read_video(path, max_frames=1).frames.shape[1:3]
    video = read_video(path, scale=min(1.0, max_size / max(width, height)))
    scale = video.frames.shape[2] / width  # the decoder rounds the size
    if masks_file is None:
        masks = silhouettes(video.frames, median_background(video.frames))
    else:  # the largest blob, as silhouettes() and jaxtrack track --masks keep it
        masks = np.stack([largest_component(mask) for mask in masks_for_frames(
            read_masks(masks_file), video.frame_indices, video.image_size, name=str(masks_file))])
    num_bins = (model.postures.num_features - 1) // 2
    observations = observations_from_silhouettes(masks, num_bins=num_bins)
    reference = load_reference(folder, num_video_frames=len(video.frames))[camera]
    indices = reference.frame_indices
    truth = truth_parts(reference.scaled(scale).keypoints)
    tracked = ms.track(jr.PRNGKey(seed), model, observations, particles)
    ok = np.asarray(tracked["status"])[indices] == FRAME_OK
    _, trc, _ = read_trc(folder / "reference" / "pose-3d" / TRC_FILES[False])
    labels = truth_postures(np.asarray(trc, np.float64)[reference.rows], reference.keypoints)
    scores = {kind: ms.score(tracked[kind]["parts"][indices], tracked[kind]["posture"][indices],
                             truth, labels, valid=ok)
              for kind in KINDS}
    squared = {kind: ms.part_squared_errors(tracked[kind]["parts"][indices], truth)[ok]
               for kind in KINDS}
    confusion = {kind: posture_confusion(labels[ok], tracked[kind]["posture"][indices][ok])
                 for kind in KINDS}
    return {"size": [int(video.frames.shape[2]), int(video.frames.shape[1])],
            "frames": int(len(indices)), "frames_with_silhouette": int(ok.sum()),
            "truth_in_silhouette": truth_in_silhouette(masks[indices], truth),
            "scores": scores, "squared": squared, "confusion": confusion,
            "seconds": tracked["seconds"],
            "figure": _figure(video.frames[indices], masks[indices], truth)}


def posture_confusion(truth: np.ndarray, estimate: np.ndarray) -> list[list[int]]:
    """``(postures, postures)`` frame counts, rows the true posture, columns the estimate."""
    from jaxtrack.priors.postures import NUM_POSTURES

    counts = np.zeros((NUM_POSTURES, NUM_POSTURES), int)
    np.add.at(counts, (np.asarray(truth, int), np.asarray(estimate, int)), 1)
    return counts.tolist()


def truth_in_silhouette(masks: np.ndarray, truth: np.ndarray) -> dict:
    """The fraction of frames whose silhouette covers each reference part (within 5 px): how
    much of the person the silhouette sees."""
    import cv2

    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (11, 11))
    height, width = masks.shape[1:]
    inside = np.zeros(truth.shape[:2], bool)
    for t, mask in enumerate(masks):
        grown = cv2.dilate(mask.astype(np.uint8), kernel) > 0
        columns = np.clip(np.round(truth[t, :, 0]).astype(int), 0, width - 1)
        rows = np.clip(np.round(truth[t, :, 1]).astype(int), 0, height - 1)
        inside[t] = grown[rows, columns]
    return {"head": float(inside[:, 0].mean()), "hands": float(inside[:, 1:3].mean()),
            "feet": float(inside[:, 3:5].mean()), "all": float(inside.mean())}


def _figure(frames: np.ndarray, masks: np.ndarray, truth: np.ndarray, count: int = 4
            ) -> np.ndarray:
    """``count`` evenly spaced frames side by side: the silhouette in green, the reference's
    head, wrists and ankles in red."""
    import cv2

    tiles = []
    for t in np.linspace(0, len(frames) - 1, count).round().astype(int):
        tile = frames[t].astype(np.float32)
        tile[masks[t] > 0] = 0.5 * tile[masks[t] > 0] + 0.5 * np.array([0, 255, 0])
        tile = tile.astype(np.uint8)
        for x, y in truth[t]:
            cv2.circle(tile, (int(round(x)), int(round(y))), 5, (255, 0, 0), -1)
        tiles.append(tile)
    return np.concatenate(tiles, axis=1)


def _rows(scores: dict) -> list[dict]:
    return [{"estimate": kind, **{f"mse_{part}": value["mse"][part]
                                  for part in ("head", "hands", "feet", "all")},
             "within_head": 100 * value["within"]["head"]["20"],
             "within_all": 100 * value["within"]["all"]["20"],
             "posture_error": 100 * value["posture_error"]}
            for kind, value in scores.items() if value["frames"]]


_COLUMNS = [("estimate", "estimate", "s"), ("mse_head", "MSE head", ".0f"),
            ("mse_hands", "MSE hands", ".0f"), ("mse_feet", "MSE feet", ".0f"),
            ("mse_all", "MSE all", ".0f"), ("within_head", "head ≤ 20 px %", ".0f"),
            ("within_all", "parts ≤ 20 px %", ".0f"),
            ("posture_error", "posture error %", ".0f")]


def _pooled(per_camera: dict) -> dict:
    """Every camera's frames together: MSE per part group, within 20 px."""
    pooled = {}
    groups = {"head": [0], "hands": [1, 2], "feet": [3, 4], "all": [0, 1, 2, 3, 4]}
    for kind in KINDS:
        squared = np.concatenate([camera["squared"][kind] for camera in per_camera.values()])
        errors = [camera["scores"][kind]["posture_error"] * camera["scores"][kind]["frames"]
                  for camera in per_camera.values() if camera["scores"][kind]["frames"]]
        distance = np.sqrt(squared)
        pooled[kind] = {
            "mse": {name: float(squared[:, idx].mean()) for name, idx in groups.items()},
            "within": {name: {"20": float(np.mean(distance[:, idx] <= 20))}
                       for name, idx in groups.items()},
            "posture_error": float(sum(errors) / len(squared)), "frames": int(len(squared)),
            "confusion": np.sum([camera["confusion"][kind] for camera in per_camera.values()],
                                axis=0).tolist()}
    return pooled


def _write_figure(path: Path, rows: list[np.ndarray]) -> None:
    """The cameras' rows stacked (padded to one width), written atomically as a PNG."""
    import os

    import cv2

    width = max(row.shape[1] for row in rows)
    padded = [np.pad(row, ((0, 0), (0, width - row.shape[1]), (0, 0))) for row in rows]
    image = cv2.cvtColor(np.concatenate(padded, axis=0), cv2.COLOR_RGB2BGR)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(path.stem + ".tmp.png")
    if not cv2.imwrite(str(temporary), image):
        raise SystemExit(f"{path}: could not write the figure")
    os.replace(temporary, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--max-size", type=int, default=640,
                        help="downscale so the longer side is at most PX")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--silhouettes", nargs="+", choices=SOURCES, default=list(SOURCES),
                        help="where the silhouettes come from (module docstring)")
    parser.add_argument("--posture-model", default=None, metavar="K,COV,RIDGE,VIEWS",
                        help="the posture model (papers.kwatra2002.mixed_state_evaluation's "
                             "--posture-models form; default: the library's)")
    parser.add_argument("--out", default=str(RESULTS / "mixed_state_real_video.json"))
    args = parser.parse_args(argv)
    from jaxtrack.evaluation.reference import default_folder
    from papers.kwatra2002.mixed_state_evaluation import posture_model_spec

    try:
        spec = None if args.posture_model is None else posture_model_spec(args.posture_model)
    except ValueError as error:
        parser.error(f"--posture-model: {error}")

    folder = default_folder()
    if not (folder / "videos").is_dir():
        raise SystemExit(f"{folder / 'videos'}: the Pose2Sim demo's videos are not there")
    begin = time.perf_counter()
    model = posture_model(Path(args.out).parent, spec)
    from jaxtrack.trackers.mixed_state import MixedStateModel

    tracker_model = MixedStateModel(model)
    results, skipped, figures = {}, {}, []
    for source in dict.fromkeys(args.silhouettes):
        per_camera = {}
        for camera in CAMERAS:
            masks_file = None
            if source == "mediapipe":
                from jaxtrack.vision.mediapipe import demo_masks

                masks_file = demo_masks(folder, camera)
                if isinstance(masks_file, dict):
                    skipped[source] = masks_file["skipped"]
                    print(f"\n{source} silhouettes skipped: {skipped[source]}")
                    break
            per_camera[camera] = camera_scores(folder, camera, tracker_model,
                                               max_size=args.max_size,
                                               particles=args.particles, seed=args.seed,
                                               masks_file=masks_file)
            _print_camera(source, camera, per_camera[camera])
        if source in skipped:
            continue
        results[source] = {"cameras": per_camera, "all": _pooled(per_camera)}
        figures += [result["figure"] for result in per_camera.values()]
    for source, result in results.items():
        pooled = result["all"]
        print(f"\n{source} silhouettes, all four cameras ({pooled['smoothed']['frames']} "
              f"frames); device: {device_description()}")
        print_table(_rows(pooled), _COLUMNS)
        _print_confusion(pooled)
    print(f"{time.perf_counter() - begin:.0f} s")
    figure = Path(args.out).with_suffix(".png")
    if figures:
        _write_figure(figure, figures)
        print(f"wrote {figure} (silhouettes and the reference, four frames per camera, each "
              f"source's cameras in turn)")
    options = tracker_model
    write_json(args.out, {
        "benchmark": "mixed_state_real_video", "device": device_description(),
        "arguments": vars(args), "truth_keypoints": list(TRUTH_KEYPOINTS),
        "tracker": {"redetect_probability": float(options.redetect_probability),
                    "redraw_on_switch": options.redraw_on_switch},
        "skipped": skipped,
        "silhouettes": {source: {
            "cameras": {camera: {key: value for key, value in camera_result.items()
                                 if key not in ("squared", "figure")}
                        for camera, camera_result in result["cameras"].items()},
            "all": result["all"]} for source, result in results.items()}})
    return 0


def _print_confusion(pooled: dict) -> None:
    """The instantaneous and smoothed postures against the truth, over the postures that occur."""
    from jaxtrack.priors.postures import POSTURE_NAMES

    for kind in ("instantaneous", "smoothed"):
        counts = np.asarray(pooled[kind]["confusion"])
        seen = [q for q in range(len(POSTURE_NAMES)) if counts[q].sum() or counts[:, q].sum()]
        print(f"{kind} posture (rows: the truth; columns: the estimate)")
        print_table([{"truth": POSTURE_NAMES[q], **{POSTURE_NAMES[r]: int(counts[q, r])
                                                  for r in seen}} for q in seen],
                    [("truth", "truth", "s"), *((POSTURE_NAMES[r], POSTURE_NAMES[r], "d")
                                                for r in seen)])


def _print_camera(source: str, camera: str, result: dict) -> None:
    print(f"\n{camera}, {source} silhouettes: {result['frames']} frames at {result['size'][0]}x"
          f"{result['size'][1]}, {result['frames_with_silhouette']} with a silhouette; px² "
          f"against the reference's head top, wrists and ankles")
    covered = result["truth_in_silhouette"]
    print(f"the silhouette covers the reference's head in {100 * covered['head']:.0f} % of "
          f"frames, its hands in {100 * covered['hands']:.0f} %, its feet in "
          f"{100 * covered['feet']:.0f} %")
    print_table(_rows(result["scores"]), _COLUMNS)


if __name__ == "__main__":
    raise SystemExit(main())
