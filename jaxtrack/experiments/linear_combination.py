"""Ong & Gong's linear-combination tracker on real motion: training data, training, evaluation,
tracking (the entry points of ``jaxtrack train|evaluate|track --method linear-combination``).

Training and test hybrid vectors come from real mocap rendered through the real Pose2Sim
calibration (``pose2sim/Calib.qca.txt``, four cameras, :func:`pose2sim_cameras`): each camera is
scaled by :data:`CAMERA_SCALE` and its image cropped to :data:`CROP_SIZE` around the subject,
so the figure is large enough for a 100-point contour. Per frame:

* contour: the rendered silhouette's outer contour, ``num_contour`` points from its top-most
  pixel, clockwise (``jaxtrack.vision.contours.silhouette_contour``);
* head and hands: the three skin blobs (``jaxtrack.vision.skin``, with the figure's skin tone as
  the skin sample), inside the silhouette;
* skeleton: the 12 upper-body vertices (``UPPER_BODY_12``) in the camera's frame, metres,
  relative to the neck, so that one silhouette from one view maps to one skeleton.

When tracking, a frame is observed as the tracker sees real video: the silhouette by background
subtraction and connected components, skin blobs inside it, and the gradient-magnitude map
(:func:`observe`). The 3-D error of a frame is the mean distance between estimated and true
skeleton vertices (neck-relative, camera frame), in metres.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import jax.numpy as jnp
import jax.random as jr
import numpy as np

from jaxtrack.body import UPPER_BODY_12, Camera, read_qca, render_motion, stage_for_cameras
from jaxtrack.body.hybrid import HybridLayout, make_hybrid, split_hybrid
from jaxtrack.likelihoods.contour_normals import ContourObservation, FitnessSettings
from jaxtrack.priors.linear_combinations import (
    LinearCombinationModel,
    fit_linear_combinations,
    load_linear_combinations,
    save_linear_combinations,
)
from jaxtrack.trackers._options import Engine
from jaxtrack.trackers.linear_combination import observe_contours

__all__ = ["CAMERA_SCALE", "CROP_SIZE", "DEFAULT_FITNESS", "DEFAULT_SKELETON_ESTIMATE",
           "DEFAULT_STEP", "DEFAULT_VIEW_SELECTION", "METHODS", "OVERLAY_ZOOM",
           "SKELETON_ESTIMATES", "TEST_CLIPS", "TRAIN_CLIPS", "VALIDATION_CLIPS",
           "VIEW_SELECTION",
           "HybridSequence", "TrainedLinearCombinations", "evaluate", "load",
           "locate_window", "multi_view", "observe", "pose2sim_cameras",
           "render_hybrid_sequences", "run_method", "aligned_skeleton_error",
           "select_tracked_views", "shown_skeletons", "skeleton_error", "skeleton_estimates",
           "subject_centre", "to_video_pixels", "track", "track_record", "track_views",
           "train", "video_report", "views_detections", "views_first_pose"]

CAMERA_SCALE = 1 / 3
"""The Pose2Sim cameras' images (1088 × 1920) are resampled by this factor."""

CROP_SIZE = (160, 240)
"""``(width, height)`` of the window cut around the subject from each scaled camera image."""

METHODS = ("linear-combination", "global-pca", "nearest-neighbour")
"""The tracker and its two baselines (``docs/linear-combination.md``)."""

_AD = "animateddrawings/"
_HISTORY = _AD + "history_c119d6b/"

TRAIN_CLIPS = (_AD + "fair1_wave_hello", _HISTORY + "8yr_old_wave_hello",
               _HISTORY + "cmu_new_walk_point", _HISTORY + "cmu_new_walk_raise_the_roof")
"""Training subjects' gestures the model is trained on (``jaxtrack.data.splits``: training)."""

VALIDATION_CLIPS = ("bandai/dataset-2_wave-right-hand_normal_001",)
"""The validation subject's wave on which eq. 9's P, Q and the step ω are chosen."""

TEST_CLIPS = (_HISTORY + "cmu_1006_wave_hello_1", _HISTORY + "cmu_1006_wave_hello_2")
"""The test subject's two waves: only ever scored."""

DEFAULT_FITNESS = FitnessSettings(contour_tolerance=64.0, hands_tolerance=16.0)
"""Eq. 9's settings every function here uses unless given others (the tracker's own default,
``jaxtrack.trackers.linear_combination.linear_combination_tracker``): O = R = 0.5 (the paper's),
P = 64 and Q = 16 px², chosen on the validation subject's wave (:data:`VALIDATION_CLIPS`) over
P ∈ {4, 16, 64} × Q ∈ {16, 64, 256} by the best particle's 3-D error
(``python -m papers.ong2002.evaluation --frames 60 --multi-view``, 2026-11-26, the same choice
on 2026-11-27)."""

DEFAULT_STEP = 0.03
"""ω, the step inside a cluster (and the global-PCA baseline's Brownian step), chosen in the
same run over {0.03, 0.1, 0.3} with :data:`DEFAULT_FITNESS`: 0.03 for both filters."""

VIEW_SELECTION = {
    "paper": {"fitness_weight": 1.0, "ambiguity_weight": 1.0, "window": 0},
    "fitness": {"fitness_weight": 1.0, "ambiguity_weight": 0.0, "window": 5},
    "ambiguity": {"fitness_weight": 0.0, "ambiguity_weight": 1.0, "window": 5},
}
"""View-selection rules (``jaxtrack.priors.linear_combinations.view_scores``' settings):
``"paper"``, Ong & Gong §5.7's fitness × 1/ambiguity per frame; ``"fitness"``, the fitness
alone averaged over ±5 frames; ``"ambiguity"``, the least ambiguity (eq. 14) averaged over ±5
frames."""

SKELETON_ESTIMATES = {"best": "skeleton", "mean": "mean_skeleton"}
"""The 3-D skeleton estimates a run reports (name → its key in a run's dict): the best-fitness
particle's (Ong & Gong's) and the particles' weighted mean."""

DEFAULT_SKELETON_ESTIMATE = "mean"
"""The 3-D skeleton ``jaxtrack track --method linear-combination`` reports and
:func:`multi_view` scores, chosen on validation together with :data:`DEFAULT_VIEW_SELECTION`
(``python -m papers.ong2002.view_selection``, 2026-11-27: the validation subject's three
Bandai-Namco gestures through the four Pose2Sim cameras, 90 frames each). With every rule the
weighted mean was 22–42 mm closer than the best particle (by the least ambiguity over ±5
frames 159 mm against 201; each view alone 175 against 206 mm on average). After a similarity
alignment the two are alike there (139 and 140 mm): the mean's gain is mostly the skeleton's
orientation, where it averages the hypotheses a silhouette leaves open."""

DEFAULT_VIEW_SELECTION = "ambiguity"
"""Chosen on validation with :data:`DEFAULT_SKELETON_ESTIMATE` (the same run): with the weighted
mean, the least ambiguity over ±5 frames selected views 159 mm off (oracle 149, worst 202), the
paper's rule over ±5 frames 160 mm, the fitness over ±5 frames 166 mm. These differ by less
than the clips do, so the rule matters less than the estimate. With the best particle the
fitness over ±5 frames was the best rule (193 mm; the default before the weighted mean was
scored)."""

