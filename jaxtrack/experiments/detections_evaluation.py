"""A detector's keypoints on the real Pose2Sim videos, scored against the triangulated reference
as they come and after each smoothing baseline, in 2-D per view and in 3-D from the four views.

    python -m jaxtrack.experiments.detections_evaluation --iterations 15 \
        --json papers/results/detections_evaluation.json

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

Particle-filter rows (:func:`particle_filter_estimates`, ``--trackers``): per view, CONDENSATION
in the SPM state on the detections alone (:func:`jaxtrack.experiments.detection_tracking.
detection_tracker`), its detection density and dynamics' noise fitted on that view's
detections by the log-evidence (:func:`~jaxtrack.experiments.detection_tracking.
fit_detection_model`, the iteration count and N of ``track_detections``' defaults unless
``--iterations`` / ``--particles`` say otherwise): the filter's estimate, the whole-sequence
(ancestry) smoother and the fixed-lag smoother, each under two priors that differ in one thing,
the random walk ``detection_tracker`` builds (AR(2) coefficients 1, 0) and a constant-velocity
AR(2) (2, −1), same noise, same fit. ``condensation hand-set ×w`` rows: the random-walk filter
with the density's hand-set defaults and every scale (f_k, σ₀) divided by √w, w in
:data:`HAND_SET_WEIGHTS` (a weight w on the Gaussian's log-density is a scale 1/√w), unfitted:
the learned-against-hand-set comparison. 3-D: ``dlt of ROW`` triangulates a row's four views
(every view weighing 1). ``speed``: the fitted filter's time per frame at
:data:`SPEED_PARTICLES` particles, compilation apart. The targets are read from the
scores by :func:`targets` (``"targets"`` in the JSON).

The papers' priors (:data:`PAPER_ROWS`), each on the same detections with the same fit:

- Tian et al. (:func:`latent_estimates`): the latent tracker as ``jaxtrack track --method
  latent --keypoints --no-image`` builds it (the bundled GPLVM, or ``--latent-model``), fitted
  and run as the SPM filter is, so that ``latent (Tian 2005)`` against ``condensation random
  walk`` / ``constant velocity`` differ in the prior (and the smoother rows in nothing else).
  ``--add latent --json FILE`` runs only these rows and merges them into FILE
  (:func:`add_rows`), the other rows kept.
- Ong & Gong: the row ``linear combination (Ong 2002)`` is reserved; its paper's command
  (``papers/ong2002/detections_real_video.py``, a 3-D skeleton from the four views, scored by
  :func:`score_3d` on this setting) adds it with :func:`add_rows`: the world skeleton as a 3-D
  row and its :func:`projected` views as a 2-D one.
- Kwatra et al.: not in this table. ``papers/kwatra2002/detections_real_video.py`` scores five
  parts (the head's top, the wrists and the ankles, hands and feet under their best left/right
  assignment) as MSE in px² at 640 px and the share within 20 px; here twelve upper-body
  markers (no ankles, MediaPipe's head point) in torso lengths. Only the wrists are common, so
  its rows would measure other markers, not another tracker; its own table compares it with
  MediaPipe's keypoints and their Butterworth filter on its markers.

:func:`beaten_by` names every row that beats a paper's row (``"paper_priors"`` in the JSON);
``--latent-reach`` prints how near the latent prior comes to the reference's own poses
(:func:`latent_reach`).

    python -m jaxtrack.experiments.detections_evaluation --filter-check cam01

checks the filter itself (:func:`filter_check`): the hand-set random-walk filter given the
reference's own markers as detections, then MediaPipe's, per walk step and swap probability,
and how far each moves per frame in the walk's std (:func:`walk_steps`).

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

__all__ = ["DEFAULT_DETECTIONS", "HAND_SET_WEIGHTS", "MIN_CONFIDENCE", "PAPER_ROWS", "PRIORS",
           "RESULTS", "SPEED_PARTICLES", "VIEWS", "Setting", "add_rows", "baseline_estimates",
           "beaten_by", "detect_views", "evaluate", "filter_check", "latent_estimates",
           "latent_reach", "left_right_swaps", "load_setting", "main",
           "particle_filter_estimates", "projected", "score_2d", "score_3d", "score_rows",
           "table", "targets", "triangulated", "walk_steps"]

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
PRIORS = {"random walk": (1.0, 0.0), "constant velocity": (2.0, -1.0)}
"""The particle filter's priors: AR(2) coefficients (x_t = a x_{t-1} + b x_{t-2} + noise) in
the SPM state, the same noise for both."""
HAND_SET_WEIGHTS = (1.0, 4.0, 16.0, 64.0)
"""Hand-set weights on the detection density's Gaussian: its scales divided by √w."""
SPEED_PARTICLES = 1000
"""N at which the filter's time per frame is reported (the speed target)."""
LAG = 5
"""The fixed-lag smoother's lag in frames."""
RESULTS = (Path(__file__).resolve().parents[2] / "papers" / "results"
           / "detections_evaluation.json")
"""Where the committed results live (``--json``'s usual value)."""
PAPER_ROWS = {"tian2005": "latent (Tian 2005)", "ong2002": "linear combination (Ong 2002)",
              "kwatra2002": "mixed-state (Kwatra 2002)"}
