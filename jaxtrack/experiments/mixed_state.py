"""Kwatra et al.'s mixed-state tracker end to end: render real posture clips, train the posture
model, track, and score instantaneous (extended Ghost), filtered and smoothed estimates.

- :func:`render_posture_sequence` renders one clip from one viewpoint over a known empty scene,
  takes the silhouettes by background subtraction, and keeps the true head, wrists and ankles
  and the posture labels of :func:`jaxtrack.priors.postures.posture_labels`.
- :func:`train` renders the training clips from several viewpoints and fits the
  :class:`~jaxtrack.priors.postures.PostureModel` (saved with :func:`save_posture_model`).
- :func:`track` runs filter and smoother on one rendered sequence or on silhouettes;
  :func:`evaluate` scores the test clips (:func:`score`: the paper's Table 1 — mean squared
  error per part, hands and feet under the best left/right assignment per frame; fraction of
  frames within ε pixels; posture error rate).

The clip split is by person (:mod:`jaxtrack.data.splits`): :data:`TRAINING_CLIPS` are
training subjects', :data:`VALIDATION_CLIPS` validation subjects' (CMU 77 and 02, HDM05 actor
mm) and :data:`TEST_CLIPS` test subjects' (CMU 139 and 131, HDM05 actor tr): no person is on two
sides.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import jax
import jax.random as jr
import numpy as np

from jaxtrack.priors.postures import (
    NUM_POSTURES,
    POSTURE_NAMES,
    PostureModel,
    fit_posture_model,
    posture_labels,
)
from jaxtrack.trackers.mixed_state import (
    MixedStateFrame,
    MixedStateModel,
    filter_sequence,
    instantaneous_estimates,
    observations_from_silhouettes,
    smooth,
    smooth_backward,
    smooth_fixed_lag,
)

__all__ = ["DEFAULT_COMPONENTS", "DEFAULT_COVARIANCE", "DEFAULT_REGULARISATION", "EPSILONS",
           "POSE2SIM_SCALE", "TEST_CLIPS", "TRAINING_CLIPS", "TRAINING_POSE2SIM_CAMERAS",
           "VALIDATION_CLIPS", "VIEW_AZIMUTHS", "PostureSequence", "evaluate", "fit",
           "model_with_options",
           "labelled_features", "render_posture_sequence", "render_sequences", "score", "track",
           "train", "training_features"]

TRAINING_CLIPS = ("cmu_posture_bvh/75_19", "cmu_posture_bvh/64_26",
                  "deepmimic_getup_bvh/getup_facedown", "deepmimic_getup_bvh/crawl",
                  "cmu_amc/07_01")
"""Sitting at two heights (subject 75), stooping (64), getting up and crawling (DeepMimic),
walking (07)."""
VALIDATION_CLIPS = ("cmu_posture_bvh/77_07", "cmu_amc/02_01",
                    "hdm05_cut/lieDownFloor/HDM_mm_lieDownFloor_015_120",
                    "hdm05_cut/squat1Reps/HDM_mm_squat1Reps_037_120",
                    "hdm05_cut/depositFloorR/HDM_mm_depositFloorR_019_120")
"""Where the posture model's and the tracker's settings are chosen
(``python -m papers.kwatra2002.mixed_state_evaluation``), all of validation subjects of
:mod:`jaxtrack.data.splits`: a half-crouch (CMU 77), a walk (CMU 02), and HDM05 actor mm's
first lie-down, squat and crouch (put an object on the floor). Until 2026-11-29 they were 77_07,
02_01 and held-out clips of two training subjects (CMU 75's 75_17, DeepMimic's roll), since no
validation subject then sat or lay down; the settings of 2026-11-27 were chosen on those."""
TEST_CLIPS = ("cmu_posture_bvh/139_16", "cmu_bvh/131_01",
              "hdm05_cut/lieDownFloor/HDM_tr_lieDownFloor_019_120",
              "hdm05_cut/squat1Reps/HDM_tr_squat1Reps_041_120",
              "hdm05_cut/depositFloorR/HDM_tr_depositFloorR_027_120")
"""All of test subjects: lying → all fours → kneel → stand (CMU 139), a stylised walk (CMU 131),
and HDM05 actor tr's first lie-down, squat and crouch. Until 2026-11-29 a low sit of CMU 75
(75_20), a training subject, held out by clip, was here too."""
VIEW_AZIMUTHS = (np.pi / 2, -np.pi / 2, np.pi / 4, -np.pi / 4, 0.0)
"""Camera azimuths (radians from the subject's mean facing direction): both profiles (lying
facing left and right), two obliques, frontal."""
PART_TRUTH_MARKERS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")
EPSILONS = (10.0, 20.0, 30.0, 50.0)
TRAINING_POSE2SIM_CAMERAS: tuple[int, ...] = ()
"""Real Pose2Sim cameras (:func:`render_posture_sequence`'s ``pose2sim_camera``) the training
clips are also seen through, beside :data:`VIEW_AZIMUTHS`; none by default. The posture model
(these views, :data:`DEFAULT_COVARIANCE`, :data:`DEFAULT_COMPONENTS`,
:data:`DEFAULT_REGULARISATION`) is chosen on the validation clips by what the tracker does
with it, the smoothed estimate's mean squared error over all parts (``python -m
benchmarks.mixed_state_evaluation``, 2026-11-27): the paper's one Gaussian per posture with
its own covariance, ridge 0.2, level views, 5 482 px², against 5 670 px² for the model the
classifier alone prefers (all four cameras too, two Gaussians per posture sharing one
covariance, ridge 1: ``python -m benchmarks.posture_classifier``, 17.5 % instantaneous
posture error against 26.6 % over the validation groups pooled). See
``docs/mixed-state.md``."""
DEFAULT_COVARIANCE = "per-posture"
"""Each posture's own covariance, Ghost's (:data:`jaxtrack.priors.postures.COVARIANCES`);
chosen with :data:`TRAINING_POSE2SIM_CAMERAS`."""
DEFAULT_COMPONENTS = 1
"""Gaussians per posture (:func:`jaxtrack.priors.postures.fit_posture_model`; 1 is the
paper's); chosen with :data:`TRAINING_POSE2SIM_CAMERAS`."""
DEFAULT_REGULARISATION = 0.2
"""The posture model's covariance ridge λ (:func:`jaxtrack.priors.postures.fit_posture_model`),
chosen with :data:`TRAINING_POSE2SIM_CAMERAS`; among ridges of the one-Gaussian model it had
the lowest instantaneous posture error on the level validation clips (2026-11-27: 23.4 %
against 23.6 % at 0.05 and 35.1 % at 0.01)."""


@dataclass(frozen=True)
class PostureSequence:
    """One rendered view of a clip: silhouettes and the truth.

    Attributes:
        name: ``<clip>_az<degrees>_<background>``.
        masks: ``(time, height, width)`` bool silhouettes from background subtraction.
        parts: ``(time, 5, 2)`` the true extremities of head, left/right hand, left/right foot
            (pixels): the top of the head, the hand tips, the toes of the drawn figure
            (:func:`extremities`), where a silhouette shows each part.
        joints: ``(time, 5, 2)`` the true head, left/right wrist, left/right ankle joints.
        labels: ``(time,)`` true postures.
        image_size: ``(width, height)``.
    """

    name: str
    masks: np.ndarray
    parts: np.ndarray
    labels: np.ndarray
    image_size: tuple[int, int]
    joints: np.ndarray | None = None


def extremities(joints_3d: np.ndarray) -> np.ndarray:
    """``(time, 5, 3)`` top of the head, left and right hand tips and toes of the figure the
    renderer draws (``jaxtrack.body._figure``) from its ``(time, 16, 3)`` joints
    (``FIGURE_MARKERS``): the points of each part farthest along its limb, where a silhouette
    shows it and Ghost's heuristics look for it."""
    from jaxtrack.body import _figure

    scale = _figure.body_scale(joints_3d)
    points, index, _ = _figure.figure_points(
        joints_3d, scale, _figure.random_appearance(np.random.default_rng(0)))

    def beyond(tip, base, distance):  # ``distance`` metres past ``tip`` along base → tip
        direction = points[:, index[tip]] - points[:, index[base]]
        direction /= np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-9)
        return points[:, index[tip]] + distance * scale * direction

    # the head ellipse's semi-axis (0.115 m) and the hand capsules' end radius (0.03 m)
    head = beyond("head_centre", "head", _HEAD_SEMI_AXIS)
    hands = [beyond(f"{side}_hand_tip", f"{side}_wrist", _HAND_TIP_RADIUS)
             for side in ("left", "right")]
    toes = [points[:, index[f"{side}_toe"]] for side in ("left", "right")]
    return np.stack([head, *hands, *toes], axis=1)