_NECK = UPPER_BODY_12.index("neck")


def pose2sim_cameras(motion, *, scale: float = CAMERA_SCALE, crop: tuple[int, int] = CROP_SIZE
                     ) -> tuple[object, list[Camera]]:
    """The motion staged in the Pose2Sim lab and its four cameras, each scaled by ``scale`` and
    cropped to ``crop`` (width, height) centred on the subject's mean projected position.

    Returns:
        ``(staged motion, cameras)``.
    """
    from jaxtrack.body._staging import project_numpy, scale_camera
    from jaxtrack.body.markers import marker_positions
    from jaxtrack.data import path

    cameras = read_qca(path("pose2sim/Calib.qca.txt"), world_up="y")
    staged = stage_for_cameras(motion, cameras)
    joints = marker_positions(staged, UPPER_BODY_12)
    cropped = []
    for camera in cameras:
        camera = scale_camera(camera, scale)
        pixels, _ = project_numpy(camera, joints.reshape(-1, 3))
        centre = 0.5 * (pixels.min(axis=0) + pixels.max(axis=0))
        shift = np.array([crop[0] / 2, crop[1] / 2]) - centre
        cropped.append(Camera(camera.focal_length,
                              jnp.asarray(camera.principal_point) + jnp.asarray(shift),
                              camera.rotation, camera.translation, camera.distortion,
                              tuple(int(v) for v in crop), name=camera.name))
    return staged, cropped


@dataclass(frozen=True)
class HybridSequence:
    """One clip seen by one camera.

    Attributes:
        name: ``<clip>_<camera>``.
        clip: the clip's name.
        vectors: ``(time, vector)`` hybrid vectors from the exact silhouette (NaN rows where
            the frame had no silhouette or no three skin blobs).
        valid: ``(time,)`` rows of ``vectors`` that are usable.
        skeleton: ``(time, 12, 3)`` the true skeleton (camera frame, neck-relative, metres).
        observations: the frames as the tracker observes them (numpy leaves), or None.
        status: per frame, empty when observed, else why not.
        images: ``(time, height, width, 3)`` uint8 RGB rendered frames (``keep_images``), or
            None.
        background: ``(height, width, 3)`` uint8 RGB, the empty scene behind them, or None.
        rotation: ``(3, 3)`` the camera's world → camera rotation (a camera-frame skeleton
            ``s`` is ``s @ rotation`` in the world's axes), or None.
    """

    name: str
    clip: str
    vectors: np.ndarray
    valid: np.ndarray
    skeleton: np.ndarray
    observations: ContourObservation | None = None
    status: tuple[str, ...] = field(default_factory=tuple)
    images: np.ndarray | None = None
    background: np.ndarray | None = None
    rotation: np.ndarray | None = None


def _background_of(sequence, size) -> np.ndarray:
    """The exact empty scene behind a rendered sequence (the renderer's own background)."""
    from jaxtrack.body import _backgrounds

    name = sequence.settings["background"]
    rng = np.random.default_rng([int(sequence.seed), 1])  # the renderer's background stream
    return _backgrounds.make_background(name, size, rng)[0]


observe = observe_contours
"""Frames as the linear-combination tracker observes them (Ong & Gong §5.2):
:func:`jaxtrack.trackers.linear_combination.observe_contours`."""


