"""The detection density as computed (flat per-pose arrays, the truncated mass once per marker
from two erfc tails, the swapped order summed over permuted detections) against the
straightforward transcription of its equations: the same values, gradients, EM residuals and
particle filter, within float rounding."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from jax.scipy.special import log_ndtr

from jaxtrack import smc
from jaxtrack.body import SPM_MARKERS
from jaxtrack.experiments.detection_tracking import detection_tracker
from jaxtrack.likelihoods import DetectionsFrame, detection_model
from jaxtrack.likelihoods.detections import (
    _FAR_TAIL,
    DetectionTemplates,
    em_residuals,
    log_density,
    swap_order,
)
from jaxtrack.trackers._particles import detection_observations, device_observation

M = len(SPM_MARKERS)
SIZE = (640.0, 480.0)


def _reference_log_mass(lower, upper):
    """log(Φ(upper) − Φ(lower)), reflected into the lower tail, from ``log_ndtr`` alone."""
    flip = lower > 0
    low, high = jnp.where(flip, -upper, lower), jnp.where(flip, -lower, upper)
    log_high = log_ndtr(high)
    x = log_ndtr(low) - log_high                                     # log(1 − eˣ), x < 0
    near = x > -np.log(2.0)
    safe_near, safe_far = jnp.where(near, x, -1.0), jnp.where(near, -1.0, x)
    return log_high + jnp.where(near, jnp.log(-jnp.expm1(safe_near)),
                                jnp.log1p(-jnp.exp(safe_far)))


def _reference_components(pose, frame, params):
    """The module docstring's equations, one order, person and keypoint at a time."""
    dtype = jnp.result_type(pose, frame.points, params.joint_scales)
    pose = pose.astype(dtype)
    neck, pelvis = params.spine
    torso = jnp.sqrt(jnp.sum((pose[neck] - pose[pelvis]) ** 2) + jnp.finfo(dtype).tiny)
    sigma = jnp.sqrt((params.joint_scales * torso) ** 2 + params.pixel_noise ** 2)
    size = frame.image_size.astype(dtype)
    log_area = jnp.sum(jnp.log(size))
    inside = jnp.all((frame.points >= -0.5) & (frame.points <= size - 0.5), -1)
    valid = jnp.arange(frame.points.shape[0]) < frame.num_people
    present = (frame.confidence > 0) & inside & valid[:, None]
    weight = (1 - params.outlier_rate) * jnp.where(present, frame.confidence, 1.0)

    def person_terms(order):
        mean, scale = pose[order], sigma[order]
        z = (frame.points - mean) / scale[:, None]
        log_gauss = (-0.5 * jnp.sum(z ** 2, -1) - 2 * jnp.log(scale) - jnp.log(2 * jnp.pi)
                     - jnp.sum(_reference_log_mass((-0.5 - mean) / scale[:, None],
                                                   (size - 0.5 - mean) / scale[:, None]), -1))
        inlier = jnp.log(weight) + log_gauss + log_area
        ratio = jnp.logaddexp(inlier, jnp.log1p(-weight))
        return jnp.where(present, ratio, 0.0), jnp.where(present, inlier, 0.0)

    ratio, inlier = jax.vmap(person_terms)(jnp.asarray([tuple(range(M)), params.swap]))
    straight, swapped = jnp.sum(ratio, -1)
    count = frame.num_people
    log_ours = jnp.log1p(-params.absent_probability) - jnp.log(jnp.maximum(count, 1))
    log_components = jnp.stack([jnp.log1p(-params.swap_probability) + straight,
                                jnp.log(params.swap_probability) + swapped])
    log_components = jnp.where(valid, log_ours + log_components, -jnp.inf)
    log_none = jnp.where(count > 0, jnp.log(params.absent_probability), 0.0)
    return ratio, inlier, log_components, log_none, present, sigma, log_area


def _reference_log_density(pose, frame, params):
    _, _, log_components, log_none, present, _, log_area = _reference_components(
        pose, frame, params)
    terms = jnp.concatenate([log_none[None], jax.nn.logsumexp(log_components, 0)])
    return jax.nn.logsumexp(terms) - log_area * jnp.sum(present)


def _reference_em_residuals(pose, frame, params):
    ratio, inlier, log_components, log_none, present, sigma, _ = jax.lax.stop_gradient(
        _reference_components(pose, frame, params))
    total = jax.nn.logsumexp(jnp.concatenate([log_none[None], log_components.ravel()]))
    gamma = jnp.where(present, jnp.exp(log_components - total)[..., None]
                      * jnp.exp(inlier - ratio), 0.0)
    orders = jnp.asarray([tuple(range(M)), params.swap])
    residual = ((frame.points[None] - pose[orders][:, None])
                / sigma[orders][:, None, :, None])
    return (jnp.sqrt(gamma)[..., None] * residual).ravel()


def _pose(centre, scale=5.0):
    shape = np.array([[0, -8], [0, 0], [0, 9], [0, 22], [-9, 1], [-12, 11], [-13, 20], [-5, 22],
                      [9, 1], [12, 11], [13, 20], [5, 22]], float)
    return shape * scale + np.asarray(centre, float)