"""The row each paper's tracker on these detections is scored under (its smoother rows add
`` smoother`` / `` lag 5``): Tian et al.'s by :func:`latent_estimates`; Ong & Gong's is added
by its paper's command through :func:`add_rows`; Kwatra et al.'s is not scored here (module
docstring, "Kwatra et al.")."""
TRACKER_PREFIXES = ("condensation", *PAPER_ROWS.values())
"""Rows that are particle filters on the detections, not baselines."""


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


def _view_detections(setting: Setting, view: str):
    """One view's detections as :class:`jaxtrack.vision.detections.Detections` (one person, or
    none where MediaPipe found no one), in the camera's frame size."""
    from jaxtrack.body import SPM_MARKERS
    from jaxtrack.vision.detections import Detections

    points, confidence = setting.detections[view]
    found = np.all(np.isfinite(points), -1)
    confidence = np.where(found, confidence, 0.0)
    camera = setting.cameras[setting.views.index(view)]
    return Detections(np.where(found[..., None], points, np.nan)[:, None], confidence[:, None],
                      (confidence > 0).any(-1).astype(int), SPM_MARKERS, "markers",
                      frame_size=tuple(float(v) for v in camera.image_size),
                      frame_ids=np.asarray(setting.frame_indices), source=f"{view} detections")


def _with_prior(tracker, coefficients: tuple[float, float]):
    """The tracker with its AR(2) dynamics' coefficients set (the noise kept)."""
    import equinox as eqx
    import jax.numpy as jnp

    first = tracker.dynamics.first_coefficients
    return eqx.tree_at(lambda t: (t.dynamics.first_coefficients, t.dynamics.second_coefficients),
                       tracker, (jnp.full_like(first, coefficients[0]),
                                 jnp.full_like(first, coefficients[1])))


def _hand_set(tracker, weight: float):
    """The tracker with the detection density's hand-set defaults, scales divided by √w."""
    import equinox as eqx

    from jaxtrack.likelihoods.detections import detection_model

    base = detection_model(dtype=tracker.likelihood.detections.joint_scales.dtype)
    scaled = eqx.tree_at(lambda d: (d.joint_scales, d.pixel_noise), base,
                         (base.joint_scales / np.sqrt(weight), base.pixel_noise / np.sqrt(weight)))
    return eqx.tree_at(lambda t: t.likelihood.detections, tracker, scaled)


