"""Following one person through a per-frame detector's output, with the detection density's
error model learned from the video itself.

- :func:`fit_detection_model`: the density's per-marker scales f_k, its pixel floor σ₀, its
  outlier rate ε and a factor on the tracker's dynamics noise, by gradient ascent (Adam) of the
  particle filter's log-evidence log p̂(D_{0:T} | θ) through the tracker's own state-space
  model (``jaxtrack.smc.fit_log_evidence``, the ``StopGradient`` estimator). Only normalised
  densities are learned so (the detection density and the dynamics): the image likelihoods are
  unnormalised energies whose evidence has no maximum in their sharpness.
- :func:`smooth_markers`: offline tracks by the engine's whole-sequence smoother (ancestry
  tracing) or a fixed-lag one for streaming.
- :func:`track_detections`: detections in, ``(frames, markers, 2)`` estimates out: builds a
  tracker for the person detected in frame 0, fits its error model (``fit=True``), tracks or
  smooths. ``docs/detections.md``, "Tracking with detections", "Learning the error model".
- :class:`ChunkDetections` and :func:`fit_on_keypoints`: what ``jaxtrack track --keypoints``
  and ``--detector`` run on a video file: an image tracker whose likelihood is the detection
  density (times its image likelihood) fed one person's keypoints a video chunk at a time by
  :func:`jaxtrack.experiments.pipeline.track_video`, its density fitted first on the same
  keypoints.
"""

from __future__ import annotations

from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from jaxtrack import smc
from jaxtrack.body import SPM_MARKERS, build_template, spm_initial_state
from jaxtrack.likelihoods.detections import DetectionModel, DetectionsFrame, detection_model
from jaxtrack.priors.dynamics import AR2Dynamics, default_noise_floor
from jaxtrack.trackers import CondensationTracker, Engine, Tracker, VideoChunk, track
from jaxtrack.trackers._particles import (
    DetectionLikelihood,
    detection_observations,
    device_observation,
)

__all__ = ["DEFAULT_STEP", "ChunkDetections", "DetectionFit", "detection_tracker",
           "fit_detection_model", "fit_on_keypoints", "fit_record", "initial_pose_of",
           "keypoint_frames", "smooth_markers", "track_detections"]

DEFAULT_STEP = 0.03
"""The random walk's starting step per frame in :func:`detection_tracker`: 0.03 in log scale,
angles (radians) and log lengths, 0.03 torso lengths in the translation; a start, which
:func:`fit_detection_model` scales to the video."""

# where the dynamics' noise lies in a tracker's model, and in the tracker (CONDENSATION /
# random walk, the latent tracker); the fit scales it by one learned factor
_NOISE_PATHS = (
    (lambda model: model.dynamics.noise_std, lambda tracker: tracker.dynamics.noise_std),
    (lambda model: model.walk.latent_std, lambda tracker: tracker.latent_std),
)


@dataclass(frozen=True)
class DetectionFit:
    """What :func:`fit_detection_model` learned.

    Attributes:
        detections: the fitted :class:`~jaxtrack.likelihoods.detections.DetectionModel`.
        noise_factor: the factor on the dynamics' noise (1 without ``fit_noise``; with
            ``fit_noise="per_component"`` the geometric mean of ``noise_factors``).
        log_evidence: ``(iterations,)`` the filter's log-evidence estimate at each iteration.
        seconds: wall time of the iterations (compilation excluded).
        compile_seconds: time to compile one iteration.
        num_particles: N per filter run.
    """

    detections: DetectionModel
    noise_factor: float
    log_evidence: np.ndarray
    seconds: float
    compile_seconds: float
    num_particles: int
    noise_factors: np.ndarray | None = None
    """With ``fit_noise="per_component"``: the factor on each component of the noise."""


def _logit(p):
    return jnp.log(p) - jnp.log1p(-p)