_HEAD_SEMI_AXIS = 0.115
_HAND_TIP_RADIUS = 0.03


def render_posture_sequence(clip: str, azimuth: float, *, image_size: tuple[int, int] = (640, 480),
                            background: str = "photo", fps: float = 30.0, seed: int = 0,
                            max_frames: int | None = None, pose2sim_camera: int | None = None,
                            laid_down: str | None = None) -> PostureSequence:
    """Render ``clip`` seen from ``azimuth`` over a ``background`` whose empty scene is known,
    and take its silhouettes by background subtraction
    (:func:`jaxtrack.vision.histograms.silhouettes`).

    With ``pose2sim_camera`` (0–3) the clip is staged in the Pose2Sim lab and seen through that
    real camera instead (its calibration, elevation and portrait frame, scaled by
    :data:`POSE2SIM_SCALE`: 363 × 640 or 360 × 640); ``azimuth`` and ``image_size`` are then
    unused. With ``laid_down`` (``"up"`` or ``"down"``) the clip is first laid on its back or
    its front (:meth:`jaxtrack.body.motion.Motion.laid_down`) and labelled by the same rule."""
    from jaxtrack.body._backgrounds import make_background
    from jaxtrack.body._figure import FIGURE_MARKERS
    from jaxtrack.body._staging import frontal_camera, project_numpy
    from jaxtrack.body.render import render_motion
    from jaxtrack.data import load_clip
    from jaxtrack.vision.histograms import silhouettes

    motion = load_clip(clip)
    if laid_down is not None:
        motion = motion.laid_down(laid_down)
    motion = motion.resample(fps)
    if max_frames is not None:
        if max_frames < 2:
            raise ValueError(f"max_frames must be at least 2, got {max_frames}")
        motion = motion.select(0, min(max_frames, motion.num_frames))
    if pose2sim_camera is None:
        camera = frontal_camera(motion, tuple(image_size), azimuth=azimuth, elevation=0.1)
        view = f"az{round(np.degrees(azimuth))}"
    else:
        motion, camera = _pose2sim_view(motion, pose2sim_camera)
        image_size, view = camera.image_size, camera.name
    scene, _ = make_background(background, tuple(image_size), np.random.default_rng(seed))
    rendered = render_motion(motion, camera, image_size=tuple(image_size), background=scene,
                             markers=FIGURE_MARKERS, seed=seed, progress=False)
    names = list(rendered.marker_names)
    joints = rendered.markers_2d[:, [names.index(name) for name in PART_TRUTH_MARKERS]]
    truth, _ = project_numpy(rendered.camera, extremities(rendered.joints_3d))
    labels = posture_labels(rendered.joints_3d, rendered.markers_2d, names)
    masks = silhouettes(rendered.images, scene)
    lying = "" if laid_down is None else f"_face-{laid_down}"
    return PostureSequence(f"{clip.split('/')[-1]}{lying}_{view}_{background}",
                           masks, np.asarray(truth, np.float64), labels,
                           rendered.image_size, np.asarray(joints, np.float64))