def _density_record(model) -> dict:
    return {"joint_scales": [round(float(v), 4) for v in np.asarray(model.joint_scales)],
            **{name: float(getattr(model, name)) for name in (
                "pixel_noise", "outlier_rate", "swap_probability", "absent_probability")},
            "swap_pairs": int(np.sum(np.asarray(model.swap) != np.arange(len(model.swap))) // 2)}


def _fit_settings(particles: int | None, iterations: int | None) -> tuple[int, int, float]:
    """N, Adam iterations and learning rate of a fit: those given, else ``track_detections``'."""
    import inspect

    from jaxtrack.experiments.detection_tracking import track_detections

    defaults = inspect.signature(track_detections).parameters
    return (int(particles or defaults["num_particles"].default),
            int(iterations or defaults["iterations"].default),
            float(defaults["learning_rate"].default))


def _fit_note(fit, hand_set, iterations: int) -> dict:
    """A fit's record in the notes: the fitted density beside the hand-set one, its cost and
    its first and last log-evidence."""
    return {"fitted": _density_record(fit.detections), "hand_set": _density_record(hand_set),
            "noise_factor": fit.noise_factor, "seconds": fit.seconds,
            "compile_seconds": fit.compile_seconds,
            "seconds_per_iteration": fit.seconds / max(iterations, 1),
            "log_evidence_first": float(fit.log_evidence[0]),
            "log_evidence_last": float(fit.log_evidence[-1])}


def _row_timer(rows: dict, notes: dict):
    """``timed(row, view, run, *args, **options)``: ``run``'s ``(frames, 12, 2)`` estimate into
    ``rows[row][view]``, its seconds into ``notes["seconds"][row][view]``."""
    def timed(row, view, run, *args, **options):
        tick = time.perf_counter()
        rows.setdefault(row, {})[view] = np.asarray(run(*args, **options), np.float64)
        notes["seconds"].setdefault(row, {})[view] = time.perf_counter() - tick

    return timed


def particle_filter_estimates(setting: Setting, *, particles: int | None = None,
                              iterations: int | None = None, lag: int = LAG,
                              priors: Mapping = PRIORS, weights=HAND_SET_WEIGHTS,
                              speed_particles: int | None = SPEED_PARTICLES, seed: int = 0,
                              progress=None) -> tuple[dict, dict]:
    """CONDENSATION on each view's detections alone (module docstring): ``(rows_2d, notes)``,
    rows_2d name → view → ``(frames, 12, 2)``; notes: per prior and view the fitted density
    beside the hand-set one, the fit's cost and log-evidence, each run's seconds, and the speed.

    Args:
        setting: :func:`load_setting`'s.
        particles: N of the fit and the filters; default ``track_detections``'.
        iterations: Adam iterations of the fit; default ``track_detections``'.
        lag: the fixed-lag smoother's lag.
        priors: name → AR(2) coefficients (:data:`PRIORS`); the first is the default prior,
            and the hand-set rows and the speed use it.
        weights: the hand-set weights (:data:`HAND_SET_WEIGHTS`); empty for none.
        speed_particles: N of the speed run on the first view (None: no speed run).
        seed: the PRNG seed (every view and prior the same keys).
        progress: a tqdm-like object updated once per view and prior.
    """
    import equinox as eqx
    import jax.random as jr

    from jaxtrack.experiments.detection_tracking import (
        detection_tracker,
        fit_detection_model,
        initial_pose_of,
        smooth_markers,
    )
    from jaxtrack.trackers import Engine, track
    from jaxtrack.trackers._particles import detection_observations

    particles, iterations, learning_rate = _fit_settings(particles, iterations)
    key_fit, key_track = jr.split(jr.key(seed))
    rows, first = {}, next(iter(priors))
    notes = {"particles": particles, "iterations": iterations, "learning_rate": learning_rate,
             "lag": lag, "priors": {name: list(c) for name, c in priors.items()},
             "hand_set_weights": list(weights), "fits": {}, "seconds": {}}
    timed = _row_timer(rows, notes)

    def filtered(tracker, observations, pose):
        return track(tracker, key_track, observations, pose, progress=False).markers

    for view in setting.views:
        observations = detection_observations(_view_detections(setting, view))
        pose = initial_pose_of(observations.detections)
        plain = detection_tracker(pose, num_particles=particles)
        for prior, coefficients in priors.items():
            tracker = _with_prior(plain, coefficients)
            fitted, fit = fit_detection_model(tracker, key_fit, observations, pose,
                                              iterations=iterations, learning_rate=learning_rate)
            notes["fits"].setdefault(prior, {})[view] = _fit_note(
                fit, tracker.likelihood.detections, iterations)
            timed(f"condensation {prior}", view, filtered, fitted, observations, pose)
            timed(f"condensation {prior} smoother", view, smooth_markers, fitted, key_track,
                  observations, pose)
            timed(f"condensation {prior} lag {lag}", view, smooth_markers, fitted, key_track,
                  observations, pose, lag=lag)
            if prior == first:
                for weight in weights:
                    timed(f"condensation hand-set x{weight:g}", view, filtered,
                          _hand_set(tracker, weight), observations, pose)
                if speed_particles and view == setting.views[0]:
                    many = eqx.tree_at(lambda t: t.engine, fitted, Engine(int(speed_particles)))
                    runs = [track(many, jr.fold_in(key_track, i), observations, pose,
                                  progress=False) for i in range(2)]
                    notes["speed"] = {
                        "view": view, "particles": int(speed_particles),
                        "frames": len(setting.frame_indices),
                        "ms_per_frame": 1e3 * runs[1].seconds_per_frame,
                        "ms_per_frame_first_run": 1e3 * runs[0].seconds_per_frame,
                        "compile_seconds": runs[0].compile_seconds,
                        "detector_ms_per_frame": setting.detector[view].get("ms_per_frame")}
            if progress is not None:
                progress.update(1)
    return rows, notes


def _latent_prior(model: Path | None):
    """The latent tracker's prior: ``model`` or the bundled one ``jaxtrack track --method latent``
    uses (:func:`jaxtrack.data.models.default_model`)."""
    from jaxtrack.data.models import default_model
    from jaxtrack.priors.train import load_prior

    return load_prior(default_model("latent") if model is None else model)


def latent_estimates(setting: Setting, *, model: Path | None = None,
                     particles: int | None = None, iterations: int | None = None,
                     lag: int = LAG, seed: int = 0, progress=None) -> tuple[dict, dict]:
    """Tian et al.'s latent tracker (Algorithm 2: CONDENSATION in the GPLVM's latent space,
    eq. 6's walk, μ(x) of eq. 3 decoded to the markers) on each view's detections alone, built
    and fitted as :func:`particle_filter_estimates` builds and fits the SPM filter, so that the
    two differ in the prior only: the same detection density (hand-set start, one noise factor,
    f_k, σ₀ and ε fitted by the same Adam ascent of the log-evidence from the same key), the
    same N, the same frame-0 pose, the same filter, smoother and fixed-lag estimates from the
    same key. The prior is ``jaxtrack track --method latent``'s (the bundled GPLVM, or
    ``model``), ν rescaled to the videos' frame rate, without the refinement stage (the
    paper's estimate; the SPM filter has none).

    Returns:
        ``(rows_2d, notes)`` as :func:`particle_filter_estimates`'s, rows
        ``PAPER_ROWS["tian2005"]`` (the tracker's estimate: the mean of the best particle's
        mode), its `` all particles`` (the weighted mean of every particle, the paper's and the
        SPM filter's estimate, same fit), `` smoother`` and `` lag L``.
    """
    import equinox as eqx
    import jax.random as jr

    from jaxtrack.experiments.detection_tracking import (
        fit_detection_model,
        initial_pose_of,
        smooth_markers,
    )
    from jaxtrack.likelihoods.detections import detection_model
    from jaxtrack.trackers import DetectionLikelihood, Engine, latent_tracker, track
    from jaxtrack.trackers._particles import detection_observations

    particles, iterations, learning_rate = _fit_settings(particles, iterations)
    prior = _latent_prior(model)
    key_fit, key_track = jr.split(jr.key(seed))  # the SPM filter's keys
    name = PAPER_ROWS["tian2005"]
    rows = {}
    notes = {"particles": particles, "iterations": iterations, "learning_rate": learning_rate,
             "lag": lag, "model": str(model) if model is not None else "bundled latent.npz",
             "model_clips": list(dict(prior.description or {}).get("settings", {})
                                .get("clips", [])), "refinement": None, "fits": {},
             "seconds": {}}
    tracker = latent_tracker(prior.model, prior.template, engine=Engine(particles),
                             fps=setting.fps, likelihood=DetectionLikelihood(detection_model()),
                             refinement=None)
    # the SPM filter's estimate is the weighted mean of every particle; the latent tracker's
    # default, the mean of the best particle's mode, is a departure from the paper
    every = latent_tracker(prior.model, prior.template, engine=Engine(particles),
                           fps=setting.fps, likelihood=DetectionLikelihood(detection_model()),
                           refinement=None, mode_radius=float("inf"))

    timed = _row_timer(rows, notes)

    def filtered(fitted, observations, pose):
        return track(fitted, key_track, observations, pose, progress=False).markers

    for view in setting.views:
        observations = detection_observations(_view_detections(setting, view))
        pose = initial_pose_of(observations.detections)
        fitted, fit = fit_detection_model(tracker, key_fit, observations, pose,
                                          iterations=iterations, learning_rate=learning_rate)
        notes["fits"][view] = _fit_note(fit, tracker.likelihood.detections, iterations)
        timed(name, view, filtered, fitted, observations, pose)
        timed(f"{name} all particles", view, filtered,
              eqx.tree_at(lambda t: (t.likelihood, t.latent_std), every,
                          (fitted.likelihood, fitted.latent_std)), observations, pose)
        timed(f"{name} smoother", view, smooth_markers, fitted, key_track, observations, pose)
        timed(f"{name} lag {lag}", view, smooth_markers, fitted, key_track, observations, pose,
              lag=lag)
        if progress is not None:
            progress.update(1)
    return rows, notes


def latent_reach(setting: Setting, *, model: Path | None = None,
                 objective: str = "reconstruction") -> dict:
    """How near Tian et al.'s prior comes to the reference's own poses, per view: each frame's
    reference markers as SPM link features in the prior's template, the latent point of them
    and μ of it (eq. 3), links stretched to the subject's proportions of frame 0 and placed at
    the frame's own placement, as :func:`latent_estimates`' tracker decodes a particle. With
    ``objective="reconstruction"`` the latent point is the one whose μ is nearest the pose
    (from eq. 5's start; a local optimum): what the prior can draw of each pose at the frame's
    own neck and scale, which no detection density, fit or particle count improves (the SPM
    filter's state reaches every pose; a latent particle may still shift its placement to
    trade some error); ``"posterior"``: eq. 5's μ⁻¹, where the tracker starts. Returns view →
    :func:`score_2d`'s scores."""
    import jax
    import jax.numpy as jnp

    from jaxtrack.body import spm_initial_state
    from jaxtrack.priors.poses import markers_from_features, pose_features

    prior = _latent_prior(model)
    out = {}
    with jax.enable_x64(True):  # μ⁻¹ in float64, as the tracker's start
        gplvm = prior.model.astype(jnp.float64)
        template = jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64), prior.template)
        for view in setting.views:
            truth = jnp.asarray(setting.truth_2d[view], jnp.float64)
            states = jax.vmap(lambda pose: spm_initial_state(pose, template))(truth)
            features = pose_features(states, template)
            latents = gplvm.inverse(features).latents
            if objective != "posterior":
                latents = gplvm.inverse(features, initial_latents=latents,
                                        objective=objective).latents
            decoded = jax.vmap(gplvm.mean)(latents)
            observed, made = (np.asarray(f).reshape(len(truth), -1, 2)
                              for f in (features, decoded))
            scale = np.clip(np.linalg.norm(observed[0], axis=-1)
                            / np.maximum(np.linalg.norm(made[0], axis=-1), 1e-9), 0.5, 2.0)
            stretched = jnp.asarray((made * scale[:, None]).reshape(len(truth), -1))
            markers = jax.vmap(markers_from_features)(stretched, states[:, :3])
            out[view] = score_2d(np.asarray(markers), setting.truth_2d[view])
    return out


