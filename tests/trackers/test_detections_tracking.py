"""The image trackers on the normalised detection density: a passer-by crossing is another
explanation, not a pull; bad detections are refused in one line; the error model is learned
from the detections (slow); the three trackers take it times an image likelihood (slow)."""

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.body import SPM_MARKERS
from jaxtrack.experiments.detection_tracking import (
    detection_tracker,
    fit_detection_model,
    smooth_markers,
    track_detections,
)
from jaxtrack.likelihoods.detections import DetectionsFrame, detection_model
from jaxtrack.trackers import track
from jaxtrack.trackers._particles import DetectionLikelihood, detection_observations
from jaxtrack.vision.detections import Detections

M = len(SPM_MARKERS)
SIZE = (320.0, 240.0)
SHAPE = np.array([[0, -8], [0, 0], [0, 9], [0, 22], [-9, 1], [-12, 11], [-13, 20], [-5, 22],
                  [9, 1], [12, 11], [13, 20], [5, 22]], float)
"""An upright upper body facing the camera, neck at the origin, neck–pelvis 22 units."""


def _walker(frames, start, speed, scale=4.0, phase=0.0):
    """``(frames, 12, 2)`` a person walking sideways at ``speed`` px per frame, right wrist
    waving."""
    t = np.arange(frames)
    markers = SHAPE[None] * scale + np.stack([start[0] + speed * t, start[1] + 0 * t],
                                             -1)[:, None]
    markers[:, SPM_MARKERS.index("right_wrist"), 1] -= 5 * scale * np.sin(t / 3 + phase)
    return markers


def _detections(people, noise, seed=0, order_seed=1):
    """A detector's output of ``people`` (each ``(frames, 12, 2)``) with Gaussian noise of
    ``noise`` px, every keypoint found at confidence 0.9, the people listed in a random order
    each frame (a detector keeps no identity)."""
    rng, order = np.random.default_rng(seed), np.random.default_rng(order_seed)
    stacked = np.stack(people, 1) + noise * rng.standard_normal(
        (len(people[0]), len(people), M, 2))
    stacked = np.stack([frame[order.permutation(len(people))] for frame in stacked])
    frames = len(stacked)
    return Detections(stacked, np.full(stacked.shape[:3], 0.9), np.full(frames, len(people)),
                      SPM_MARKERS, "markers", frame_size=SIZE)


def _error(estimate, truth):
    return float(np.mean(np.linalg.norm(np.asarray(estimate) - truth, axis=-1)))


def test_each_tracker_stays_with_its_person_when_the_other_crosses():
    """Two people walk towards each other and cross (frame 12: 25 px apart vertically, one
    smaller), both detected in every frame in a random order; a tracker started on either
    stays with it, 4 px from its person and 20+ px from the other past the crossing: the
    other is another mixture component, not a pull."""
    frames = 16
    ours = _walker(frames, (100, 90), 3.0)
    other = _walker(frames, (170, 115), -3.0, scale=3.5, phase=1.0)
    observations = detection_observations(_detections([ours, other], noise=3.0))
    late = slice(frames - 4, frames)  # past the crossing
    for person, passer_by in ((ours, other), (other, ours)):
        tracker = detection_tracker(person[0], num_particles=128,
                                    detections=detection_model(joint_scales=np.full(M, 0.05)))
        estimate = track(tracker, jr.key(0), observations, person[0], progress=False).markers
        assert _error(estimate[late], person[late]) < 7.0
        assert _error(estimate[late], passer_by[late]) > 18.0