def _noise_paths(model, tracker):
    for of_model, of_tracker in _NOISE_PATHS:
        try:
            of_model(model), of_tracker(tracker)
        except AttributeError:
            continue
        return of_model, of_tracker
    raise ValueError(f"the {type(tracker).__name__}'s dynamics noise is not one this fit knows "
                     f"(CONDENSATION's dynamics.noise_std, the latent tracker's latent_std): "
                     f"give fit_noise=False")


def fit_detection_model(tracker, key, observations, initial_pose, *, iterations: int = 40,
                        learning_rate: float = 0.05, num_particles: int | None = None,
                        fit_noise: bool | str = True) -> tuple[object, DetectionFit]:
    """Learn the detection density's scales f_k and σ₀, its outlier rate ε and (``fit_noise``)
    a factor on the dynamics' noise for one video, by Adam ascent of the log-evidence of the
    tracker's particle filter (module docstring).

    Args:
        tracker: a CONDENSATION or latent tracker whose likelihood is a
            :class:`~jaxtrack.trackers._particles.DetectionLikelihood`.
        key: PRNG key.
        observations: the video's observations (:func:`~jaxtrack.trackers._particles.
            detection_observations`), a leading ``time`` axis on every leaf.
        initial_pose: ``(12, 2)`` frame 0's pose.
        iterations: Adam steps (one filter run forward and backward each).
        learning_rate: Adam's step in the unconstrained parameters (log f_k, log σ₀,
            logit ε, log factor).
        num_particles: N per filter run; default the tracker's.
        fit_noise: also learn the dynamics' noise factor; ``"per_component"``: one factor
            per component of the noise (e.g. each of the 25 SPM state's), so that the fit can
            widen the walk of the fast-moving parts (the forearms) alone.

    Returns:
        ``(tracker, fit)``: the tracker with the fitted density (and noise), and a
        :class:`DetectionFit`.
    """
    likelihood = getattr(tracker, "likelihood", None)
    if not isinstance(likelihood, DetectionLikelihood):
        raise ValueError(f"fit_detection_model learns a DetectionLikelihood's parameters; the "
                         f"tracker's likelihood is {type(likelihood).__name__}")
    key_start, key_fit = jr.split(key)
    first = jax.tree.map(lambda leaf: leaf[0], observations)
    state = tracker.start(key_start, first, initial_pose)
    model = getattr(state, "model", None)
    if not isinstance(model, smc.StateSpaceModel):
        raise ValueError(f"the {type(tracker).__name__} keeps no particle filter whose "
                         f"log-evidence could be ascended (MHT keeps refined modes): fit with a "
                         f"CONDENSATION or latent tracker and give the fitted density to it")
    if fit_noise not in (True, False, "per_component"):
        raise ValueError(f"fit_noise must be True, False or 'per_component', got {fit_noise!r}")
    of_model = of_tracker = None
    if fit_noise:
        of_model, of_tracker = _noise_paths(model, tracker)
    base = model.templates.params
    dtype = base.joint_scales.dtype
    noise_shape = jnp.shape(of_model(model)) if fit_noise == "per_component" else ()
    start = {"joint_scales": jnp.log(base.joint_scales), "pixel_noise": jnp.log(base.pixel_noise),
             "outlier_rate": _logit(base.outlier_rate),
             "noise": jnp.zeros(noise_shape, dtype)}

    def density(params) -> DetectionModel:
        return eqx.tree_at(lambda d: (d.joint_scales, d.pixel_noise, d.outlier_rate), base,
                           (jnp.exp(params["joint_scales"]), jnp.exp(params["pixel_noise"]),
                            jax.nn.sigmoid(params["outlier_rate"])))

    def build(params):
        built = eqx.tree_at(lambda m: m.templates.params, model, density(params))
        if fit_noise:
            built = eqx.tree_at(of_model, built, of_model(model) * jnp.exp(params["noise"]))
        return built

    engine = getattr(tracker, "engine", None)
    particles = num_particles or tracker.num_particles
    result = smc.fit_log_evidence(
        key_fit, build, start, device_observation(observations, dtype), particles,
        iterations=iterations, learning_rate=learning_rate,
        ess_threshold=getattr(engine, "ess_threshold", 1.0))
    fitted = density(result.params)
    factors = np.exp(np.asarray(result.params["noise"], np.float64)) if fit_noise else None
    new = eqx.tree_at(lambda t: t.likelihood, tracker,
                      DetectionLikelihood(fitted, likelihood.image))
    if fit_noise:
        new = eqx.tree_at(of_tracker, new, of_tracker(tracker) * jnp.asarray(factors, dtype))
    factor = float(np.exp(np.mean(np.log(factors)))) if fit_noise else 1.0
    return new, DetectionFit(fitted, factor, np.asarray(result.log_evidence), result.seconds,
                             result.compile_seconds, particles,
                             factors if fit_noise == "per_component" else None)