def walk_steps(points, step: float = 0.03) -> dict:
    """How far a ``(frames, 12, 2)`` motion moves per frame in the random walk's own units:
    each frame's SPM state (the template of frame 0, :func:`jaxtrack.body.spm_initial_state`),
    its per-frame change divided by the walk's std
    (:func:`jaxtrack.priors.dynamics.default_noise_floor` at ``step``). Returns
    ``beyond_3_sigma`` (the share of frames where some component moves more than 3 std) and
    ``largest`` (the five components with the largest 95th percentile, in std)."""
    import jax.numpy as jnp

    from jaxtrack.body import SPM_STATE_NAMES, build_template, spm_initial_state
    from jaxtrack.priors.dynamics import default_noise_floor

    points = np.asarray(points, np.float64)
    template = build_template(points[:1])
    states = np.stack([np.asarray(spm_initial_state(jnp.asarray(pose), template))
                       for pose in points])
    change = np.diff(states, axis=0)
    change[:, 3:] = (change[:, 3:] + np.pi) % (2 * np.pi) - np.pi  # angles wrap
    ratio = np.abs(change) / default_noise_floor(float(np.exp(states[0, 0])), relative=step)
    high = np.percentile(ratio, 95, axis=0)
    return {"beyond_3_sigma": float(np.mean((ratio > 3).any(1))),
            "largest": {SPM_STATE_NAMES[k]: float(high[k]) for k in np.argsort(-high)[:5]}}