def test_mht_runs_on_the_detections_alone():
    """MHT without an image: the frame's size, which bounds a runaway mode, comes from the
    detections (it read the image's shape and failed without one); it stays with its person
    past the crossing."""
    from jaxtrack.trackers import mht_tracker

    frames = 16
    ours = _walker(frames, (100, 90), 3.0)
    other = _walker(frames, (170, 115), -3.0, scale=3.5, phase=1.0)
    observations = detection_observations(_detections([ours, other], noise=3.0))
    condensation = detection_tracker(ours[0], num_particles=8,
                                     detections=detection_model(joint_scales=np.full(M, 0.05)))
    tracker = mht_tracker(condensation.template, likelihood=condensation.likelihood,
                          step_std=condensation.dynamics.noise_std, num_modes=3, max_steps=3)
    estimate = track(tracker, jr.key(0), observations, ours[0], progress=False).markers
    late = slice(frames - 4, frames)
    assert np.all(np.isfinite(estimate))
    assert _error(estimate[late], ours[late]) < 0.5 * _error(estimate[late], other[late])


def _one_line_error(call, *words):
    with pytest.raises(ValueError) as error:
        call()
    message = str(error.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message
    return message


def test_bad_detections_are_refused_in_one_line():
    ours = _walker(4, (80, 90), 2.0)
    good = _detections([ours], noise=1.0)
    frames = detection_observations(good).detections
    points = np.asarray(frames.points).copy()
    points[2, 0, 3] = np.nan
    _one_line_error(lambda: detection_observations(DetectionsFrame(
        points, frames.confidence, frames.num_people, frames.image_size)), "frame 2",
        "non-finite")
    _one_line_error(lambda: detection_observations(DetectionsFrame(
        np.asarray(frames.points)[:, :, :5], np.asarray(frames.confidence)[:, :, :5],
        frames.num_people, frames.image_size)), "points must be")
    _one_line_error(lambda: detection_observations(DetectionsFrame(
        frames.points, np.asarray(frames.confidence)[:3], frames.num_people,
        frames.image_size)), "confidence must be")
    missing = Detections(good.points, good.confidence, good.people, SPM_MARKERS, "markers",
                         frame_size=SIZE, frame_ids=np.array([0, 1, 4, 5]))
    _one_line_error(lambda: detection_observations(missing), "missing", "1", "4")
    unsized = Detections(good.points, good.confidence, good.people, SPM_MARKERS, "markers")
    _one_line_error(lambda: detection_observations(unsized), "frame_size")
    _one_line_error(lambda: detection_observations(good.points), "Detections")
    few = Detections(good.points[:, :, :4], good.confidence[:, :, :4], good.people,
                     SPM_MARKERS[:4], "markers", frame_size=SIZE)
    _one_line_error(lambda: detection_observations(few), "not among")
    _one_line_error(lambda: DetectionLikelihood(detection_model(("neck", "pelvis"))),
                    "12 markers")
    _one_line_error(lambda: track_detections(good, smoothing="sometimes"), "smoothing")


@pytest.mark.slow
def test_a_fit_recovers_the_detectors_noise_scale():
    """Detections with 6 px Gaussian noise: the fitted spread σ_k = √((f_k T)² + σ₀²) at the
    true torso, averaged over the markers, is within 20 % of 6 px (from a start of 2.3 px), the
    outlier rate falls, and the log-evidence rises."""
    frames, noise = 30, 6.0
    ours = _walker(frames, (80, 90), 2.0)
    observations = detection_observations(_detections([ours], noise=noise))
    start = detection_model(joint_scales=np.full(M, 0.02), pixel_noise=2.0, outlier_rate=0.2)
    tracker = detection_tracker(ours[0], detections=start, num_particles=256)
    fitted, fit = fit_detection_model(tracker, jr.key(1), observations, ours[0], iterations=60)
    model = fit.detections
    torso = np.linalg.norm(ours[0, 1] - ours[0, 3])
    sigma = np.sqrt((np.asarray(model.joint_scales) * torso) ** 2
                    + float(model.pixel_noise) ** 2)
    assert abs(np.mean(sigma) / noise - 1) < 0.2, sigma
    assert float(model.outlier_rate) < 0.1
    assert np.mean(fit.log_evidence[-5:]) > fit.log_evidence[0] + 100
    assert isinstance(fitted.likelihood, DetectionLikelihood)


@pytest.mark.slow  # two fits compile: about 30 s
def test_a_per_component_noise_fit_learns_one_factor_per_component():
    """fit_noise="per_component": one factor per SPM component of the walk's noise, applied
    component by component to the tracker; the scalar fit's record is unchanged in kind; any
    other value is refused in one line."""
    ours = _walker(8, (80, 90), 2.0)
    observations = detection_observations(_detections([ours], noise=3.0))
    tracker = detection_tracker(ours[0], num_particles=16)
    fitted, fit = fit_detection_model(tracker, jr.key(1), observations, ours[0], iterations=2,
                                      learning_rate=0.3, fit_noise="per_component")
    noise = np.asarray(tracker.dynamics.noise_std)
    assert fit.noise_factors.shape == noise.shape and len(set(fit.noise_factors)) > 1
    np.testing.assert_allclose(np.asarray(fitted.dynamics.noise_std),
                               noise * fit.noise_factors, rtol=1e-5)
    assert fit.noise_factor == pytest.approx(np.exp(np.mean(np.log(fit.noise_factors))))
    _, scalar = fit_detection_model(tracker, jr.key(1), observations, ours[0], iterations=2)
    assert scalar.noise_factors is None and isinstance(scalar.noise_factor, float)
    _one_line_error(lambda: fit_detection_model(tracker, jr.key(1), observations, ours[0],
                                                fit_noise="each"), "fit_noise must be")


@pytest.mark.slow
def test_the_smoothers_use_later_frames():
    """Ancestry smoothing and fixed-lag smoothing both run through the engine and give marker
    tracks as close to the truth as the filter's (here, within 25 %)."""
    ours = _walker(16, (80, 90), 3.0)
    observations = detection_observations(_detections([ours], noise=4.0))
    tracker = detection_tracker(ours[0], num_particles=256)
    filtered = track(tracker, jr.key(0), observations, ours[0], progress=False).markers
    whole = smooth_markers(tracker, jr.key(0), observations, ours[0])
    lagged = smooth_markers(tracker, jr.key(0), observations, ours[0], lag=3)
    assert whole.shape == lagged.shape == (16, M, 2)
    for estimate in (whole, lagged):
        assert _error(estimate, ours) < 1.25 * _error(filtered, ours)


@pytest.mark.slow
def test_latent_condensation_and_mht_take_the_density_times_the_image(prior, sequence):
    """Each image tracker runs with the detection density times the limb/edge likelihood, the
    detections (truth + 3 px noise and a passer-by) riding beside the frames."""
    from jaxtrack.body import spm_initial_state
    from jaxtrack.trackers import (
        Engine,
        Likelihood,
        condensation_tracker,
        latent_tracker,
        mht_tracker,
    )

    truth = np.asarray(sequence.truth)
    other = truth + np.array([120.0, 10.0])
    detections = _detections([truth, other], noise=3.0)
    height, width = np.shape(sequence.frames)[1:3]
    detections = Detections(detections.points, detections.confidence, detections.people,
                            SPM_MARKERS, "markers", frame_size=(width, height))
    likelihood = DetectionLikelihood(detection_model(), image=Likelihood())
    observations = detection_observations(detections, grey=np.asarray(sequence.frames),
                                          likelihood=likelihood.image)
    states = np.asarray(spm_initial_state(jnp.asarray(truth), prior.template))
    for tracker in (latent_tracker(prior.model, prior.template, engine=Engine(32),
                                   likelihood=likelihood, refinement=None),
                    condensation_tracker(prior.template, states, engine=Engine(32),
                                         likelihood=likelihood),
                    mht_tracker(prior.template, states, likelihood=likelihood, num_modes=3,
                                max_steps=3)):
        result = track(tracker, jr.key(0), observations, truth[0], progress=False)
        assert np.all(np.isfinite(result.markers))
        assert _error(result.markers, truth) < 0.5 * _error(result.markers, other)