def render_sequences(clips: Sequence[str], azimuths: Sequence[float],
                     backgrounds: Sequence[str], image_size: tuple[int, int],
                     max_frames: int | None, seed: int, pose2sim_cameras: Sequence[int] = (),
                     laid_down: str | None = None) -> list[PostureSequence]:
    """Every clip from every azimuth, then through every Pose2Sim camera of
    ``pose2sim_cameras``, over every background (:func:`render_posture_sequence`, every clip
    laid down as ``laid_down`` says), clip by clip; the seeds :func:`evaluate` uses for the
    same arguments."""
    views = [(azimuth, None) for azimuth in azimuths] + [(0.0, int(camera))
                                                        for camera in pose2sim_cameras]
    sequences = []
    for index, clip in enumerate(clips):
        for view, (azimuth, camera) in enumerate(views):
            for background in backgrounds:
                sequences.append(render_posture_sequence(
                    clip, azimuth, image_size=image_size, background=background,
                    seed=seed + 97 * index + view, max_frames=max_frames,
                    pose2sim_camera=camera, laid_down=laid_down))
    return sequences


POSE2SIM_SCALE = 1 / 3
"""The Pose2Sim cameras' 1088 × 1920 frames rendered at a third: the longer side 640, the
paper's resolution."""


def _pose2sim_view(motion, index: int):
    """``motion`` staged in the Pose2Sim lab and its camera ``index`` scaled by
    :data:`POSE2SIM_SCALE`."""
    from jaxtrack.body import read_qca
    from jaxtrack.body._staging import scale_camera, stage_for_cameras
    from jaxtrack.data import path

    cameras = read_qca(path("pose2sim/Calib.qca.txt"), world_up="y")
    if not 0 <= index < len(cameras):
        raise ValueError(f"pose2sim_camera must be 0-{len(cameras) - 1}, got {index}")
    return (stage_for_cameras(motion, cameras),
            scale_camera(cameras[index], POSE2SIM_SCALE))