def smooth_markers(tracker, key, observations, initial_pose, *, lag: int | None = None,
                   num_particles: int | None = None) -> np.ndarray:
    """Offline markers of every frame from the engine's smoother over the tracker's filter.

    Args:
        tracker: a CONDENSATION or latent tracker (a particle filter: ``state.model`` is a
            ``jaxtrack.smc.StateSpaceModel`` with ``markers_of``).
        key: PRNG key.
        observations: as :func:`fit_detection_model`.
        initial_pose: ``(12, 2)`` frame 0's pose.
        lag: None: the whole-sequence smoother (``smc.trace_ancestry``: each frame's markers
            read from the final particles' ancestry with the final weights); an int L: the
            fixed-lag smoother (``smc.fixed_lag_ancestry``: frame t from frame t + L).
        num_particles: N; default the tracker's.

    Returns:
        ``(time, 12, 2)`` the weighted mean of each frame's particles' markers.
    """
    key_start, key_run = jr.split(key)
    state = tracker.start(key_start, jax.tree.map(lambda leaf: leaf[0], observations),
                          initial_pose)
    model = getattr(state, "model", None)
    if not isinstance(model, smc.StateSpaceModel):
        raise ValueError(f"the {type(tracker).__name__} keeps no particle history to smooth "
                         f"(MHT keeps refined modes): smooth with a CONDENSATION or latent "
                         f"tracker")
    dtype = jax.tree.leaves(model.templates.params)[0].dtype
    engine = getattr(tracker, "engine", None)
    result = smc.run(key_run, model, device_observation(observations, dtype),
                     num_particles or tracker.num_particles, keep_history=True,
                     ess_threshold=getattr(engine, "ess_threshold", 1.0))
    return np.asarray(_smoothed(model, result, lag))


@eqx.filter_jit
def _smoothed(model, result, lag):
    markers = jax.vmap(jax.vmap(model.markers_of))
    if lag is None:
        paths = smc.trace_ancestry(result)
        weights = jax.nn.softmax(paths.log_weights)
        return jnp.einsum("p,tpmc->tmc", weights, markers(paths.paths))
    lagged = smc.fixed_lag_ancestry(result, lag)
    weights = jax.nn.softmax(lagged.log_weights, axis=-1)
    return jnp.einsum("tp,tpmc->tmc", weights, markers(lagged.particles))


def initial_pose_of(frames, person: int | None = None) -> np.ndarray:
    """Frame 0's pose, ``(12, 2)``: the detected person (``person``, or the one with the
    largest summed confidence) whose 12 markers were all found there."""
    points = np.asarray(frames.points)[0]
    confidence = np.asarray(frames.confidence)[0]
    count = int(np.asarray(frames.num_people)[0])
    complete = [j for j in range(count) if np.all(confidence[j] > 0)]
    if person is None:
        if not complete:
            raise ValueError("no person detected in frame 0 has all 12 markers: give "
                             "initial_pose=(12, 2) pixels")
        person = max(complete, key=lambda j: confidence[j].sum())
    elif person not in complete:
        raise ValueError(f"person {person} is not detected in frame 0 with all 12 markers "
                         f"(complete: {complete}); give initial_pose=")
    return points[person].astype(np.float64)


