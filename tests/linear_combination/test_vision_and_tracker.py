"""Skin blobs, observations of frames without a person, and the tracker on a rendered clip."""

import jax.random as jr
import numpy as np
import pytest

from jaxtrack.body.hybrid import HybridLayout
from jaxtrack.experiments.linear_combination import TrainedLinearCombinations, observe, run_method
from jaxtrack.likelihoods.contour_normals import ContourObservation
from jaxtrack.priors.linear_combinations import fit_linear_combinations
from jaxtrack.trackers import Engine
from jaxtrack.trackers.linear_combination import linear_combination_tracker, track_observations
from jaxtrack.vision.skin import skin_blobs, skin_mask

SKIN = (224, 172, 135)


def _disks(centres, size=(120, 100)):
    import cv2

    image = np.zeros((size[1], size[0], 3), np.uint8)
    image[:] = (30, 60, 160)
    for centre in centres:
        cv2.circle(image, centre, 6, SKIN, -1)
    return image


def test_skin_blobs_head_on_top_hands_by_x():
    image = _disks([(60, 15), (90, 60), (20, 70)])
    blobs = skin_blobs(skin_mask(image))
    assert blobs.found
    np.testing.assert_allclose(blobs.head, [60, 15], atol=0.6)
    np.testing.assert_allclose(blobs.hands, [[20, 70], [90, 60]], atol=0.6)
    same = skin_blobs(skin_mask(image, reference=SKIN))
    np.testing.assert_allclose(same.hands, blobs.hands)


def test_no_skin_and_no_person_are_reported():
    empty = _disks([])
    blobs = skin_blobs(skin_mask(empty))
    assert not blobs.found and "skin pixels" in blobs.reason
    frames = np.stack([empty, _disks([(60, 15), (90, 60), (20, 70)])])
    observations, status = observe(frames, empty)
    assert list(np.asarray(observations.found)) == [False, True]
    assert "no silhouette" in status[0] and status[1] == ""
    assert np.all(np.isfinite(observations.head)) and np.all(np.isfinite(observations.hands))
    with pytest.raises(ValueError, match="images must be"):
        observe(frames[..., 0], empty)


@pytest.fixture(scope="module")
def trained(rendered):
    vectors = rendered.vectors[rendered.valid]
    layout = HybridLayout(num_contour=40, num_skeleton=12)
    fit = fit_linear_combinations(vectors, np.zeros(len(vectors)), layout,
                                  variance_fraction=0.95, num_clusters=3)
    return TrainedLinearCombinations(fit.model, vectors, {"fps": 6.0})


def test_tracker_beats_the_mean_skeleton_and_survives_a_blank_frame(rendered, trained):
    """On its own training clip the tracker's 3-D error is below that of always answering
    the training mean skeleton; a frame without observations reports found False and a
    finite skeleton."""
    observations = rendered.observations
    found = np.array(observations.found)
    found[5] = False  # as observe reports a frame without a silhouette
    head = np.array(observations.head)
    head[5] = np.nan
    observations = ContourObservation(observations.gradient, head, observations.hands, found)
    tracker = linear_combination_tracker(trained.model, engine=Engine(40), iterations=1)
    result = track_observations(tracker, jr.PRNGKey(0), observations)
    estimates = result.estimates
    assert estimates.best_skeleton_3d.shape == rendered.skeleton.shape
    assert np.all(np.isfinite(estimates.best_skeleton_3d))
    assert not estimates.found[5] and estimates.found[4]
    assert np.all(np.isnan(estimates.best_markers[5])) and np.all(
        np.isfinite(estimates.best_markers[4]))
    error = np.linalg.norm(estimates.best_skeleton_3d - rendered.skeleton, axis=-1).mean()
    mean_skeleton = rendered.skeleton[rendered.valid].mean(axis=0)
    baseline = np.linalg.norm(mean_skeleton - rendered.skeleton, axis=-1).mean()
    assert error < 0.8 * baseline, (error, baseline)
    clusters = np.asarray(estimates.cluster)
    assert clusters.min() >= 0 and clusters.max() < 3
    spread = np.asarray(estimates.skeleton_spread)
    assert spread.shape == (len(found),) and np.all(np.isfinite(spread)) and np.all(spread >= 0)


def test_skeleton_spread_is_the_weighted_rms_distance_of_the_particles_skeletons(trained):
    """``skeleton_spread``: √(Σ_i w_i mean_k |s_ik − s̄_k|²) over the particles'
    reconstructed skeletons; 0 when every particle is the same."""
    import jax.numpy as jnp

    from jaxtrack.trackers.linear_combination import _skeleton_spread

    model, layout = trained.model, trained.model.layout
    coefficients = np.random.default_rng(0).normal(size=(5, model.num_components))
    log_weights = np.log(np.array([0.1, 0.2, 0.3, 0.15, 0.25]))
    skeletons = np.stack([np.asarray(model.reconstruct(jnp.asarray(c)))[layout.skeleton_slice]
                          for c in coefficients]).reshape(5, layout.num_skeleton, 3)
    weights = np.exp(log_weights)
    mean = np.einsum("i,ikd->kd", weights, skeletons)
    expected = np.sqrt(weights @ np.mean(np.sum((skeletons - mean) ** 2, axis=-1), axis=-1))
    spread = _skeleton_spread(model, jnp.asarray(coefficients), jnp.asarray(log_weights),
                              jnp.asarray(mean))
    assert float(spread) == pytest.approx(expected, rel=1e-5) and expected > 0
    same = jnp.asarray(np.repeat(coefficients[:1], 5, axis=0))
    assert float(_skeleton_spread(model, same, jnp.asarray(log_weights),
                                  jnp.asarray(skeletons[0]))) == pytest.approx(0.0, abs=1e-6)


def test_nearest_neighbour_baseline_finds_the_frame_itself(rendered, trained):
    run = run_method("nearest-neighbour", trained, rendered.observations)
    chosen = run["skeleton"][rendered.valid]
    own = np.all(np.isclose(chosen, rendered.skeleton[rendered.valid]), axis=(1, 2))
    assert own.sum() >= len(own) - 2, f"its own vector chosen on {own.sum()} of {len(own)}"
    with pytest.raises(ValueError, match="method must be one of"):
        run_method("brownian", trained, rendered.observations)