def filter_check(setting: Setting, view: str, *, steps=(0.03, 0.1), weight: float = 16.0,
                 swap_probabilities=(0.05, 0.0), particles: int = 500, seed: int = 1) -> list:
    """The random-walk filter (hand-set density, scales divided by √``weight``, unfitted) given
    the reference's own markers as detections (confidence 0.9), then MediaPipe's, for each
    random-walk step and swap probability: does the filter lose what its input holds?

    Returns:
        rows ``{"input", "step", "swap_probability", "error_px", "error_torso", "within_15",
        "left_right_swaps"}``.
    """
    import dataclasses

    import equinox as eqx
    import jax.numpy as jnp
    import jax.random as jr

    from jaxtrack.experiments.detection_tracking import detection_tracker, initial_pose_of
    from jaxtrack.trackers import track
    from jaxtrack.trackers._particles import detection_observations

    truth = setting.truth_2d[view]
    exact = dataclasses.replace(setting, detections={
        **setting.detections, view: (truth, np.full(truth.shape[:2], 0.9))})
    rows = []
    for name, source in (("reference", exact), ("mediapipe", setting)):
        observations = detection_observations(_view_detections(source, view))
        pose = initial_pose_of(observations.detections)
        for step in steps:
            tracker = _hand_set(detection_tracker(pose, num_particles=particles, step=step),
                                weight)
            for swap in swap_probabilities:
                swapped = eqx.tree_at(lambda t: t.likelihood.detections.swap_probability,
                                      tracker, jnp.asarray(swap, tracker.dynamics.noise_std.dtype))
                estimate = np.asarray(track(swapped, jr.key(seed), observations, pose,
                                            progress=False).markers, np.float64)
                scored = score_2d(estimate, truth)
                rows.append({"input": name, "step": step, "swap_probability": swap,
                             **{key: scored[key] for key in ("error_px", "error_torso",
                                                             "within_15")},
                             "left_right_swaps": left_right_swaps(estimate, truth)["frames"]})
    return rows


NOISE_CHECK_RUNS = ((15, 0.05), (60, 0.1))
"""``(Adam iterations, step)`` of :func:`noise_check`'s fits: the evaluation's, and a longer,
larger-stepped fit that takes the log-evidence further."""


def noise_check(setting: Setting, view: str, *, runs=NOISE_CHECK_RUNS, particles: int = 500,
                seed: int = 0) -> list[dict]:
    """The fitted random-walk filter on one view with one factor on the walk's noise (the
    default) against one factor per SPM component (``fit_noise="per_component"``, so that the
    fit may widen the forearms' walk alone), for each ``(iterations, step)`` of ``runs``:
    rows of the fit's last log-evidence, the filter's error and the largest factors."""
    import jax.random as jr

    from jaxtrack.experiments.detection_tracking import (
        detection_tracker,
        fit_detection_model,
        initial_pose_of,
    )
    from jaxtrack.trackers import track
    from jaxtrack.trackers._particles import detection_observations

    key_fit, key_track = jr.split(jr.key(seed))
    observations = detection_observations(_view_detections(setting, view))
    pose = initial_pose_of(observations.detections)
    tracker = _with_prior(detection_tracker(pose, num_particles=particles),
                          next(iter(PRIORS.values())))
    rows = []
    for iterations, step in runs:
        for noise in (True, "per_component"):
            fitted, fit = fit_detection_model(tracker, key_fit, observations, pose,
                                              iterations=iterations, learning_rate=step,
                                              fit_noise=noise)
            estimate = track(fitted, key_track, observations, pose, progress=False).markers
            scored = score_2d(estimate, setting.truth_2d[view])
            factors = np.atleast_1d(fit.noise_factors if fit.noise_factors is not None
                                    else fit.noise_factor)
            rows.append({"iterations": iterations, "step": step,
                         "noise": "per component" if noise == "per_component" else "one",
                         "log_evidence": float(fit.log_evidence[-1]),
                         "error_torso": scored["error_torso"],
                         "within_15": scored["within_15"],
                         "largest_factors": np.round(np.sort(factors)[::-1][:3], 2).tolist()})
    return rows


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
    scored_2d, scored_3d = score_rows(setting, rows_2d, rows_3d)
    return {"rows_2d": scored_2d, "rows_3d": scored_3d,
            "raw_left_right_swaps": swaps, "detector": setting.detector, "notes": notes,
            "frames": [int(i) for i in setting.frame_indices], "fps": setting.fps,
            "min_confidence": min_confidence}


def score_rows(setting: Setting, rows_2d: Mapping, rows_3d: Mapping | None = None
               ) -> tuple[dict, dict]:
    """Rows' estimates scored: rows_2d name → view → ``(frames, 12, 2)`` into name → ``{view:
    score_2d, "all": mean over views}``; rows_3d name → ``(frames, 12, 3)`` into name →
    score_3d."""
    scored_2d = {}
    for name, per_view in rows_2d.items():
        missing = [view for view in setting.views if view not in per_view]
        if missing:
            raise ValueError(f"row {name!r} lacks views {missing}")
        views = {view: score_2d(per_view[view], setting.truth_2d[view])
                 for view in setting.views}
        scored_2d[name] = {**views, "all": _mean_over_views(views)}
    return scored_2d, {name: score_3d(world, setting.truth_3d)
                       for name, world in (rows_3d or {}).items()}