def _frames(dtype):
    """Four frames of up to three people (the second mirrored, a keypoint outside, one
    missing, a padded slot, a frame holding no one)."""
    rng = np.random.default_rng(0)
    ours = _pose((300.0, 150.0)) + rng.normal(0, 4.0, (M, 2))
    mirrored = ours[list(swap_order(SPM_MARKERS))]
    other = _pose((120.0, 200.0), 4.0) + rng.normal(0, 3.0, (M, 2))
    points = np.stack([np.stack([ours, other, other]), np.stack([mirrored, ours, other]),
                       np.stack([ours, ours, ours]), np.stack([ours, ours, ours])])
    points[0, 0, 2] = (700.0, 10.0)                       # outside the image: not found
    confidence = rng.uniform(0.2, 1.0, (4, 3, M))
    confidence[1, 1, 5] = 0.0                             # not found
    people = np.array([2, 3, 1, 0])
    confidence[np.arange(3)[None] >= people[:, None]] = 0.0
    return DetectionsFrame(jnp.asarray(points, dtype), jnp.asarray(confidence, dtype),
                           jnp.asarray(people, jnp.int32),
                           jnp.broadcast_to(jnp.asarray(SIZE, dtype), (4, 2)))


def _poses(dtype):
    """Poses about ours, near the borders, and far outside the image (the exact tail)."""
    rng = np.random.default_rng(1)
    centres = [(300, 150), (320, 160), (5, 240), (635, 470), (300, -40), (-2000, 240),
               (300, 9000), (2600, -3000)]
    return jnp.asarray(np.stack([_pose(c, s) + rng.normal(0, 3.0, (M, 2))
                                 for c in centres for s in (0.2, 5.0)]), dtype)


def _far(poses, params, size):
    """Which poses have a marker past the erfc tails' reach (more than _FAR_TAIL σ out)."""
    torso = np.linalg.norm(poses[:, 1] - poses[:, 3], axis=-1)
    sigma = np.sqrt((np.asarray(params.joint_scales) * torso[:, None]) ** 2
                    + float(params.pixel_noise) ** 2)[..., None]
    outside = np.maximum(-0.5 - poses, poses - (np.asarray(size) - 0.5))
    return np.any(outside / sigma > _FAR_TAIL, axis=(1, 2))


def _over(function):
    """``function`` of every pose in every frame."""
    return jax.vmap(jax.vmap(function, in_axes=(0, None, None)), in_axes=(None, 0, None))


def _setting(dtype):
    params = detection_model(swap_probability=0.1, absent_probability=0.1, dtype=dtype)
    return _poses(dtype), _frames(dtype), params


def test_the_density_and_its_residuals_match_the_straightforward_transcription():
    poses, frames, params = _setting(jnp.float64)
    far = _far(np.asarray(poses), params, SIZE)
    assert far.any() and not far.all()  # both of the mass' branches, in one vmap

    @jax.jit
    def both(poses, frames, params):
        return ((_over(log_density)(poses, frames, params),
                 _over(em_residuals)(poses, frames, params)),
                (_over(_reference_log_density)(poses, frames, params),
                 _over(_reference_em_residuals)(poses, frames, params)))

    fast, reference = both(poses, frames, params)
    for mine, theirs in zip(fast, reference, strict=True):
        assert np.all(np.isfinite(theirs))
        np.testing.assert_allclose(mine, theirs, rtol=1e-10, atol=1e-10)


@pytest.mark.slow
def test_its_gradients_and_float32_values_match_the_straightforward_transcription():
    def gradients(density, poses, frames, params):
        return jax.grad(lambda *a: jnp.sum(_over(density)(*a)), argnums=(0, 2))(poses, frames,
                                                                                 params)

    setting = _setting(jnp.float64)
    fast = jax.jit(gradients, static_argnums=0)(log_density, *setting)
    reference = jax.jit(gradients, static_argnums=0)(_reference_log_density, *setting)
    for mine, theirs in zip(jax.tree.leaves(fast), jax.tree.leaves(reference), strict=True):
        assert np.all(np.isfinite(mine))
        np.testing.assert_allclose(mine, theirs, rtol=1e-9, atol=1e-9)
    setting = _setting(jnp.float32)
    fast = jax.jit(_over(log_density))(*setting)
    assert fast.dtype == jnp.float32
    np.testing.assert_allclose(fast, jax.jit(_over(_reference_log_density))(*setting),
                               rtol=2e-6)


class _ReferenceTemplates(DetectionTemplates):
    def detection_log_density(self, markers_2d, observation):
        return _reference_log_density(markers_2d, self._frame(observation), self.params)


@pytest.mark.slow
def test_a_filter_on_it_follows_the_one_on_the_straightforward_density():
    # the same key, the same particles: every frame's evidence and estimate agree to rounding
    rng = np.random.default_rng(2)
    walk = np.cumsum(rng.normal(0, 3.0, (8, 1, 2)), 0)
    points = (_pose((300.0, 150.0))[None] + walk + rng.normal(0, 4.0, (8, M, 2)))[:, None]
    confidence = np.where(rng.uniform(size=(8, 1, M)) < 0.9, 0.8, 0.0)
    frames = DetectionsFrame(points, confidence, np.ones(8, np.int32),
                             np.broadcast_to(np.asarray(SIZE), (8, 2)))
    observations = detection_observations(frames, dtype=np.float64)
    tracker = detection_tracker(points[0, 0], num_particles=64, dtype=jnp.float64)
    state = tracker.start(jr.key(0), jax.tree.map(lambda leaf: leaf[0], observations),
                          points[0, 0])
    model = state.model
    reference = eqx.tree_at(lambda m: m.templates, model,
                            _ReferenceTemplates(None, model.templates.params))
    observations = device_observation(observations, jnp.float64)

    @jax.jit
    def run(model):
        result = smc.run(jr.key(1), model, observations, 64)
        return result.log_evidence_increments, jax.vmap(model.markers_of)(result.mean)

    (fast, fast_markers), (slow, slow_markers) = run(model), run(reference)
    assert np.all(np.isfinite(slow))
    np.testing.assert_allclose(fast, slow, rtol=1e-10)
    np.testing.assert_allclose(fast_markers, slow_markers, rtol=0, atol=1e-8)