def detection_tracker(initial_pose, *, detections: DetectionModel | None = None,
                      num_particles: int = 500, step: float = DEFAULT_STEP,
                      dtype=jnp.float32) -> CondensationTracker:
    """CONDENSATION in the 25-d SPM state with a random walk of ``step`` (:data:`DEFAULT_STEP`)
    and the detection density alone, its SPM template the pose ``initial_pose`` itself (a
    tracker for one video, built from its first frame)."""
    pose = np.asarray(initial_pose, np.float64)
    if pose.shape != (len(SPM_MARKERS), 2) or not np.all(np.isfinite(pose)):
        raise ValueError(f"initial_pose must be ({len(SPM_MARKERS)}, 2) finite pixels, got "
                         f"shape {pose.shape}")
    template = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), build_template(pose[None]))
    state = np.asarray(spm_initial_state(jnp.asarray(pose), template), np.float64)
    noise = default_noise_floor(float(np.exp(state[0])), relative=step)
    ones = jnp.ones(noise.shape, dtype)
    dynamics = AR2Dynamics(first_coefficients=ones, second_coefficients=0 * ones,
                           offset=0 * ones, noise_std=jnp.asarray(noise, dtype))
    return CondensationTracker(
        dynamics=dynamics, template=template,
        likelihood=DetectionLikelihood(detections or detection_model(dtype=dtype)),
        engine=Engine(int(num_particles)))


def track_detections(detections, *, method: str = "condensation", fit: bool = True,
                     smoothing: str | int | None = None, initial_pose=None,
                     person: int | None = None, num_particles: int = 500,
                     iterations: int = 40, learning_rate: float = 0.05, tracker=None,
                     key=None, frame_size: tuple[float, float] | None = None,
                     return_fit: bool = False):
    """Follow one person through a detector's output: ``(frames, 12, 2)`` estimates.

    Args:
        detections: a :class:`jaxtrack.vision.detections.Detections` (one view, consecutive
            frames, markers including the tracker's 12).
        method: ``"condensation"`` (a random walk in the SPM state, :func:`detection_tracker`),
            or ``"tracker"`` with ``tracker=`` any CONDENSATION or latent tracker whose
            likelihood is a ``DetectionLikelihood``.
        fit: learn the error model and the dynamics' noise from these detections first
            (:func:`fit_detection_model`).
        smoothing: None: the filter's estimate per frame (``jaxtrack.trackers.track``);
            ``"ancestry"``: the whole-sequence smoother; an int L: the fixed-lag smoother.
        initial_pose: ``(12, 2)`` frame 0's pose; default the person of frame 0
            (:func:`initial_pose_of`, ``person``).
        num_particles: N of the filter (and of the fit).
        iterations, learning_rate: the fit's (:func:`fit_detection_model`).
        key: PRNG key (default ``jax.random.key(0)``).
        frame_size: ``(width, height)`` where the detections do not say.
        return_fit: also return the :class:`DetectionFit` (None without ``fit``).

    Returns:
        ``(frames, 12, 2)`` pixels in ``SPM_MARKERS`` order (and the fit, with ``return_fit``).
    """
    if method not in ("condensation", "tracker"):
        raise ValueError(f"method must be 'condensation' or 'tracker', got {method!r}")
    if smoothing is not None and smoothing != "ancestry" and not (
            isinstance(smoothing, int) and smoothing >= 0):
        raise ValueError(f"smoothing must be None, 'ancestry' or a lag >= 0, got {smoothing!r}")
    key = jr.key(0) if key is None else key
    observations = detection_observations(detections, frame_size=frame_size)
    if initial_pose is None:
        initial_pose = initial_pose_of(observations.detections, person)
    if method == "tracker":
        if tracker is None:
            raise ValueError("method='tracker' needs tracker=")
    else:
        tracker = detection_tracker(initial_pose, num_particles=num_particles)
    key_fit, key_track = jr.split(key)
    result = None
    if fit:
        tracker, result = fit_detection_model(tracker, key_fit, observations, initial_pose,
                                              iterations=iterations,
                                              learning_rate=learning_rate)
    if smoothing is None:
        estimates = track(tracker, key_track, observations, initial_pose,
                          progress=False).markers
    else:
        estimates = smooth_markers(tracker, key_track, observations, initial_pose,
                                   lag=None if smoothing == "ancestry" else smoothing)
    estimates = np.asarray(estimates, np.float64)
    return (estimates, result) if return_fit else estimates