def subject_centre(frames: np.ndarray, background: np.ndarray | None, *,
                   masks: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Where training would centre its :data:`CROP_SIZE` window on a video of a static camera
    (the middle of the upper body's extent over the clip), from silhouettes of up to 32 frames:
    horizontally the middle of the silhouettes' extent, vertically a third of the figure's height
    below its top (on rendered figures the crop's centre lies 0.29–0.36 of the way down; a figure
    whose feet are not segmented comes out short, and its crop too high).

    Args:
        frames: ``(time, height, width, 3)`` uint8 RGB.
        background: ``(height, width, 3)`` uint8 RGB, the empty scene (unused with ``masks``).
        masks: ``(time, height, width)`` bool person masks to use instead of background
            subtraction (:func:`observe`'s).

    Returns:
        ``(centre (x, y), frames with a person)``; the image's centre when no frame has one.
    """
    from jaxtrack.vision.foreground import foreground_mask, largest_component

    boxes = []
    for t in np.unique(np.linspace(0, len(frames) - 1, 32).round().astype(int)):
        person = (foreground_mask(frames[t], background) if masks is None
                  else np.asarray(masks[t], bool))
        rows, columns = np.nonzero(largest_component(person))
        if rows.size:
            boxes.append((columns.min(), rows.min(), columns.max(), rows.max()))
    if not boxes:
        return np.array([frames.shape[2], frames.shape[1]]) / 2, 0
    left, top, right, bottom = np.asarray(boxes, np.float64).T
    x = 0.5 * (np.percentile(left, 10) + np.percentile(right, 90))
    y = np.median(top) + 0.33 * np.percentile(bottom - top, 90)
    return np.array([x, y]), len(boxes)


def render_hybrid_sequences(clip: str, *, views: tuple[int, ...] = (0, 1, 2, 3),
                            num_contour: int = 100, fps: float = 30.0,
                            max_frames: int | None = None, background: str = "photo",
                            seed: int = 0, keep_observations: bool = False,
                            keep_images: bool = False) -> list[HybridSequence]:
    """Hybrid vectors of one real clip through the Pose2Sim cameras ``views`` (module
    docstring); with ``keep_observations`` also the frames as the tracker observes them, with
    ``keep_images`` the rendered frames and their empty scene."""
    from jaxtrack.body.camera import to_camera_frame
    from jaxtrack.data import resolve_clip
    from jaxtrack.vision.contours import silhouette_contour
    from jaxtrack.vision.skin import skin_blobs, skin_mask

    source = resolve_clip(clip)
    motion = source.load().resample(fps)
    if max_frames is not None:
        motion = motion.select(0, min(int(max_frames), motion.num_frames))
    staged, cameras = pose2sim_cameras(motion)
    sequences = []
    for view in views:
        if not 0 <= view < len(cameras):
            raise ValueError(f"views must be camera indices 0..{len(cameras) - 1}, got {view}")
        camera = cameras[view]
        rendered = render_motion(staged, camera, background=background, markers=UPPER_BODY_12,
                                 seed=seed + 101 * view, progress=False)
        reference = rendered.settings["appearance"]["skin"]
        joints = np.asarray(to_camera_frame(camera, rendered.joints_3d))
        skeleton = joints - joints[:, _NECK:_NECK + 1]
        layout = HybridLayout(num_contour=num_contour, num_skeleton=len(UPPER_BODY_12))
        vectors = np.full((motion.num_frames, layout.size), np.nan)
        for t in range(motion.num_frames):
            silhouette = rendered.silhouettes[t]
            if not silhouette.any():
                continue  # no contour (a figure cut by the crop's edge is kept, as in the
                # paper's upper-body views: the crop frames the upper body, arms may leave it)
            blobs = skin_blobs(skin_mask(rendered.images[t], silhouette, reference=reference))
            if not blobs.found:
                continue
            contour = silhouette_contour(silhouette, num_contour)
            vectors[t] = np.asarray(make_hybrid(contour, blobs.hands, blobs.head, skeleton[t]))
        observations, status, scene = None, (), None
        if keep_observations or keep_images:
            scene = _background_of(rendered, camera.image_size)
        if keep_observations:
            observations, status = observe(rendered.images, scene, skin_reference=reference)
            status = tuple(status)
        sequences.append(HybridSequence(
            name=f"{source.short_name}_{camera.name}", clip=source.short_name,
            vectors=vectors, valid=np.all(np.isfinite(vectors), axis=1), skeleton=skeleton,
            observations=observations, status=status,
            images=rendered.images if keep_images else None,
            background=scene if keep_images else None,
            rotation=np.asarray(camera.rotation, np.float64)))
    return sequences


@dataclass(frozen=True)
class TrainedLinearCombinations:
    """A trained model with its training vectors (the nearest-neighbour baseline's table).

    Attributes:
        model: the :class:`LinearCombinationModel`.
        vectors: ``(examples, vector)`` the training hybrid vectors, in the model's order.
        description: what it was trained on and how.
    """

    model: LinearCombinationModel
    vectors: np.ndarray
    description: dict


def _training_set(sequences: list[HybridSequence]) -> tuple[np.ndarray, np.ndarray]:
    vectors, ids = [], []
    for index, sequence in enumerate(sequences):
        # a frame without blobs breaks the sequence: the frames after it start a new one, so
        # no transition is counted across the gap
        runs = np.cumsum(~sequence.valid)
        vectors.append(sequence.vectors[sequence.valid])
        ids.append(index * 100_000 + runs[sequence.valid])
    if not vectors or sum(len(v) for v in vectors) < 2:
        raise ValueError("the training clips gave fewer than 2 usable frames (no skin blobs "
                         "found): nothing to train on")
    return np.concatenate(vectors), np.concatenate(ids)


def train(clips: list[str], *, views: tuple[int, ...] = (0, 1, 2, 3), num_contour: int = 100,
          num_clusters: int = 20, variance_fraction: float = 0.8, fps: float = 30.0,
          max_frames: int | None = None, background: str = "photo", seed: int = 0,
          output: str | os.PathLike | None = None) -> TrainedLinearCombinations:
    """Train the model on real clips rendered through the Pose2Sim cameras ``views``.

    Args:
        clips: catalogue names or paths of training clips (training subjects only).
        views: Pose2Sim camera indices to render each clip through.
        num_contour: N_C (Ong & Gong: 100).
        num_clusters: k-means clusters (Ong & Gong: 10–100).
        variance_fraction: global PCA variance kept (Ong & Gong: about 80 %).
        fps: frame rate the clips are resampled to (transitions are counted at it).
        max_frames: frames per clip (None: all).
        background: the renderer's background.
        seed: rendering and k-means seed.
        output: where to save the model (``.npz``); None: not saved.
    """
    if not clips:
        raise ValueError("clips is empty: give at least one training clip")
    sequences = [sequence for clip in clips for sequence in render_hybrid_sequences(
        clip, views=views, num_contour=num_contour, fps=fps, max_frames=max_frames,
        background=background, seed=seed)]
    vectors, ids = _training_set(sequences)
    layout = HybridLayout(num_contour=num_contour, num_skeleton=len(UPPER_BODY_12))
    fit = fit_linear_combinations(vectors, ids, layout, variance_fraction=variance_fraction,
                                  num_clusters=num_clusters, seed=seed)
    description = {"clips": list(clips), "views": list(views), "fps": fps,
                   "max_frames": max_frames, "background": background, "seed": seed,
                   "num_clusters": num_clusters, "variance_fraction": variance_fraction,
                   "explained_variance": fit.explained_variance,
                   "unseen_rows": list(fit.unseen_rows), "frames": int(len(vectors)),
                   "skeleton": list(UPPER_BODY_12)}
    if output is not None:
        save_linear_combinations(output, fit.model, description=description,
                                 arrays={"training_vectors": vectors})
    return TrainedLinearCombinations(fit.model, vectors, description)


def load(path: str | os.PathLike) -> TrainedLinearCombinations:
    """A model saved by :func:`train` (with its training vectors)."""
    saved = load_linear_combinations(path)
    if "training_vectors" not in saved.arrays:
        raise ValueError(f"{path}: the model file lacks its training vectors (save it with "
                         "jaxtrack.experiments.linear_combination.train)")
    return TrainedLinearCombinations(saved.model, saved.arrays["training_vectors"],
                                     saved.description)


def skeleton_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``(time,)`` mean distance (metres) between estimated and true skeleton vertices."""
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    if estimate.shape != truth.shape or estimate.shape[-1] != 3:
        raise ValueError(f"estimate {estimate.shape} and truth {truth.shape} must be equal "
                         "(time, joints, 3) skeletons")
    return np.linalg.norm(estimate - truth, axis=-1).mean(axis=-1)


def aligned_skeleton_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``(time,)`` :func:`skeleton_error` after the similarity transform (rotation, uniform
    scale, translation; Umeyama 1991) that best maps each frame's estimate onto its truth: the
    usual score of monocular 3-D pose, blind to the subject's size and the global rotation."""
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    if estimate.shape != truth.shape or estimate.shape[-1] != 3:
        raise ValueError(f"estimate {estimate.shape} and truth {truth.shape} must be equal "
                         "(time, joints, 3) skeletons")
    centred_estimate = estimate - estimate.mean(axis=1, keepdims=True)
    centred_truth = truth - truth.mean(axis=1, keepdims=True)
    covariance = np.einsum("tji,tjk->tik", centred_truth, centred_estimate)
    left, singular, right_t = np.linalg.svd(covariance)
    signs = np.ones_like(singular)
    signs[:, -1] = np.sign(np.linalg.det(left @ right_t))  # a rotation, not a reflection
    rotation = left @ (signs[:, :, None] * right_t)
    variance = np.sum(centred_estimate ** 2, axis=(1, 2))
    scale = np.where(variance > 0, np.sum(singular * signs, axis=1) / np.maximum(variance, 1e-300),
                     0.0)
    aligned = scale[:, None, None] * np.einsum("tik,tjk->tji", rotation, centred_estimate)
    return np.linalg.norm(aligned - centred_truth, axis=-1).mean(axis=-1)


def run_method(method: str, trained: TrainedLinearCombinations, observations: ContourObservation,
               *, particles: int = 300, iterations: int = 5, seed: int = 0,
               fitness: FitnessSettings = DEFAULT_FITNESS, step: float = DEFAULT_STEP,
               jump_spread: float = 0.3, brownian_step: float = DEFAULT_STEP) -> dict:
    """One method on one observed sequence: ``{"skeleton": (time, 12, 3), "found": (time,),
    "seconds_per_frame", "compile_seconds", "options"}``."""
    from jaxtrack.trackers.linear_combination import (
        linear_combination_tracker,
        nearest_neighbour,
        track_observations,
    )

    model = trained.model
    if method == "nearest-neighbour":
        import equinox as eqx

        vectors = jnp.asarray(trained.vectors, jnp.float32)
        # compiled ahead of time, so that the run time per frame excludes compilation
        tick = time.perf_counter()
        compiled = eqx.filter_jit(nearest_neighbour).lower(vectors, model.layout, observations,
                                                           fitness).compile()
        compile_seconds = time.perf_counter() - tick
        tick = time.perf_counter()
        picks = np.asarray(compiled(vectors, model.layout, observations, fitness))
        seconds = time.perf_counter() - tick
        skeleton = np.asarray(split_hybrid(trained.vectors[picks], model.layout).skeleton_3d)
        return {"skeleton": skeleton, "found": np.asarray(observations.found),
                "seconds_per_frame": seconds / len(picks), "compile_seconds": compile_seconds,
                "options": {"method": method}}
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    constrained = method == "linear-combination"
    tracker = linear_combination_tracker(
        model, engine=Engine(particles), fitness=fitness, iterations=iterations,
        step=step if constrained else brownian_step, jump_spread=jump_spread,
        constrained=constrained)
    result = track_observations(tracker, jr.PRNGKey(seed), observations)
    estimates = result.estimates
    return {"skeleton": np.asarray(estimates.best_skeleton_3d),
            "mean_skeleton": np.asarray(estimates.skeleton_3d),
            "found": np.asarray(estimates.found), "ess": np.asarray(estimates.ess),
            "seconds_per_frame": result.seconds_per_frame,
            "compile_seconds": result.compile_seconds, "options": result.options}


def evaluate(trained: TrainedLinearCombinations, clips: list[str], *,
             methods: tuple[str, ...] = METHODS, views: tuple[int, ...] = (0, 1, 2, 3),
             particles: int = 300, iterations: int = 5, max_frames: int | None = None,
             background: str = "photo", seed: int = 0,
             fitness: FitnessSettings = DEFAULT_FITNESS, step: float = DEFAULT_STEP,
             jump_spread: float = 0.3, output: str | os.PathLike | None = None,
             estimate: str = DEFAULT_SKELETON_ESTIMATE) -> dict:
    """3-D skeleton error of each method on held-out clips rendered through ``views``.

    Returns a JSON-able dict: per sequence and method the mean 3-D error (metres) of the
    skeleton ``estimate`` (:data:`SKELETON_ESTIMATES`; the nearest-neighbour baseline has one
    skeleton, its nearest vector's), ``aligned_error_m`` after a similarity alignment
    (:func:`aligned_skeleton_error`), the error per frame (``errors_m``), and both filters'
    two estimates apart (``best_error_m``, the best-fitness particle's, the paper's;
    ``mean_error_m``, the weighted mean's); frames observed, run time per frame and compile
    time apart; and per method the mean over sequences. Written to ``output`` (JSON,
    atomically) when given. The clips must not share a subject with the training clips
    (``jaxtrack.data.splits.check_disjoint``).
    """
    from jaxtrack._files import write_json_atomically
    from jaxtrack.data.splits import check_disjoint

    if estimate not in SKELETON_ESTIMATES:
        raise ValueError(f"estimate must be one of {tuple(SKELETON_ESTIMATES)}, got "
                         f"{estimate!r}")
    check_disjoint(trained.description.get("clips", []), clips)
    fps = float(trained.description.get("fps", 30.0))
    layout = trained.model.layout
    results = {"trained_on": trained.description, "methods": list(methods), "particles": particles,
               "iterations": iterations, "fitness": fitness.record(),
               "step": float(step), "jump_spread": float(jump_spread),
               "skeleton_estimate": estimate, "sequences": {}}
    for clip in clips:
        for sequence in render_hybrid_sequences(clip, views=views, num_contour=layout.num_contour,
                                                fps=fps, max_frames=max_frames,
                                                background=background, seed=seed + 7,
                                                keep_observations=True):
            entry = {"frames": int(len(sequence.skeleton)),
                     "observed": int(np.sum(sequence.observations.found))}
            for method in methods:
                run = run_method(method, trained, sequence.observations, particles=particles,
                                 iterations=iterations, seed=seed, fitness=fitness, step=step,
                                 jump_spread=jump_spread, brownian_step=step)
                skeleton = run.get(SKELETON_ESTIMATES[estimate], run["skeleton"])
                errors = skeleton_error(skeleton, sequence.skeleton)
                aligned = aligned_skeleton_error(skeleton, sequence.skeleton)
                entry[method] = {"error_m": float(errors.mean()),
                                 "errors_m": [round(float(e), 6) for e in errors],
                                 "aligned_error_m": float(aligned.mean()),
                                 "seconds_per_frame": float(run["seconds_per_frame"]),
                                 "compile_seconds": float(run["compile_seconds"])}
                if "mean_skeleton" in run:
                    for name, key in SKELETON_ESTIMATES.items():
                        entry[method][f"{name}_error_m"] = float(
                            skeleton_error(run[key], sequence.skeleton).mean())
            results["sequences"][sequence.name] = entry
    results["mean_error_m"] = {method: float(np.mean([entry[method]["error_m"] for entry in
                                                      results["sequences"].values()]))
                               for method in methods}
    if output is not None:
        write_json_atomically(Path(output), results)
    return results


def multi_view(trained: TrainedLinearCombinations, clip: str, *,
               views: tuple[int, ...] = (0, 1, 2, 3), particles: int = 300, iterations: int = 5,
               max_frames: int | None = None, background: str = "photo", seed: int = 0,
               fitness: FitnessSettings = DEFAULT_FITNESS, step: float = DEFAULT_STEP,
               jump_spread: float = 0.3, ambiguities: np.ndarray | None = None,
               sigma: float = 4.0, beta: float = 100.0, threshold: float = 0.05,
               selection: str = DEFAULT_VIEW_SELECTION,
               estimate: str = DEFAULT_SKELETON_ESTIMATE) -> dict:
    """View selection (Ong & Gong §5.5–5.7) on a clip seen by several Pose2Sim cameras.

    Each view is tracked on its own; per frame a view is selected by the rule ``selection``
    (:data:`VIEW_SELECTION`; the paper's: the view of greatest fitness × 1/ambiguity, eq. 14 on
    the training ambiguities, eq. 10–13), and its 3-D error is compared with the best and the
    worst view of that frame (the best is the oracle's choice).

    Args:
        ambiguities: the training vectors' ambiguities (None: computed with ``sigma``,
            ``beta``, ``threshold``; ``jaxtrack.priors.linear_combinations.training_ambiguity``).
        selection: a rule of :data:`VIEW_SELECTION` (default :data:`DEFAULT_VIEW_SELECTION`).
        estimate: the 3-D skeleton scored, ``"best"`` or ``"mean"`` (default
            :data:`DEFAULT_SKELETON_ESTIMATE`; :data:`SKELETON_ESTIMATES`).

    Returns:
        A JSON-able dict: mean 3-D error (metres) of the selected, best, worst and each single
        view, the share of frames where the selected view is the best, and per frame the
        chosen view and every view's error, ambiguity (−1: not observed), log fitness (−10³⁰
        where not finite) and whether it observed the frame; ``skeletons_world`` ``(time,
        views, 12, 3)``, each view's neck-relative 3-D skeleton turned from its camera's axes
        into the world's, and ``truth_world`` ``(time, 12, 3)``, the true one, so that the
        views' skeletons can be compared with each other (the 3-D errors are the same in
        either axes). All of these are of the skeleton ``estimate``; ``estimates`` holds
        ``errors_m`` and ``skeletons_world`` of each estimate of :data:`SKELETON_ESTIMATES`
        (the best particle's and the weighted mean's).
    """
    from jaxtrack.priors.linear_combinations import (
        nearest_ambiguity,
        select_views,
        training_ambiguity,
    )

    model = trained.model
    layout = model.layout
    if len(views) < 2:
        raise ValueError(f"view selection needs at least 2 views, got {views}")
    _check_selection(selection)
    if estimate not in SKELETON_ESTIMATES:
        raise ValueError(f"estimate must be one of {tuple(SKELETON_ESTIMATES)}, got "
                         f"{estimate!r}")
    if ambiguities is None:
        ambiguities = training_ambiguity(trained.vectors, layout, sigma=sigma, beta=beta,
                                         threshold=threshold)
    sequences = render_hybrid_sequences(clip, views=views, num_contour=layout.num_contour,
                                        fps=float(trained.description.get("fps", 30.0)),
                                        max_frames=max_frames, background=background,
                                        seed=seed + 7, keep_observations=True)
    log_fitness, ambiguity, found, spread = [], [], [], []
    by_estimate = {name: ([], []) for name in SKELETON_ESTIMATES}  # errors, world skeletons
    for sequence in sequences:
        run = _track_run(trained, sequence.observations, particles=particles,
                         iterations=iterations, seed=seed, fitness=fitness, step=step,
                         jump_spread=jump_spread)
        for name, (estimate_errors, world) in by_estimate.items():
            skeleton = run[SKELETON_ESTIMATES[name]]
            estimate_errors.append(skeleton_error(skeleton, sequence.skeleton))
            world.append(np.asarray(skeleton, np.float64) @ sequence.rotation)
        log_fitness.append(run["log_fitness"])
        spread.append(run["skeleton_spread"])
        vectors = np.asarray(make_hybrid(run["contour"], run["head_hands"][:, 1:],
                                         run["head_hands"][:, 0], run["skeleton"]))
        seen = run["found"] & np.all(np.isfinite(vectors), axis=1)
        view_ambiguity = np.full(len(vectors), np.inf)
        if seen.any():
            view_ambiguity[seen] = nearest_ambiguity(vectors[seen], trained.vectors,
                                                     ambiguities, layout)
        ambiguity.append(view_ambiguity)
        found.append(seen)
    truth_world = sequences[0].skeleton @ sequences[0].rotation  # the same from every view
    errors = np.stack(by_estimate[estimate][0], 1)  # (frames, views) of the reported estimate
    estimates = {name: {"errors_m": np.stack(each, 1).tolist(),
                        "skeletons_world": np.round(np.stack(world, 1), 5).tolist()}
                 for name, (each, world) in by_estimate.items()}
    log_fitness = np.stack(log_fitness, 1)
    ambiguity, found = np.stack(ambiguity, 1), np.stack(found, 1)
    chosen = select_views(log_fitness, np.where(np.isfinite(ambiguity), ambiguity, 0.0), found,
                          **VIEW_SELECTION[selection])
    frames = np.arange(len(errors))
    selected = errors[frames, chosen]
    return {"clip": clip, "views": [sequence.name for sequence in sequences],
            "selection": selection, "estimate": estimate, "selected_m": float(selected.mean()),
            "best_m": float(errors.min(axis=1).mean()),
            "worst_m": float(errors.max(axis=1).mean()),
            "single_view_m": [float(e) for e in errors.mean(axis=0)],
            "selected_is_best": float(np.mean(chosen == errors.argmin(axis=1))),
            "chosen": chosen.tolist(), "errors_m": errors.tolist(),
            "ambiguity": np.where(np.isfinite(ambiguity), ambiguity, -1.0).tolist(),
            "log_fitness": np.where(np.isfinite(log_fitness), log_fitness, -1e30).tolist(),
            "found": found.tolist(),
            "skeleton_spread_m": np.round(np.stack(spread, 1).astype(np.float64), 6).tolist(),
            "skeletons_world": estimates[estimate]["skeletons_world"],
            "truth_world": np.round(truth_world, 5).tolist(), "estimates": estimates}


def _check_selection(selection: str) -> None:
    if selection not in VIEW_SELECTION:
        raise ValueError(f"selection must be one of {tuple(VIEW_SELECTION)}, got {selection!r}")


def select_tracked_views(trained: TrainedLinearCombinations, estimates: list,
                         selection: str = DEFAULT_VIEW_SELECTION
                         ) -> tuple[list[int | None], np.ndarray | None]:
    """Ong & Gong §5.5–5.7 on views tracked one by one: every view's ambiguity (eq. 14 on the
    training vectors' ambiguities, eq. 10–13) and per frame the view the rule ``selection``
    picks (:data:`VIEW_SELECTION`: ``"paper"``, the greatest fitness × 1/ambiguity;
    ``"fitness"``, the greatest fitness over ±5 frames; ``"ambiguity"``, the default chosen on
    validation, the least ambiguity over ±5 frames).

    Args:
        trained: the model and its training vectors.
        estimates: per view the tracker's estimates (``track_observations(...).estimates``),
            all of one length.
        selection: a rule of :data:`VIEW_SELECTION`.

    Returns:
        ``(chosen, ambiguity)``: per frame the chosen view, None where no view observed the
        frame; and the ``(time, views)`` ambiguities, NaN where a view did not observe the frame
        (None for one view, which is always chosen where it observed).
    """
    from jaxtrack.priors.linear_combinations import (
        nearest_ambiguity,
        select_views,
        training_ambiguity,
    )

    _check_selection(selection)
    if len(estimates) == 1:
        return [0 if found else None for found in np.asarray(estimates[0].found)], None
    layout = trained.model.layout
    ambiguities = training_ambiguity(trained.vectors, layout)
    count = len(estimates[0].found)
    ambiguity = np.full((count, len(estimates)), np.nan)
    seen = np.zeros((count, len(estimates)), bool)
    for index, estimate in enumerate(estimates):
        markers = np.asarray(estimate.best_markers)
        vectors = np.asarray(make_hybrid(estimate.contour, markers[:, 1:], markers[:, 0],
                                         estimate.best_skeleton_3d))
        seen[:, index] = np.asarray(estimate.found) & np.all(np.isfinite(vectors), axis=1)
        if seen[:, index].any():
            ambiguity[seen[:, index], index] = nearest_ambiguity(
                vectors[seen[:, index]], trained.vectors, ambiguities, layout)
    log_fitness = np.stack([np.asarray(e.log_fitness, np.float64) for e in estimates], axis=1)
    chosen = select_views(log_fitness, np.where(seen, ambiguity, 0.0), seen,
                          **VIEW_SELECTION[selection])
    return [int(view) if seen[t].any() else None for t, view in enumerate(chosen)], ambiguity


def _track_run(trained, observations, *, particles, iterations, seed, fitness, step,
               jump_spread) -> dict:
    from jaxtrack.trackers.linear_combination import linear_combination_tracker, track_observations

    tracker = linear_combination_tracker(trained.model, engine=Engine(particles),
                                         fitness=fitness, iterations=iterations, step=step,
                                         jump_spread=jump_spread)
    result = track_observations(tracker, jr.PRNGKey(seed), observations)
    estimates = result.estimates
    return {"skeleton": np.asarray(estimates.best_skeleton_3d),
            "mean_skeleton": np.asarray(estimates.skeleton_3d),
            "head_hands": np.asarray(estimates.best_markers),
            "contour": np.asarray(estimates.contour), "found": np.asarray(estimates.found),
            "log_fitness": np.asarray(estimates.log_fitness),
            "skeleton_spread": np.asarray(estimates.skeleton_spread),
            "seconds_per_frame": result.seconds_per_frame,
            "compile_seconds": result.compile_seconds, "options": result.options}


def track(trained: TrainedLinearCombinations, images: np.ndarray, background: np.ndarray, *,
          skin_reference=None, particles: int = 300, iterations: int = 5, seed: int = 0,
          fitness: FitnessSettings = DEFAULT_FITNESS, step: float = DEFAULT_STEP,
          jump_spread: float = 0.3) -> dict:
    """Track one view of a video: ``images`` ``(time, height, width, 3)`` uint8 RGB of a static
    camera whose empty scene is ``background``. Returns per frame the best particle's
    ``skeleton`` ``(time, 12, 3)`` and the weighted mean's (``mean_skeleton``), the image
    estimates (``head_hands`` ``(time, 3, 2)``, ``contour``), ``log_fitness``, ``found`` and
    ``status`` (why a frame was not observed), and the timings and options."""
    observations, status = observe(images, background, skin_reference=skin_reference)
    run = _track_run(trained, observations, particles=particles, iterations=iterations,
                     seed=seed, fitness=fitness, step=step, jump_spread=jump_spread)
    return run | {"status": status}


# ``jaxtrack track --method linear-combination``'s record and overlay, on the video pipeline


def locate_window(frames: np.ndarray, background: np.ndarray | None,
                  masks: np.ndarray | None) -> tuple[np.ndarray, int]:
    """Where a calibrated camera's frames are cut to :data:`CROP_SIZE` (the pipeline's
    ``Window(CROP_SIZE, locate=locate_window)``): the window's origin ``(x0, y0)`` around the
    subject (:func:`subject_centre` of frames spread over the video against its median
    ``background``, or of their ``masks``), and the frames it was found from."""
    centre, people = subject_centre(frames, background, masks=masks)
    return np.round(centre - np.asarray(CROP_SIZE) / 2), people


def to_video_pixels(points: np.ndarray, run) -> np.ndarray:
    """Tracking pixels (inside the crop) of a view (a pipeline ``ViewRun``) -> the video's own
    pixels (pixel centres at integers, as ``scale_camera``)."""
    return (points + run.origin + 0.5) / run.factors - 0.5


def _rounded(values, digits: int):
    values = np.asarray(values, np.float64)
    if not np.all(np.isfinite(values)):
        return None
    return np.round(values, digits).tolist()


def _not_observed(run) -> np.ndarray:
    """``(time,)`` the view's frames its observation gives a reason for (not observed)."""
    return np.array([bool(text) for text in run.reasons])


def _view_statuses(run) -> list:
    """Each frame's :class:`jaxtrack.trackers.status.FrameStatus` in one view: its head and hands
    in the video's own pixels against the video's size, ``no person`` where the observation
    gives a reason it was not observed, its best particle's log-fitness."""
    from jaxtrack.trackers.status import frame_statuses

    estimate = run.result.estimates
    points = to_video_pixels(np.asarray(estimate.best_markers, np.float64), run)
    return frame_statuses(points, tuple(run.size),
                          degenerate=~(np.asarray(estimate.ess) > 0),
                          no_person=_not_observed(run),
                          log_likelihood=np.asarray(estimate.log_fitness, np.float64))


def skeleton_estimates(estimates, skeleton_estimate: str) -> np.ndarray:
    """``(time, joints, 3)`` a view's 3-D skeleton of the estimate ``skeleton_estimate``
    names (:data:`SKELETON_ESTIMATES`: ``"mean"``, the weighted mean's; ``"best"``, the best
    particle's)."""
    if skeleton_estimate not in SKELETON_ESTIMATES:
        raise ValueError(f"skeleton_estimate must be one of {tuple(SKELETON_ESTIMATES)}, got "
                         f"{skeleton_estimate!r}")
    return np.asarray(estimates.skeleton_3d if skeleton_estimate == "mean"
                      else estimates.best_skeleton_3d, np.float64)


def track_record(trained, cameras, runs, skeletons, chosen, ambiguity, tracker, *,
                 model: str, calibration: str | None, masks: list | None, skin, seed: int,
                 view_selection: str, skeleton_estimate: str) -> dict:
    """``track.json`` of a linear-combination run (``jaxtrack track --method
    linear-combination``): per frame the selected view and its status, and per view the head
    and hands in the video's own pixels and the 3-D skeleton.

    Args:
        trained: the model (:class:`TrainedLinearCombinations`).
        cameras: the calibrated cameras, one per view, or None.
        runs: per view the pipeline's ``ViewRun`` (:class:`jaxtrack.experiments.pipeline.ViewRun`:
            its ``TrackResult``, frames, window origin, scale, size, reasons).
        skeletons: per view ``(time, joints, 3)`` the skeleton reported.
        chosen, ambiguity: :func:`select_tracked_views`' selected view per frame and
            ``(time, views)`` ambiguities (None with one view).
        tracker: the linear-combination tracker.
        model, calibration, masks, skin, seed: what the command was given, for the record.
        view_selection, skeleton_estimate: the rules used.
    """
    from jaxtrack.trackers.status import (
        LOST_RULE,
        FrameStatus,
        status_counts,
        status_legend,
    )

    joints = list(trained.description["skeleton"])
    view_statuses = [_view_statuses(run) for run in runs]
    frame_statuses = [FrameStatus.NO_PERSON if chosen[t] is None
                      else view_statuses[chosen[t]][t] for t in range(len(chosen))]
    first = runs[0]
    frames = []
    for t in range(len(chosen)):
        entries = []
        for index, run in enumerate(runs):
            estimate = run.result.estimates
            found = bool(estimate.found[t])
            markers = np.asarray(estimate.best_markers[t], np.float64)
            video_markers = to_video_pixels(markers, run) if found else None
            skeleton = np.asarray(skeletons[index][t], np.float64)
            entry = {
                "status": run.reasons[t] or "observed", "observed": found,
                "frame_status": view_statuses[index][t].value,
                "log_fitness": round(float(estimate.log_fitness[t]), 4),
                "ambiguity": None if ambiguity is None else _rounded(ambiguity[t, index], 5),
                "cluster": int(estimate.cluster[t]), "ess": round(float(estimate.ess[t]), 2),
                "head": None if video_markers is None else _rounded(video_markers[0], 2),
                "hands": None if video_markers is None else _rounded(video_markers[1:], 2),
                "skeleton_m": dict(zip(joints, np.round(skeleton, 4).tolist(), strict=True))}
            if cameras is not None:  # neck-relative in the calibration's world axes (Y up)
                world = skeleton @ np.asarray(cameras[index].rotation, np.float64)
                entry["skeleton_world_m"] = dict(zip(joints, np.round(world, 4).tolist(),
                                                     strict=True))
            entries.append(entry)
        frame = int(first.frame_indices[t])
        frames.append({"frame": frame, "time_s": (round(frame / first.fps, 4)
                                                  if math.isfinite(first.fps) else None),
                       "status": frame_statuses[t].value,
                       "views": entries, "selected_view": chosen[t],
                       "selected": None if chosen[t] is None else runs[chosen[t]].name})
    return {
        "method": "linear-combination", "model": model,
        "statuses": status_legend(), "lost_rule": LOST_RULE,
        "status_of_a_frame": "the selected view's (each view's is its frame_status)",
        "status_counts": status_counts(frame_statuses),
        "trained_on": {key: trained.description.get(key) for key in
                       ("clips", "views", "fps", "num_clusters", "frames")},
        "calibration": calibration,
        "views": [{"video": str(run.video), "camera": run.name,
                   "size": list(run.size), "fps": _rounded(run.fps, 3),
                   "stride": run.stride,
                   "scale": np.round(run.factors, 5).tolist(),
                   "crop_origin": np.round(run.origin, 1).tolist(),
                   "crop_from_silhouettes": (len(run.frame_indices) if run.located_from is None
                                             else run.located_from),
                   "silhouettes": ("background subtraction against the median of the "
                                   "video's frames" if masks is None
                                   else f"masks {masks[index]}")}
                  for index, run in enumerate(runs)],
        "tracked_size": list(first.tracked_size),
        "skin": "fixed chroma box" if skin is None else list(skin),
        "particles": tracker.num_particles, "iterations": tracker.iterations,
        "view_selection": view_selection if len(runs) > 1 else None,
        "skeleton_estimate": skeleton_estimate,
        "seed": seed, "tracker": first.result.options, "joints": joints,
        "coordinates": "head and hands in the video's own pixels (hands ordered left to right "
                       "in the image); skeleton_m (the skeleton_estimate) in the camera's "
                       "frame, metres, relative to the neck",
        "frames": frames}


def shown_skeletons(skeletons: list[np.ndarray], chosen: list[int | None],
                    cameras) -> np.ndarray:
    """``(time, joints, 3)`` the 3-D skeleton the overlay draws each frame: the selected view's
    (the only view's) of each view's ``skeletons`` ``(time, joints, 3)``, x right, y up,
    metres from the neck; in the calibration's world axes when there is one (the same axes
    whichever view is selected), else the camera's axes with y and z turned to point up and
    toward the viewer. NaN in a frame no view observed."""
    count = len(chosen)
    joints = np.asarray(skeletons[0]).shape[1]
    shown = np.full((count, joints, 3), np.nan)
    for t, index in enumerate(chosen):
        if index is None:
            continue
        skeleton = np.asarray(skeletons[index][t], np.float64)
        if cameras is not None:
            shown[t] = skeleton @ np.asarray(cameras[index].rotation, np.float64)
        else:
            shown[t] = skeleton * np.array([1.0, -1.0, -1.0])
    return shown


def _frame_labels(reasons: list[str]) -> list[str]:
    """Per frame ``"3/40 no skin blobs"``: the frame's number and why it was not observed
    (the first words of its reason)."""
    return [f"{t + 1}/{len(reasons)} {text.split(':')[0].split('(')[0].strip()}".strip()
            for t, text in enumerate(reasons)]


OVERLAY_ZOOM = 2
"""The overlay's panels are drawn at this many times the tracking resolution."""


def video_report(trained: TrainedLinearCombinations, cameras, tracker, *, model: str,
                 calibration: str | None, masks: list | None, skin, seed: int,
                 view_selection: str = DEFAULT_VIEW_SELECTION,
                 skeleton_estimate: str = DEFAULT_SKELETON_ESTIMATE):
    """The video pipeline's ``report`` hook for ``jaxtrack track --method linear-combination``
    (:func:`jaxtrack.experiments.pipeline.track_video`): from the views tracked one by one, Ong
    & Gong's view selection (§5.5–5.7, :func:`select_tracked_views`), the record
    (:func:`track_record`, with its ``seconds``) and the overlay's writer: the views side by
    side with their contours, head and hands, ambiguity bars and the selected view framed, and
    the selected view's 3-D skeleton (Fig. 17;
    :func:`jaxtrack.vision.overlay_views.write_views_stream`).

    Args: as :func:`track_record` (``runs``, ``skeletons``, ``chosen`` and ``ambiguity`` come
    from the pipeline's views).

    Returns:
        ``report(runs, timings) -> (record, draw)``.
    """
    _check_selection(view_selection)
    if skeleton_estimate not in SKELETON_ESTIMATES:
        raise ValueError(f"skeleton_estimate must be one of {tuple(SKELETON_ESTIMATES)}, got "
                         f"{skeleton_estimate!r}")

    def report(runs, timings: dict):
        from jaxtrack.vision.overlay_views import write_views_stream

        estimates = [run.result.estimates for run in runs]
        tick = time.perf_counter()
        chosen, ambiguity = select_tracked_views(trained, estimates, selection=view_selection)
        selection_seconds = time.perf_counter() - tick
        skeletons = [skeleton_estimates(estimate, skeleton_estimate) for estimate in estimates]
        for run, skeleton, estimate in zip(runs, skeletons, estimates, strict=True):
            if not (np.all(np.isfinite(skeleton))
                    and np.all(np.isfinite(np.asarray(estimate.log_fitness)))):
                raise ValueError(f"tracking {run.video} produced non-finite skeletons; nothing "
                                 f"written")
        record = track_record(trained, cameras, runs, skeletons, chosen, ambiguity, tracker,
                              model=model, calibration=calibration, masks=masks, skin=skin,
                              seed=seed, view_selection=view_selection,
                              skeleton_estimate=skeleton_estimate)
        # decoding counts the pass that finds the background and window; total: up to the
        # overlay (the tracking pass holds observing and tracking)
        record["seconds"] = {
            "decode": round(timings["background_seconds"]
                            + timings["decode_and_prepare_seconds"], 3),
            "observe": round(timings["observe_seconds"], 3),
            "view_selection": round(selection_seconds, 3),
            "per_view": [{"compile": round(run.result.compile_seconds, 3),
                          "ms_per_frame": round(1e3 * run.result.seconds_per_frame, 3)}
                         for run in runs],
            "total": round(timings["background_seconds"] + timings["tracking_pass_seconds"]
                           + selection_seconds, 3)}

        def draw(frames, path, fps: float):
            return write_views_stream(
                frames, [estimate.contour for estimate in estimates],
                [estimate.best_markers for estimate in estimates], path, fps=fps,
                names=[run.name for run in runs], marker_names=("head", "hand", "other_hand"),
                labels=[_frame_labels(run.reasons) for run in runs], ambiguity=ambiguity,
                selected=None if ambiguity is None else chosen, zoom=OVERLAY_ZOOM,
                skeletons=shown_skeletons(skeletons, chosen, cameras),
                skeleton_names=list(trained.description["skeleton"]))

        return record, draw

    return report


def views_detections(keypoints, image_sizes, *, dtype=jnp.float32):
    """Every view's detections of one person as the tracker over calibrated views reads them.

    Args:
        keypoints: one ``(points (time, 12, 2), confidence (time, 12))`` per view, in the
            calibration's pixels and ``UPPER_BODY_12``'s order (NaN or confidence 0 where not
            found), each view's rows the same frames.
        image_sizes: one ``(width, height)`` per view.

    Returns:
        A :class:`jaxtrack.likelihoods.detections.DetectionsFrame` with leaves ``(time, views,
        1, 12, 2)``, ``(time, views, 1, 12)``, ``(time, views)``, ``(time, views, 2)``; a view
        with no keypoint found in a frame holds no one there.
    """
    from jaxtrack.likelihoods.detections import DetectionsFrame

    if len(keypoints) != len(image_sizes) or not keypoints:
        raise ValueError(f"give one (points, confidence) and one image size per view, got "
                         f"{len(keypoints)} and {len(image_sizes)}")
    frames = {len(points) for points, _ in keypoints}
    if len(frames) != 1:
        raise ValueError(f"every view's keypoints must hold the same frames, got "
                         f"{sorted(frames)} rows")
    all_points, all_confidence, people = [], [], []
    for (points, confidence), size in zip(keypoints, image_sizes, strict=True):
        points = np.asarray(points, np.float64)
        confidence = np.asarray(confidence, np.float64)
        if points.shape[1:] != (len(UPPER_BODY_12), 2) or confidence.shape != points.shape[:2]:
            raise ValueError(f"a view's keypoints must be (time, {len(UPPER_BODY_12)}, 2) with "
                             f"(time, {len(UPPER_BODY_12)}) confidences, got {points.shape} and "
                             f"{confidence.shape}")
        inside = np.all(np.isfinite(points) & (points >= -0.5)
                        & (points <= np.asarray(size, np.float64) - 0.5), -1)
        confidence = np.where(inside, np.clip(np.nan_to_num(confidence), 0.0, 1.0), 0.0)
        all_points.append(np.where(confidence[..., None] > 0, points, 0.0))
        all_confidence.append(confidence)
        people.append((confidence > 0).any(-1))
    count = frames.pop()
    sizes = np.broadcast_to(np.asarray(image_sizes, np.float64), (count, len(keypoints), 2))
    return DetectionsFrame(jnp.asarray(np.stack(all_points, 1)[:, :, None], dtype),
                           jnp.asarray(np.stack(all_confidence, 1)[:, :, None], dtype),
                           jnp.asarray(np.stack(people, 1), jnp.int32), jnp.asarray(sizes, dtype))


def views_first_pose(keypoints, cameras, frame: int = 0) -> np.ndarray:
    """``(12, 3)`` the skeleton triangulated (weighted DLT) from the views' keypoints of row
    ``frame``, NaN where a joint is seen in fewer than two views: where the tracker over
    calibrated views places its first particles.

    A detector that swapped a person's left and right in one view pulls every lateral joint
    off, so each view's labels are taken as given or exchanged, whichever set of exchanges
    (fewest first; never all views, which only mirrors the skeleton) reprojects with the least
    confidence-weighted error.
    """
    from itertools import product

    from jaxtrack.body.camera import project
    from jaxtrack.likelihoods.detections import swap_order
    from jaxtrack.vision.triangulation import triangulate

    cameras = list(cameras)
    points = np.stack([np.asarray(points, np.float64)[frame] for points, _ in keypoints])
    confidence = np.stack([np.nan_to_num(np.asarray(conf, np.float64)[frame])
                           for _, conf in keypoints])
    points = np.where((confidence > 0)[..., None], points, np.nan)
    mirror = list(swap_order(UPPER_BODY_12))
    best, best_cost = None, np.inf
    flips = sorted(product((False, True), repeat=len(cameras)), key=sum)
    for flip in flips:
        if 0 < len(cameras) == sum(flip) or (best is not None and sum(flip) > len(cameras) / 2):
            continue
        labelled = np.stack([view[mirror] if exchange else view
                             for view, exchange in zip(points, flip, strict=True)])
        weights = np.stack([view[mirror] if exchange else view
                            for view, exchange in zip(confidence, flip, strict=True)])
        world, _ = triangulate(labelled, cameras, confidence=weights)
        seen = np.all(np.isfinite(world), -1)
        if not seen.any():
            continue
        cost = 0.0
        for view, camera in enumerate(cameras):
            pixels = np.asarray(project(camera, np.where(seen[:, None], world, 0.0)))
            error = np.linalg.norm(pixels - labelled[view], axis=-1)
            cost += np.nansum(np.where(seen, weights[view] * error, 0.0))
        if cost < best_cost - 1e-9:
            best, best_cost = world, cost
    if best is None:
        best, _ = triangulate(points, cameras, confidence=confidence)
    return best


def track_views(model: LinearCombinationModel, cameras, keypoints, *, particles: int = 300,
                iterations: int = 5, seed: int = 0, constrained: bool = True, up=(0.0, 0.0, 1.0),
                detection=None, progress: bool = False, **walks) -> dict:
    """The linear-combination tracker over calibrated views on their detections
    (:func:`jaxtrack.trackers.linear_combination_views.linear_combination_views_tracker`).

    Args:
        model: the trained model.
        cameras: one :class:`Camera` per view (their image sizes bound the detections).
        keypoints: one ``(points (time, 12, 2), confidence (time, 12))`` per view
            (:func:`views_detections`).
        detection: the detection density (default the hand-set one).
        walks: ``step``, ``jump_spread``, ``translation_step``, ``yaw_step``, ``scale_step``.

    Returns:
        ``{"skeleton", "best_skeleton"}`` ``(time, 12, 3)`` world points, ``"markers"``
        ``(time, views, 12, 2)``, ``"ess"``, ``"scale"``, ``"spread"`` ``(time,)``,
        ``"log_evidence"`` (the sum of the frames' increments after frame 0),
        ``"seconds_per_frame"``, ``"compile_seconds"``, ``"options"``.
    """
    from jaxtrack.trackers import _runner
    from jaxtrack.trackers.linear_combination_views import linear_combination_views_tracker

    cameras = list(cameras)
    observations = views_detections(keypoints, [camera.image_size for camera in cameras])
    tracker = linear_combination_views_tracker(
        model, cameras, detection=detection, engine=Engine(particles), iterations=iterations,
        constrained=constrained, up=up, **walks)
    result = _runner.track(tracker, jr.PRNGKey(seed), observations,
                           views_first_pose(keypoints, cameras), progress=progress,
                           description="linear-combination")
    estimates = result.estimates
    return {"skeleton": np.asarray(estimates.skeleton_3d, np.float64),
            "best_skeleton": np.asarray(estimates.best_skeleton_3d, np.float64),
            "markers": np.asarray(estimates.markers, np.float64),
            "ess": np.asarray(estimates.ess, np.float64),
            "scale": np.asarray(estimates.scale, np.float64),
            "spread": np.asarray(estimates.skeleton_spread, np.float64),
            "log_evidence": float(np.sum(np.asarray(estimates.log_likelihood, np.float64)[1:])),
            "seconds_per_frame": result.seconds_per_frame,
            "compile_seconds": result.compile_seconds, "options": result.options}