def add_rows(path: Path, setting: Setting, rows_2d: Mapping, *, notes_key: str,
             notes: Mapping, command: str, triangulate: bool = True,
             rows_3d: Mapping | None = None) -> dict:
    """Score more rows (rows_2d name → view → ``(frames, 12, 2)``, rows_3d name → ``(frames,
    12, 3)`` world metres) on ``setting`` and merge them into the results already written at
    ``path`` (rows of the same name replaced, the others kept), with ``dlt of NAME`` for each
    2-D row (``triangulate``), ``notes`` under ``results["notes"][notes_key]``, ``command``
    under ``results["commands"][notes_key]``, and the targets and :func:`beaten_by` of the
    papers' rows recomputed. The file is rewritten atomically. This is how a paper's tracker
    on these detections (:data:`PAPER_ROWS`) joins the table without the other rows being run
    again: a tracker of 3-D skeletons (Ong & Gong's over the four views) gives its row in
    ``rows_3d`` and, through :func:`projected`, in ``rows_2d`` with ``triangulate=False``.

    Returns:
        the merged results.

    Raises:
        FileNotFoundError: no results at ``path`` (run the evaluation first). ValueError:
            they were scored on other frames than ``setting``'s.
    """
    import json

    from jaxtrack._files import write_json_atomically

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no results to add rows to; run python -m "
                                f"jaxtrack.experiments.detections_evaluation --json {path} "
                                f"first")
    results = json.loads(path.read_text())
    if results.get("frames") != [int(i) for i in setting.frame_indices]:
        raise ValueError(f"{path}: its rows were scored on other frames than these detections'; "
                         f"run the whole evaluation again")
    extra_3d = ({f"dlt of {name}": triangulated(setting, per_view)
                 for name, per_view in rows_2d.items()} if triangulate else {})
    extra_3d.update(rows_3d or {})
    scored_2d, scored_3d = score_rows(setting, rows_2d, extra_3d)
    results["rows_2d"].update(scored_2d)
    results["rows_3d"].update(scored_3d)
    results.setdefault("notes", {})[notes_key] = dict(notes)
    results.setdefault("commands", {})[notes_key] = command
    _conclusions(results)
    write_json_atomically(path, results)
    return results


def projected(setting: Setting, world) -> dict:
    """A ``(frames, 12, 3)`` world-metre estimate projected into each view (the views'
    calibrated cameras): view → ``(frames, 12, 2)`` pixels, a 2-D row of a 3-D tracker."""
    from jaxtrack.body._staging import project_numpy

    return {view: project_numpy(camera, np.asarray(world, np.float64))[0]
            for view, camera in zip(setting.views, setting.cameras, strict=True)}


def _conclusions(results: dict) -> None:
    """``targets`` of the SPM filter and ``paper_priors``: each paper's row's scores against
    the SPM filter's with the same fit and the rows that beat it (:func:`beaten_by`)."""
    rows = results["rows_2d"]
    if "condensation random walk" in rows:
        results["targets"] = targets(results)
    papers = {}
    for row in PAPER_ROWS.values():
        if row in rows or row in results["rows_3d"]:
            papers[row] = {"beaten_by": beaten_by(results, row) if row in rows else None,
                           "beaten_by_3d": beaten_by(results, row, three_d=True)}
    if papers:
        results["paper_priors"] = papers


def beaten_by(results: Mapping, row: str, *, three_d: bool = False) -> dict | list:
    """Every other row whose error (% of the torso) is lower than ``row``'s: per view and over
    the views (``"all"``) in 2-D, or (``three_d``) the 3-D rows beating ``row`` (a 3-D row) or
    else ``dlt of ROW``. The row's own smoother and fixed-lag variants are left out."""
    if three_d:
        rows = results["rows_3d"]
        mine = row if row in rows else f"dlt of {row}"
        if mine not in rows:
            return []
        return [name for name, scored in rows.items()
                if not name.startswith(mine) and scored["error_torso"] is not None
                and scored["error_torso"] < rows[mine]["error_torso"]]
    rows = results["rows_2d"]
    if row not in rows:
        raise ValueError(f"the results hold no row {row!r}")
    out = {}
    for view in rows[row]:
        mine = rows[row][view]["error_torso"]
        out[view] = [name for name, scored in rows.items()
                     if not name.startswith(row) and mine is not None
                     and scored[view]["error_torso"] is not None
                     and scored[view]["error_torso"] < mine]
    return out


def triangulated(setting: Setting, per_view: Mapping) -> np.ndarray:
    """A 2-D row's four views triangulated by the DLT, every view weighing 1 (a filtered track
    has no confidence of its own): ``(frames, 12, 3)`` world metres."""
    from jaxtrack.vision.triangulation import triangulate

    return triangulate(np.stack([np.asarray(per_view[view]) for view in setting.views]),
                       setting.cameras)[0]