def keypoint_frames(points, confidence, frame_size: tuple[float, float]) -> DetectionsFrame:
    """One person's keypoints as a sequence's :class:`DetectionsFrame` (one person per frame,
    none where no keypoint was found), as the detection density reads them.

    Args:
        points: ``(time, 12, 2)`` pixels in ``SPM_MARKERS`` order, NaN where not found.
        confidence: ``(time, 12)`` in ``[0, 1]``, 0 where not found.
        frame_size: ``(width, height)`` of the frames the points are in.

    Keypoints outside ``[−½, W − ½] × [−½, H − ½]`` are not found (the density's support, as
    :func:`jaxtrack.likelihoods.detections_frames` takes them)."""
    points = np.asarray(points, np.float64)
    confidence = np.clip(np.nan_to_num(np.asarray(confidence, np.float64)), 0.0, 1.0)
    width, height = (float(value) for value in frame_size)
    inside = np.all(np.isfinite(points), -1) & (points[..., 0] >= -0.5) & \
        (points[..., 0] <= width - 0.5) & (points[..., 1] >= -0.5) & \
        (points[..., 1] <= height - 0.5)
    found = inside & (confidence > 0)
    return DetectionsFrame(np.where(found[..., None], points, 0.0)[:, None],
                           np.where(found, confidence, 0.0)[:, None],
                           found.any(-1).astype(np.int32),
                           np.broadcast_to(np.array([width, height]), (len(points), 2)))


class ChunkDetections(Tracker):
    """An image tracker whose likelihood is a :class:`DetectionLikelihood`, reading the
    detections from a video chunk's keypoints (one person, ``VideoChunk.keypoints``), so that
    :func:`jaxtrack.experiments.pipeline.track_video` runs it on a video file as it runs any
    tracker. Everything else is the wrapped tracker's.

    Attributes:
        tracker: the latent, CONDENSATION or MHT tracker.
        frame_size: ``(width, height)`` of the tracked frames (the density's outlier area and
            support).
    """

    tracker: Tracker
    frame_size: tuple[float, float] = eqx.field(static=True)

    def __check_init__(self):
        if not isinstance(getattr(self.tracker, "likelihood", None), DetectionLikelihood):
            raise ValueError("ChunkDetections wraps a tracker whose likelihood is a "
                             "DetectionLikelihood")

    @property
    def likelihood(self) -> DetectionLikelihood:
        return self.tracker.likelihood

    @property
    def reads(self) -> tuple[str, ...]:
        return tuple(name for name in self.tracker.reads if name != "keypoints") + (
            "keypoints",)

    def observe(self, chunk: VideoChunk, out=None):
        if chunk.keypoints is None:
            raise ValueError("the detection density reads a detector's keypoints: give "
                             "keypoints=...")
        frames = keypoint_frames(*chunk.keypoints, self.frame_size)
        image = self.likelihood.image
        if image is None:
            return detection_observations(frames)
        return detection_observations(frames, grey=chunk.grey, likelihood=image,
                                      masks=chunk.masks)

    @property
    def num_particles(self) -> int:
        return self.tracker.num_particles

    def start(self, key, first_frame, initial_pose):
        return self.tracker.start(key, first_frame, initial_pose)

    def first_estimate(self, state):
        return self.tracker.first_estimate(state)

    def update(self, key, state, frame):
        return self.tracker.update(key, state, frame)

    def options(self) -> dict:
        return self.tracker.options()

    def smooth(self, estimates):
        return self.tracker.smooth(estimates)