def labelled_features(sequence: PostureSequence, num_bins: int = 16
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The silhouette features (:func:`jaxtrack.vision.histograms.silhouette_features`) and
    the true postures of ``sequence``'s frames that have a silhouette."""
    from jaxtrack.vision.histograms import FRAME_OK, silhouette_features

    values, status = silhouette_features(sequence.masks, num_bins)
    keep = status == FRAME_OK
    return values[keep], sequence.labels[keep]


def training_features(clips: Sequence[str] = TRAINING_CLIPS, *,
                      azimuths: Sequence[float] = VIEW_AZIMUTHS,
                      backgrounds: Sequence[str] = ("photo",),
                      image_size: tuple[int, int] = (640, 480), num_bins: int = 16,
                      max_frames: int | None = None, seed: int = 0,
                      pose2sim_cameras: Sequence[int] = TRAINING_POSE2SIM_CAMERAS
                      ) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    """Render the training clips from every azimuth (and through every Pose2Sim camera of
    ``pose2sim_cameras``) over every background and label them:
    per rendered sequence, the features and labels of its frames with a silhouette (what
    :func:`jaxtrack.priors.postures.fit_posture_model` takes), and the settings they were
    rendered with, JSON-able (for :func:`fit`'s description)."""
    sequences = render_sequences(clips, azimuths, backgrounds, image_size, max_frames, seed,
                                 pose2sim_cameras)
    pairs = [labelled_features(sequence, num_bins) for sequence in sequences]
    features, labels = [values for values, _ in pairs], [names for _, names in pairs]
    settings = {"clips": list(clips), "azimuths": [float(a) for a in azimuths],
                "backgrounds": list(backgrounds), "image_size": list(image_size),
                "num_bins": num_bins, "pose2sim_cameras": [int(c) for c in pose2sim_cameras]}
    return features, labels, settings


def fit(features: Sequence[np.ndarray], labels: Sequence[np.ndarray], *,
        regularisation: float = DEFAULT_REGULARISATION, pseudocount: float = 0.5,
        components: int = DEFAULT_COMPONENTS, covariance: str = DEFAULT_COVARIANCE,
        **description
        ) -> tuple[PostureModel, dict]:
    """The posture model of :func:`training_features`' output and a JSON-able description
    (``description``'s entries, label counts, transition counts, the settings)."""
    from jaxtrack.priors.postures import transition_counts

    model = fit_posture_model(features, labels, regularisation=regularisation,
                              pseudocount=pseudocount, components=components,
                              covariance=covariance)
    all_labels = np.concatenate(labels)
    return model, {
        **description, "frames": int(all_labels.size),
        "label_counts": {name: int(np.sum(all_labels == q))
                         for q, name in enumerate(POSTURE_NAMES)},
        "transition_counts": transition_counts(labels).astype(int).tolist(),
        "regularisation": regularisation, "pseudocount": pseudocount,
        "components": components, "covariance": covariance,
    }


def train(clips: Sequence[str] = TRAINING_CLIPS, *, azimuths: Sequence[float] = VIEW_AZIMUTHS,
          backgrounds: Sequence[str] = ("photo",), image_size: tuple[int, int] = (640, 480),
          num_bins: int = 16, max_frames: int | None = None, seed: int = 0,
          regularisation: float = DEFAULT_REGULARISATION, pseudocount: float = 0.5,
          components: int = DEFAULT_COMPONENTS, covariance: str = DEFAULT_COVARIANCE,
          pose2sim_cameras: Sequence[int] = TRAINING_POSE2SIM_CAMERAS
          ) -> tuple[PostureModel, dict]:
    """Render the training clips from every azimuth over every background, label them and fit
    the posture model. Returns the model and a JSON-able description (clips, views, label
    counts, transition counts) to save with it (``regularisation``:
    :data:`DEFAULT_REGULARISATION`; ``components``: :data:`DEFAULT_COMPONENTS`; ``covariance``:
    :data:`DEFAULT_COVARIANCE`; ``pose2sim_cameras``: :data:`TRAINING_POSE2SIM_CAMERAS`, the
    real cameras every clip is also seen through)."""
    features, labels, settings = training_features(
        clips, azimuths=azimuths, backgrounds=backgrounds, image_size=image_size,
        num_bins=num_bins, max_frames=max_frames, seed=seed, pose2sim_cameras=pose2sim_cameras)
    return fit(features, labels, regularisation=regularisation, pseudocount=pseudocount,
               components=components, covariance=covariance,
               **settings)


def _best_pair_errors(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Squared error per frame of a pair of parts under the better of the two assignments."""
    straight = np.sum((estimate - truth) ** 2, axis=-1)
    crossed = np.sum((estimate - truth[:, ::-1]) ** 2, axis=-1)
    return np.where(straight.sum(-1, keepdims=True) <= crossed.sum(-1, keepdims=True), straight,
                    crossed)


def part_squared_errors(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``(time, 5)`` squared errors (px²) of head, hand, hand, foot, foot; hands and feet under
    the best left/right assignment per frame (the paper's superposition)."""
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    if estimate.shape != truth.shape or estimate.shape[1:] != (5, 2):
        raise ValueError(f"estimate and truth must both be (time, 5, 2), got {estimate.shape} "
                         f"and {truth.shape}")
    head = np.sum((estimate[:, :1] - truth[:, :1]) ** 2, axis=-1)
    return np.concatenate([head, _best_pair_errors(estimate[:, 1:3], truth[:, 1:3]),
                           _best_pair_errors(estimate[:, 3:5], truth[:, 3:5])], axis=1)


def score(parts: np.ndarray, posture: np.ndarray, truth_parts: np.ndarray,
          truth_labels: np.ndarray, valid: np.ndarray | None = None) -> dict:
    """Mean squared error per part (px²), fraction of frames within each ε in :data:`EPSILONS`
    per part, largest head error (px) and posture error rate, over the ``valid`` frames (all
    None, with ``frames`` 0, when no frame is valid)."""
    squared = part_squared_errors(parts, truth_parts)
    valid = np.ones(len(squared), bool) if valid is None else np.asarray(valid, bool)
    squared, posture, labels = squared[valid], np.asarray(posture)[valid], truth_labels[valid]
    if not len(squared):  # no frame with a silhouette: nothing to score, and no NaN
        return {"mse": None, "within": None, "max_head_error": None, "posture_error": None,
                "frames": 0}
    groups = {"head": [0], "hands": [1, 2], "feet": [3, 4], "all": [0, 1, 2, 3, 4]}
    distance = np.sqrt(squared)
    return {
        "mse": {name: float(squared[:, idx].mean()) for name, idx in groups.items()},
        "within": {name: {f"{eps:g}": float(np.mean(distance[:, idx] <= eps)) for eps in EPSILONS}
                   for name, idx in groups.items()},
        "max_head_error": float(distance[:, 0].max()),
        "posture_error": float(np.mean(posture != labels)),
        "frames": int(valid.sum()),
    }


def track(key, model: MixedStateModel, observations: MixedStateFrame, num_particles: int = 500,
          *, lag: int | None = None, backward_paths: int | None = None) -> dict:
    """Filter and smooth one sequence; every estimate as NumPy arrays.

    Returns a dict of ``(time,)`` postures and ``(time, 5, 2)`` parts for ``instantaneous``,
    ``filtered``, ``smoothed`` (and ``fixed_lag`` when ``lag`` is given, ``backward``, the
    two-pass smoother of :func:`jaxtrack.trackers.mixed_state.smooth_backward` with that many
    paths, when ``backward_paths`` is), each as ``{"posture", "parts"}``, plus ``status``,
    ``ess`` and the run time in seconds (``backward_seconds`` for the two-pass smoother).
    """
    begin = time.perf_counter()
    result = filter_sequence(key, model, observations, num_particles)
    smoothed = smooth(result)
    jax.block_until_ready(smoothed)
    seconds = time.perf_counter() - begin
    posture, parts = instantaneous_estimates(model, observations)
    out = {
        "instantaneous": {"posture": np.asarray(posture), "parts": np.asarray(parts)},
        "filtered": {"posture": np.asarray(result.filtered_posture),
                     "parts": np.asarray(result.filtered_parts)},
        "smoothed": {"posture": np.asarray(smoothed.posture), "parts": np.asarray(smoothed.parts)},
        "status": np.asarray(result.status), "ess": np.asarray(result.ess),
        "seconds": seconds,
    }
    if lag is not None:
        lagged = smooth_fixed_lag(result, lag)
        out["fixed_lag"] = {"posture": np.asarray(lagged.posture),
                            "parts": np.asarray(lagged.parts)}
    if backward_paths is not None:
        begin = time.perf_counter()
        backward = smooth_backward(jr.fold_in(key, 1), result, model, observations,
                                   backward_paths)
        jax.block_until_ready(backward)
        out["backward_seconds"] = time.perf_counter() - begin
        out["backward"] = {"posture": np.asarray(backward.posture),
                           "parts": np.asarray(backward.parts)}
    return out



def model_with_options(posture_model, model_options) -> MixedStateModel:
    """The :class:`MixedStateModel` of an evaluation's ``model_options`` (as its results record
    them): :class:`MixedStateModel`'s keywords, and ``part_cutoff``, the part likelihood's δ,
    and ``part_scale``, a factor on its standard deviations σ_i (R_i = (scale σ_i)² I, eq. 7)."""
    options = dict(model_options)
    if "part_cutoff" in options or "part_scale" in options:  # eq. 7's δ and R_i
        import inspect

        from jaxtrack.likelihoods.part_distances import PartDistances

        defaults = inspect.signature(PartDistances).parameters  # σ_i and δ not given
        sigma = np.asarray(defaults["standard_deviations"].default, np.float64)
        options["part_likelihood"] = PartDistances(
            float(options.pop("part_scale", 1.0)) * sigma,
            cutoff=options.pop("part_cutoff", defaults["cutoff"].default))
    return MixedStateModel(posture_model, **options)

def evaluate(posture_model: PostureModel, clips: Sequence[str] = TEST_CLIPS, *,
             azimuths: Sequence[float] = VIEW_AZIMUTHS, backgrounds: Sequence[str] = ("clutter",),
             image_size: tuple[int, int] = (640, 480), num_bins: int = 16,
             num_particles: int = 500, lag: int = 10, max_frames: int | None = None,
             seed: int = 1, sequences: Sequence[PostureSequence] | None = None,
             pose2sim_cameras: Sequence[int] = (), backward_paths: int | None = None,
             **model_options) -> dict:
    """Render the test clips, track each view, and score every estimate.

    Returns ``{"sequences": {name: {estimate: score}}, "overall": {estimate: score},
    "overall_joints": {estimate: score}}``, the overall scores over all frames of all sequences
    pooled, estimates being ``instantaneous`` (extended Ghost), ``filtered``, ``smoothed`` and
    ``fixed_lag``; ``overall`` against the parts' extremities (top of the head, hand tips, toes:
    where silhouette hypotheses locate them), ``overall_joints`` against the head, wrist and
    ankle joints. ``sequences``: the rendered views (:func:`render_sequences` of the same
    arguments), to score several settings on one rendering. ``pose2sim_cameras``: also render
    through these real Pose2Sim cameras (0–3; :func:`render_posture_sequence`).
    ``backward_paths``: also score the two-pass smoother with that many paths (estimate
    ``backward``; :func:`track`). ``model_options``:
    :class:`MixedStateModel`'s keywords, and ``part_cutoff``, the part likelihood's δ, and
    ``part_scale``, a factor on its standard deviations σ_i (R_i = (scale σ_i)² I, eq. 7).
    """
    from jaxtrack.vision.histograms import FRAME_OK

    if posture_model.num_features != 2 * num_bins + 1:
        raise ValueError(f"posture_model has {posture_model.num_features} features but "
                         f"num_bins={num_bins} gives {2 * num_bins + 1}")
    model = model_with_options(posture_model, model_options)
    if sequences is None:
        sequences = render_sequences(clips, azimuths, backgrounds, image_size, max_frames, seed,
                                     pose2sim_cameras)
    kinds = ("instantaneous", "filtered", "smoothed", "fixed_lag") + (
        () if backward_paths is None else ("backward",))
    pooled = {kind: {"posture": [], "parts": []} for kind in kinds}
    truth_parts, truth_joints, truth_labels, valid_all, per_sequence = [], [], [], [], {}
    key = jr.PRNGKey(seed)
    for sequence in sequences:
        observations = observations_from_silhouettes(sequence.masks, num_bins=num_bins)
        key, subkey = jr.split(key)
        estimates = track(subkey, model, observations, num_particles, lag=lag,
                          backward_paths=backward_paths)
        valid = estimates["status"] == FRAME_OK
        per_sequence[sequence.name] = {
            kind: score(estimates[kind]["parts"], estimates[kind]["posture"], sequence.parts,
                        sequence.labels, valid) for kind in kinds}
        per_sequence[sequence.name]["joints"] = {
            kind: score(estimates[kind]["parts"], estimates[kind]["posture"], sequence.joints,
                        sequence.labels, valid)["mse"] for kind in kinds}
        per_sequence[sequence.name]["seconds"] = estimates["seconds"]
        if backward_paths is not None:
            per_sequence[sequence.name]["backward_seconds"] = estimates["backward_seconds"]
        for kind in kinds:
            for field_name in ("posture", "parts"):
                pooled[kind][field_name].append(estimates[kind][field_name])
        truth_parts.append(sequence.parts)
        truth_joints.append(sequence.joints)
        truth_labels.append(sequence.labels)
        valid_all.append(valid)
    truth_parts, truth_labels = np.concatenate(truth_parts), np.concatenate(truth_labels)
    truth_joints = np.concatenate(truth_joints)
    valid_all = np.concatenate(valid_all)
    overall = {kind: score(np.concatenate(pooled[kind]["parts"]),
                           np.concatenate(pooled[kind]["posture"]), truth_parts, truth_labels,
                           valid_all) for kind in kinds}
    overall_joints = {kind: score(np.concatenate(pooled[kind]["parts"]),
                                  np.concatenate(pooled[kind]["posture"]), truth_joints,
                                  truth_labels, valid_all) for kind in kinds}
    confusion = np.zeros((NUM_POSTURES, NUM_POSTURES), int)
    np.add.at(confusion, (truth_labels[valid_all],
                          np.concatenate(pooled["smoothed"]["posture"])[valid_all]), 1)
    return {"sequences": per_sequence, "overall": overall, "overall_joints": overall_joints,
            "smoothed_confusion": confusion.tolist(),
            "settings": {"clips": list(clips), "azimuths": [float(a) for a in azimuths],
                         "backgrounds": list(backgrounds), "image_size": list(image_size),
                         "num_particles": num_particles, "lag": lag, "seed": seed,
                         "backward_paths": backward_paths,
                         "device": jax.devices()[0].device_kind,
                         "model": {name: value if isinstance(value, (bool, str))
                                   else float(value) for name, value in model_options.items()}}}