def targets(results: Mapping, row: str = "condensation random walk") -> dict:
    """The targets for the particle-filter row ``row`` (the filter with the defaults),
    read from :func:`evaluate`'s results: each ``{"value", "target", "met"}``."""
    rows_2d, rows_3d = results["rows_2d"], results["rows_3d"]
    if row not in rows_2d:
        raise ValueError(f"the results hold no row {row!r}: run with the particle filters")
    views = [view for view in rows_2d[row] if view != "all"]
    within = {view: rows_2d[row][view]["within_15"] for view in views}
    butterworth = rows_2d["butterworth"]["all"]["error_torso"]
    out = {"within_15_every_view": {"value": within, "target": ">= 0.95 in every view",
                                    "met": all(value >= 0.95 for value in within.values())},
           "error_against_butterworth": {
               "value": rows_2d[row]["all"]["error_torso"] / butterworth,
               "target": "<= 0.5 (mean error over the views / Butterworth's)"}}
    out["error_against_butterworth"]["met"] = out["error_against_butterworth"]["value"] <= 0.5
    if f"dlt of {row}" in rows_3d:
        ratio = rows_3d[f"dlt of {row}"]["error_mm"] / rows_3d["dlt"]["error_mm"]
        out["3d_against_dlt"] = {"value": ratio, "target": "<= 0.8 (error mm / raw DLT's)",
                                 "met": ratio <= 0.8}
    hand = [name for name in rows_2d if name.startswith("condensation hand-set")]
    if hand:
        per_view = {}
        for view in views:
            best = min(hand, key=lambda name: rows_2d[name][view]["error_torso"])
            per_view[view] = {"fitted": rows_2d[row][view]["error_torso"], "best_hand_set": best,
                              "best_hand_set_error": rows_2d[best][view]["error_torso"]}
            per_view[view]["met"] = per_view[view]["fitted"] <= per_view[view][
                "best_hand_set_error"]
        out["fitted_against_hand_set"] = {
            "value": per_view, "target": "fitted error <= the best hand-set weight's, every view",
            "met": all(record["met"] for record in per_view.values())}
    speed = results.get("notes", {}).get("particle_filters", {}).get("speed")
    if speed:
        out["speed"] = {"value": speed["ms_per_frame"], "target": "<= 5 ms per frame and view",
                        "met": speed["ms_per_frame"] <= 5.0}
    beaten = {}
    for view in (*views, "all"):
        mine = rows_2d[row][view]["error_torso"]
        beaten[view] = [name for name, scored in rows_2d.items()
                        if not name.startswith(TRACKER_PREFIXES) and scored[view]["error_torso"]
                        is not None and scored[view]["error_torso"] < mine]
    out["baselines_beating_the_filter"] = beaten
    out["baselines_beating_the_filter_3d"] = [
        name for name, scored in rows_3d.items()
        if not name.startswith(tuple(f"dlt of {prefix}" for prefix in TRACKER_PREFIXES))
        and f"dlt of {row}" in rows_3d
        and scored["error_mm"] < rows_3d[f"dlt of {row}"]["error_mm"]]
    return out


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
    parser.add_argument("--no-trackers", action="store_true",
                        help="the baselines only, without the particle filters' rows")
    parser.add_argument("--particles", type=int, default=None,
                        help="N of the particle filters' fit and runs (default "
                             "track_detections')")
    parser.add_argument("--iterations", type=int, default=None,
                        help="Adam iterations of each fit (default track_detections')")
    parser.add_argument("--speed-particles", type=int, default=SPEED_PARTICLES,
                        help="N of the timed run (0: none)")
    parser.add_argument("--add", choices=("latent",), default=None,
                        help="instead: run only these rows (latent: Tian et al.'s tracker, "
                             "latent_estimates) and add them to the results already in --json, "
                             "leaving the other rows as they are")
    parser.add_argument("--latent-reach", action="store_true",
                        help="instead: how near the latent tracker's prior comes to the "
                             "reference's own poses in each view (latent_reach); prints a table")
    parser.add_argument("--latent-model", type=Path, default=None,
                        help="the latent tracker's GPLVM prior (default: the bundled one "
                             "jaxtrack track --method latent uses)")
    parser.add_argument("--noise-check", choices=VIEWS, nargs="+", default=None,
                        metavar="VIEW",
                        help="instead: one noise factor against one per SPM component in the "
                             "fit, on these views (noise_check); prints a table")
    parser.add_argument("--filter-check", choices=VIEWS, default=None,
                        help="instead: the hand-set filter on this view given the reference's "
                             "own markers, then MediaPipe's (filter_check); prints a table")
    args = parser.parse_args(argv)
    if not 0 <= args.min_confidence <= 1:
        parser.error(f"--min-confidence must lie in [0, 1], got {args.min_confidence}")
    for option in ("particles", "iterations"):
        value = getattr(args, option)
        if value is not None and value < 1:
            parser.error(f"--{option} must be a positive integer, got {value}")
    if args.speed_particles < 0:
        parser.error(f"--speed-particles must be 0 or more, got {args.speed_particles}")
    if args.json is not None and args.json.suffix != ".json":
        parser.error(f"--json {args.json}: give a .json file name")
    if args.add is not None and (args.json is None or not args.json.is_file()):
        parser.error(f"--add {args.add}: give --json with the results to add to (run without "
                     f"--add first)")
    if args.add is not None and args.no_trackers:
        parser.error("--add runs a tracker's rows; leave --no-trackers out")
    if args.latent_model is not None:
        from jaxtrack.priors.gplvm import GPLVMFormatError
        from jaxtrack.priors.train import load_prior

        try:
            load_prior(args.latent_model)
        except (OSError, GPLVMFormatError, ValueError) as error:
            parser.error(f"--latent-model {args.latent_model}: {' '.join(str(error).split())}")
    from jaxtrack.vision.mediapipe import DetectorUnavailableError

    try:
        with tqdm(total=len(VIEWS), desc="detections", file=sys.stderr) as progress:
            setting = load_setting(args.data, args.detections, progress)
    except (FileNotFoundError, DetectorUnavailableError) as error:
        parser.exit(1, f"{parser.prog}: {' '.join(str(error).split())}\n")
    if args.noise_check is not None:
        print("| view | iterations | step | noise factors | log-evidence | % torso | "
              "within 15 % | largest factors |\n|---|---|---|---|---|---|---|---|")
        for view in args.noise_check:
            for row in noise_check(setting, view):
                print(f"| {view} | {row['iterations']} | {row['step']:g} | {row['noise']} | "
                      f"{row['log_evidence']:.0f} | {_cell(row['error_torso'])} | "
                      f"{_cell(row['within_15'], digits=0)} | "
                      f"{', '.join(f'{v:g}' for v in row['largest_factors'])} |", flush=True)
        return 0
    if args.latent_reach:
        print("the reference's own poses through the latent prior: mu(x) at x = mu^-1(pose) "
              "(Tian et al. eq. 5) and at the x whose mu is nearest the pose\n"
              "| view | eq. 5: error px / % torso / within 15 % | nearest: error px / % torso "
              "/ within 15 % |\n|---|---|---|")
        reach = [latent_reach(setting, model=args.latent_model, objective=objective)
                 for objective in ("posterior", "reconstruction")]
        for view in setting.views:
            print(f"| {view} | " + " | ".join(
                f"{scored[view]['error_px']:.1f} / {_cell(scored[view]['error_torso'])} / "
                f"{_cell(scored[view]['within_15'], digits=0)}" for scored in reach) + " |")
        return 0
    if args.filter_check is not None:
        print(f"{args.filter_check}: the random-walk filter, hand-set density x16, N = 500")
        print("| input | step | swap probability | error px | % torso | within 15 % | "
              "frames left/right exchanged |\n|---|---|---|---|---|---|---|")
        for row in filter_check(setting, args.filter_check):
            print(f"| {row['input']} | {row['step']:g} | {row['swap_probability']:g} | "
                  f"{row['error_px']:.1f} | {_cell(row['error_torso'])} | "
                  f"{_cell(row['within_15'], digits=0)} | {row['left_right_swaps']} |")
        for name, points in (("reference", setting.truth_2d[args.filter_check]),
                             ("mediapipe", setting.detections[args.filter_check][0])):
            steps = walk_steps(points)
            print(f"{name}: frames with a step beyond 3 std of the walk (step 0.03): "
                  f"{_cell(steps['beyond_3_sigma'], digits=0)} %; 95th percentile, std: "
                  + ", ".join(f"{key} {value:.1f}" for key, value in steps["largest"].items()))
        return 0
    started = time.perf_counter()
    options = [f"--{name.replace('_', '-')} {getattr(args, name)}"
               for name in ("particles", "iterations", "latent_model")
               if getattr(args, name) is not None]
    options += ["--no-trackers"] if args.no_trackers else []
    options += [f"--add {args.add}"] if args.add else []
    command = " ".join(["python -m jaxtrack.experiments.detections_evaluation", *options,
                        *([f"--json {args.json}"] if args.json else [])])
    latent = None
    if not args.no_trackers:
        with tqdm(total=len(setting.views), desc="latent tracker", file=sys.stderr) as progress:
            latent = latent_estimates(setting, model=args.latent_model,
                                      particles=args.particles, iterations=args.iterations,
                                      progress=progress)
    if args.add is not None:
        try:
            results = add_rows(args.json, setting, latent[0], notes_key="latent",
                               notes={**latent[1], "seconds_total":
                                      time.perf_counter() - started}, command=command)
        except ValueError as error:
            parser.exit(1, f"{parser.prog}: {' '.join(str(error).split())}\n")
        print(table({"rows_2d": {name: row for name, row in results["rows_2d"].items()
                                 if name in latent[0]},
                     "rows_3d": {f"dlt of {name}": results["rows_3d"][f"dlt of {name}"]
                                 for name in latent[0]}}))
        for row, record in results.get("paper_priors", {}).items():
            print(f"{row} is beaten by: {record['beaten_by']}; in 3-D: "
                  f"{record['beaten_by_3d']}")
        print(f"added to {args.json}")
        return 0
    extra_2d, extra_3d, filters = {}, {}, None
    if not args.no_trackers:
        with tqdm(total=len(setting.views) * len(PRIORS), desc="particle filters",
                  file=sys.stderr) as progress:
            extra_2d, filters = particle_filter_estimates(
                setting, particles=args.particles, iterations=args.iterations,
                speed_particles=args.speed_particles or None, progress=progress)
        extra_2d.update(latent[0])
        extra_3d = {f"dlt of {name}": triangulated(setting, per_view)
                    for name, per_view in extra_2d.items()}
    results = evaluate(setting, extra_2d=extra_2d, extra_3d=extra_3d,
                       min_confidence=args.min_confidence)
    if filters is not None:
        results["notes"]["particle_filters"] = filters
        results["notes"]["latent"] = latent[1]
        _conclusions(results)
    results["seconds"] = time.perf_counter() - started
    results["command"] = command
    print(table(results))
    for view, record in setting.detector.items():
        print(f"{view}: MediaPipe {record['version']} {record['ms_per_frame']:.1f} ms/frame "
              f"(first {record['first_frame_seconds']:.2f} s), "
              f"{record['frames_without_person']} frames without a person, left and right "
              f"exchanged in {results['raw_left_right_swaps'][view]['frames']} (undone: "
              f"{_cell(results['raw_left_right_swaps'][view]['error_torso_undone'])} % torso)")
    for name, record in results.get("targets", {}).items():
        print(f"target {name}: {record}")
    for row, record in results.get("paper_priors", {}).items():
        print(f"{row} is beaten by: {record['beaten_by']}; in 3-D: {record['beaten_by_3d']}")
    if args.json is not None:
        write_json_atomically(args.json, results)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