def fit_on_keypoints(tracker, key, points, confidence, frame_size: tuple[float, float],
                     initial_pose, *, iterations: int, num_particles: int | None = None,
                     learning_rate: float = 0.05, fitting_tracker=None
                     ) -> tuple[object, DetectionFit]:
    """Fit a tracker's detection density (and, for a particle filter, its dynamics' noise) on
    one person's keypoints (:func:`fit_detection_model` on the detections alone: the image
    likelihood, unnormalised, is not learned so), and return the tracker with the fitted
    density, its image likelihood kept.

    Args:
        tracker: a latent, CONDENSATION or MHT tracker whose likelihood is a
            :class:`DetectionLikelihood`.
        key: PRNG key.
        points, confidence: ``(time, 12, 2)`` and ``(time, 12)`` the frames tracked, in the
            tracked frames' pixels (:func:`keypoint_frames`).
        frame_size: ``(width, height)`` of those frames.
        initial_pose: ``(12, 2)`` the first frame's pose, in the same pixels.
        iterations, learning_rate: Adam's steps and step size.
        num_particles: N per filter run of the fit (default the tracker's).
        fitting_tracker: the particle filter to fit with where ``tracker`` keeps none (MHT):
            its density is fitted (not its noise) and handed to ``tracker``.

    Returns:
        ``(tracker, fit)``.
    """
    likelihood = tracker.likelihood
    if not isinstance(likelihood, DetectionLikelihood):
        raise ValueError(f"fit_on_keypoints fits a DetectionLikelihood; the tracker's "
                         f"likelihood is {type(likelihood).__name__}")
    alone = DetectionLikelihood(likelihood.detections)
    fitter = tracker if fitting_tracker is None else fitting_tracker
    fitter = eqx.tree_at(lambda t: t.likelihood, fitter, alone)
    observations = detection_observations(keypoint_frames(points, confidence, frame_size))
    fitted, fit = fit_detection_model(fitter, key, observations, initial_pose,
                                      iterations=iterations, num_particles=num_particles,
                                      learning_rate=learning_rate,
                                      fit_noise=fitting_tracker is None)
    base = tracker if fitting_tracker is not None else fitted
    return eqx.tree_at(lambda t: t.likelihood, base,
                       DetectionLikelihood(fit.detections, likelihood.image)), fit


def fit_record(fit: DetectionFit, hand_set: DetectionModel) -> dict:
    """``track.json``'s record of a fit: the fitted values beside the hand-set ones, and its
    cost."""
    def values(model: DetectionModel) -> dict:
        scales = np.asarray(model.joint_scales, np.float64)
        return {"joint_scales": dict(zip(SPM_MARKERS, np.round(scales, 5).tolist(),
                                         strict=True)),
                "pixel_noise": round(float(model.pixel_noise), 4),
                "outlier_rate": round(float(model.outlier_rate), 5),
                "swap_probability": float(model.swap_probability),
                "absent_probability": float(model.absent_probability)}

    fitted, given = values(fit.detections), values(hand_set)
    fitted["noise_factor"], given["noise_factor"] = round(fit.noise_factor, 4), 1.0
    evidence = np.asarray(fit.log_evidence, np.float64)
    return {"fitted": fitted, "hand_set": given,
            "iterations": int(evidence.size), "particles": int(fit.num_particles),
            "seconds": round(fit.seconds, 3), "compile_seconds": round(fit.compile_seconds, 3),
            "log_evidence_first": float(evidence[0]), "log_evidence_final": float(evidence[-1]),
            "learned": "the detection density's f_k, sigma0, outlier rate and the dynamics' "
                       "noise factor, by Adam ascent of the filter's log-evidence on the "
                       "detections alone (jaxtrack.experiments.detection_tracking)"}


