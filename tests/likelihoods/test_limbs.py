"""Limb-strip NCC likelihood on video rendered from a real wave gesture (same frames as the NCC
tests: the bundled AnimatedDrawings wave at 10 fps, 640 × 480, over a real photograph)."""

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _wave import RIGHT_ELBOW, RIGHT_WRIST, rendered_wave, wrong_poses

from jaxtrack.likelihoods import (
    DEFAULT_LIMB_SHARPNESS,
    LIMB_SEGMENTS,
    LimbTemplates,
    limb_ncc_log_likelihood,
    limb_ncc_scores,
    limb_points,
    make_appearance_templates,
    make_limb_templates,
)


@cache
def wave():
    """Grey frames, true markers (``_wave.rendered_wave``) and templates cut at frame 0."""
    grey, markers = rendered_wave()
    return grey, markers, make_limb_templates(grey[0], markers[0])


scores_of = jax.jit(limb_ncc_scores, static_argnames="nearest")
batch_log_likelihood = jax.jit(jax.vmap(limb_ncc_log_likelihood, in_axes=(0, None, None)))
batch_log_likelihood_bilinear = jax.jit(jax.vmap(
    lambda markers, image, templates: limb_ncc_log_likelihood(markers, image, templates,
                                                              nearest=False),
    in_axes=(0, None, None)))
residuals_of = jax.jit(lambda templates, *args: templates.residuals(*args))



def test_strip_points_follow_their_segments_and_scale_with_the_spine():
    markers = np.zeros((12, 2), np.float32)
    markers[3] = [0, 100]  # pelvis 100 px under the neck: half width 0.1 × 100 = 10 px
    markers[RIGHT_ELBOW], markers[RIGHT_WRIST] = [50, 0], [50, 40]
    points = np.asarray(limb_points(markers, along=5, across=3))
    forearm = [name for name, *_ in LIMB_SEGMENTS].index("right forearm and hand")
    assert points.shape == (len(LIMB_SEGMENTS), 5, 3, 2)
    np.testing.assert_allclose(points[forearm, 0, 1], [50, 0], atol=1e-5)  # starts at the elbow
    np.testing.assert_allclose(points[forearm, -1, 1], [50, 40 * 1.35], atol=1e-4)  # over the hand
    np.testing.assert_allclose(points[forearm, 0, [0, 2], 0], [60, 40], atol=1e-5)  # ±10 px across
    twice = np.asarray(limb_points(2 * markers, along=5, across=3))
    np.testing.assert_allclose(twice, 2 * points, atol=1e-4)  # strips scale with the body


def test_templates_are_unit_strips_that_match_their_own_frame():
    grey, markers, templates = wave()
    assert templates.strips.shape == (len(LIMB_SEGMENTS), 12, 7)
    np.testing.assert_allclose(jnp.mean(templates.strips, axis=(1, 2)), 0, atol=1e-6)
    np.testing.assert_allclose(jnp.sum(templates.strips**2, axis=(1, 2)), 1, rtol=1e-5)
    np.testing.assert_allclose(scores_of(markers[0], grey[0], templates, nearest=False), 1,
                               rtol=1e-5)
    # nearest-pixel sampling reads the same strips to within half a pixel
    assert np.all(np.asarray(scores_of(markers[0], grey[0], templates)) > 0.8)


@pytest.mark.parametrize("nearest", [True, False])
def test_true_pose_beats_turned_and_shifted_arms(nearest):
    grey, markers, templates = wave()
    score = batch_log_likelihood if nearest else batch_log_likelihood_bilinear
    for t in (3, 6, 9):
        values = np.asarray(score(np.concatenate([markers[t][None], wrong_poses(markers[t])]),
                                  grey[t], templates))
        assert np.all(values[1:] < values[0]), (t, values)


def test_invariant_to_brightness_and_contrast_and_flat_images_score_zero():
    grey, markers, templates = wave()
    pose = markers[5] + np.float32(0.37)
    reference = scores_of(pose, grey[5], templates, nearest=False)
    for gain, offset in ((2.5, -0.3), (0.05, 0.9), (40.0, 7.0)):
        changed = scores_of(pose, gain * grey[5] + offset, templates, nearest=False)
        np.testing.assert_allclose(changed, reference, atol=2e-5)
    for nearest in (True, False):
        flat = scores_of(pose, jnp.full((480, 640), 0.7, jnp.float32), templates,
                         nearest=nearest)
        np.testing.assert_array_equal(flat, 0)
    far = np.full((12, 2), 1e9, np.float32)  # far off the image: border pixels, never NaN
    assert np.all(np.isfinite(scores_of(far, grey[5], templates)))


def test_residuals_are_the_cost_as_a_sum_of_squares_and_vmap_equals_a_loop():
    grey, markers, templates = wave()
    particles = markers[4] + np.random.default_rng(1).normal(0, 3, (5, 12, 2)).astype(np.float32)
    sharpness = jnp.float32(DEFAULT_LIMB_SHARPNESS)
    for pose in particles[:2]:
        residuals = residuals_of(templates, pose, grey[4], sharpness)
        cost = -limb_ncc_log_likelihood(pose, grey[4], templates, sharpness, nearest=False)
        np.testing.assert_allclose(0.5 * jnp.sum(residuals**2), cost, rtol=1e-4)
    batched = batch_log_likelihood(particles, grey[4], templates)
    looped = [limb_ncc_log_likelihood(pose, grey[4], templates) for pose in particles]
    np.testing.assert_allclose(batched, looped, rtol=1e-5, atol=1e-5)
    assert batched.dtype == jnp.float32
    # the tracker-facing interface is the same function
    np.testing.assert_allclose(templates.log_likelihood(particles[0], grey[4], 4.0), looped[0],
                               rtol=1e-5)


def test_misuse_is_reported():
    grey, markers, templates = wave()
    with pytest.raises(ValueError, match="finite"):
        make_limb_templates(grey[0], np.full((12, 2), np.nan))
    with pytest.raises(ValueError, match="width"):
        make_limb_templates(grey[0], markers[0], width=0.0)
    with pytest.raises(ValueError, match="along"):
        make_limb_templates(grey[0], markers[0], along=1)
    with pytest.raises(ValueError, match="12, 2"):
        limb_points(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="grey"):
        limb_ncc_scores(markers[0], np.zeros((480, 640, 3)), templates)
    with pytest.raises(ValueError, match="strips"):
        LimbTemplates(strips=jnp.zeros((3, 12, 7)), width=jnp.float32(0.1))
    with pytest.raises(ValueError, match="likelihood must be one of"):
        make_appearance_templates("silhouette", grey[0], markers[0])