def _pose2sim_view(setting, view: str, frame_size: tuple[float, float]):
    """One view of :mod:`jaxtrack.experiments.detections_evaluation`'s setting as
    :class:`~jaxtrack.vision.detections.Detections` (one person, or none where not found)."""
    from jaxtrack.vision.detections import Detections

    points, confidence = setting.detections[view]
    confidence = np.where(np.all(np.isfinite(points), -1), confidence, 0.0)
    people = (confidence > 0).any(-1).astype(int)
    return Detections(points[:, None], confidence[:, None], people, SPM_MARKERS, "markers",
                      frame_size=frame_size, frame_ids=np.asarray(setting.frame_indices),
                      source=f"{view} detections")


def main(argv: list[str] | None = None) -> int:
    """Fit, track and smooth the Pose2Sim demo's detections per view; print the fit's cost and
    each estimate's score against the triangulated reference.

        python -m jaxtrack.experiments.detection_tracking --views cam01 --particles 1000
    """
    import argparse
    import time

    from jaxtrack.experiments.detections_evaluation import VIEWS, load_setting, score_2d

    parser = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    parser.add_argument("--views", nargs="+", default=list(VIEWS))
    parser.add_argument("--particles", type=int, default=1000)
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--learning-rate", type=float, default=0.05)
    parser.add_argument("--lag", type=int, default=5)
    parser.add_argument("--frame-size", type=float, nargs=2, default=(1080.0, 1920.0))
    args = parser.parse_args(argv)
    setting = load_setting()
    print(f"{len(setting.frame_indices)} frames per view, N = {args.particles}, "
          f"{args.iterations} Adam iterations, fixed lag {args.lag}")
    for view in args.views:
        detections = _pose2sim_view(setting, view, tuple(args.frame_size))
        observations = detection_observations(detections)
        pose = initial_pose_of(observations.detections)
        truth = setting.truth_2d[view]
        tracker = detection_tracker(pose, num_particles=args.particles)
        rows = {"detections": setting.detections[view][0]}
        seconds = {}
        tick = time.perf_counter()
        rows["filter, unfitted"] = track(tracker, jr.key(1), observations, pose,
                                         progress=False).markers
        seconds["filter, unfitted"] = time.perf_counter() - tick
        fitted, fit = fit_detection_model(tracker, jr.key(0), observations, pose,
                                          iterations=args.iterations,
                                          learning_rate=args.learning_rate)
        model = fit.detections
        print(f"{view}: fit {fit.seconds:.1f} s for {args.iterations} iterations "
              f"({fit.seconds / args.iterations:.2f} s each) + {fit.compile_seconds:.1f} s "
              f"compiling; log-evidence {fit.log_evidence[0]:.1f} -> "
              f"{np.mean(fit.log_evidence[-5:]):.1f}; sigma0 {float(model.pixel_noise):.2f} px, "
              f"outlier rate {float(model.outlier_rate):.3f}, noise x{fit.noise_factor:.2f}, "
              f"f_k {np.round(np.asarray(model.joint_scales), 3).tolist()}")
        for name, lag in (("filter", "filter"), ("smoother (ancestry)", None),
                          (f"fixed lag {args.lag}", args.lag)):
            tick = time.perf_counter()
            if lag == "filter":
                rows[name] = track(fitted, jr.key(1), observations, pose,
                                   progress=False).markers
            else:
                rows[name] = smooth_markers(fitted, jr.key(1), observations, pose, lag=lag)
            seconds[name] = time.perf_counter() - tick
        for name, estimate in rows.items():
            score = score_2d(estimate, truth)
            jitter = np.nanmean(np.linalg.norm(np.diff(np.asarray(estimate, float), 2, axis=0),
                                               axis=-1))
            timing = f", {seconds[name]:.1f} s (with compiling)" if name in seconds else ""
            print(f"  {name:22s} error {score['error_px']:.1f} px "
                  f"({100 * score['error_torso']:.1f} % torso), within 15 % "
                  f"{100 * score['within_15']:.0f} %, acceleration {jitter:.2f} px/frame²"
                  f"{timing}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
