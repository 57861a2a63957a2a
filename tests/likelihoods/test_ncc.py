"""NCC template likelihood (Tian et al. 2005, eq. 7) on video rendered from a real wave gesture.

The frames come from the bundled AnimatedDrawings wave clip at 10 fps, 640 × 480, over a real
photograph, with templates cut at frame 0's true markers. The renderer's clothes texture is
fixed in screen space (it does not move with the body), which pulls the NCC optimum towards the
template frame's marker positions; the thresholds below leave room for that, and the 1-D sweep
uses the head and the hands, whose outline against the background dominates their patches.
"""

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _wave import rendered_wave
from scipy import ndimage

from jaxtrack.likelihoods import (
    DEFAULT_NCC_SHARPNESS,
    NCCTemplates,
    bilinear_sample,
    make_templates,
    ncc_log_likelihood,
    ncc_log_likelihood_nearest,
    ncc_scores,
    ncc_scores_nearest,
    patch_half_size,
    sample_patches,
    sample_patches_nearest,
)

HEAD, RIGHT_WRIST, LEFT_WRIST = 0, 6, 10


@cache
def wave():
    """Grey frames, true markers (``_wave.rendered_wave``) and templates cut at frame 0."""
    grey, markers = rendered_wave()
    return grey, markers, make_templates(grey[0], markers[0])


# compiled once per input shape and dtype; eager calls (op by op) cost more compile time in all
batch_log_likelihood = jax.jit(jax.vmap(ncc_log_likelihood, in_axes=(0, None, None)))
log_likelihood = jax.jit(ncc_log_likelihood)
scores_of = jax.jit(ncc_scores)
patches_of = jax.jit(sample_patches, static_argnums=2)
value_and_grad_of = jax.jit(jax.value_and_grad(ncc_log_likelihood))
batch_log_likelihood_nearest = jax.jit(jax.vmap(ncc_log_likelihood_nearest,
                                                in_axes=(0, None, None)))
log_likelihood_nearest = jax.jit(ncc_log_likelihood_nearest)
scores_nearest_of = jax.jit(ncc_scores_nearest)
patches_nearest_of = jax.jit(sample_patches_nearest, static_argnums=2)


def test_patch_half_size_is_a_tenth_of_the_spine():
    markers = np.zeros((12, 2))
    markers[3] = [0.0, 130.0]  # pelvis 130 px below the neck: side 13, half 6
    assert patch_half_size(markers) == 6
    assert isinstance(patch_half_size(markers), int)
    markers[3] = [0.0, 60.0]  # side 6 → half 2.5 rounds up to 3 (a 7-pixel patch)
    assert patch_half_size(markers) == 3
    markers[3] = [0.0, 10.0]  # tiny body: never below a 5 × 5 patch
    assert patch_half_size(markers) == 2
    with pytest.raises(ValueError, match="concrete"):
        jax.jit(patch_half_size)(markers)
    with pytest.raises(ValueError, match="12, 2"):
        patch_half_size(np.zeros((12, 3)))


def test_sample_patches_is_bilinear_with_clamped_border():
    image = np.random.default_rng(0).random((23, 31))
    # sub-pixel centres inside, on and beyond every border
    centres = np.array([[10.3, 7.8], [20.8, 3.6], [7.5, 14.2], [0.0, 0.0], [30.0, 22.0],
                        [-4.2, 11.5], [33.7, -2.1], [15.0, 25.9]])
    half = 3
    patches = np.asarray(patches_of(image, centres, half))
    offsets = np.arange(-half, half + 1)
    ys = centres[:, 1, None, None] + offsets[None, :, None] + 0 * offsets[None, None, :]
    xs = centres[:, 0, None, None] + 0 * offsets[None, :, None] + offsets[None, None, :]
    # SciPy's linear interpolation with edge replication is the same clamped bilinear sampler
    expected = ndimage.map_coordinates(image, [ys.ravel(), xs.ravel()], order=1, mode="nearest")
    np.testing.assert_allclose(patches, expected.reshape(patches.shape), rtol=0, atol=1e-12)
    # at integer centres the samples are the pixels themselves
    np.testing.assert_array_equal(patches_of(image, np.array([[12.0, 9.0]]), 2)[0],
                                  image[7:12, 10:15])


def test_bilinear_sample_reads_one_channel_in_place():
    stack = np.random.default_rng(1).random((3, 23, 31))
    x = np.array([10.3, 20.8, 0.0, 30.0, -4.2, 33.7, 15.5])
    y = np.array([7.8, 3.6, 0.0, 22.0, 11.5, -2.1, 25.9])
    sample = jax.jit(bilinear_sample, static_argnames="channel")
    for channel in range(3):
        expected = ndimage.map_coordinates(stack[channel], [y, x], order=1, mode="nearest")
        np.testing.assert_allclose(sample(stack, x, y, channel=channel), expected, rtol=0,
                                   atol=1e-12)
        np.testing.assert_array_equal(sample(stack, x, y, channel=channel),
                                      sample(stack[channel], x, y))
    with pytest.raises(ValueError, match="channel"):
        bilinear_sample(jnp.asarray(stack), x, y)
    with pytest.raises(ValueError, match="channel 3"):
        bilinear_sample(jnp.asarray(stack), x, y, channel=3)


def test_templates_are_zero_mean_unit_norm_and_match_their_own_frame():
    grey, markers, templates = wave()
    assert templates.patches.shape == (12, 13, 13) and templates.half_size == 6
    np.testing.assert_allclose(jnp.mean(templates.patches, axis=(1, 2)), 0, atol=1e-6)
    np.testing.assert_allclose(jnp.sum(templates.patches**2, axis=(1, 2)), 1, rtol=1e-5)
    np.testing.assert_allclose(scores_of(markers[0], grey[0], templates), 1, rtol=1e-5)
    assert float(log_likelihood(markers[0], grey[0], templates)) == pytest.approx(0, abs=1e-4)
    with pytest.raises(ValueError, match="half_size=2"):
        NCCTemplates(patches=jnp.zeros((12, 7, 7)), half_size=2)


def test_true_pose_beats_poses_of_other_frames():
    grey, markers, templates = wave()
    for t in (4, 6, 9):
        scores = np.asarray(batch_log_likelihood(markers, grey[t], templates))
        others = [s for s in range(len(markers)) if abs(s - t) >= 4]
        # each other pose is ≥ 0.4 s away, several pixels per marker
        assert scores[t] > max(scores[others]) + 0.3, (t, scores)


def test_true_pose_beats_markers_shifted_by_a_few_pixels():
    grey, markers, templates = wave()
    directions = np.random.default_rng(0).normal(size=(16, 12, 2))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    for t in (3, 6, 9):
        truth = float(log_likelihood(markers[t], grey[t], templates))
        shifted = np.asarray(batch_log_likelihood(
            (markers[t] + 4 * directions).astype(np.float32), grey[t], templates))
        assert np.all(shifted < truth), (t, truth, shifted)  # every marker 4 px off, any way
        assert truth - shifted.mean() > 2 * DEFAULT_NCC_SHARPNESS


@pytest.mark.parametrize("marker", [HEAD, RIGHT_WRIST, LEFT_WRIST])
def test_sweep_of_one_marker_peaks_at_its_true_position(marker):
    grey, markers, templates = wave()
    offsets = np.arange(-6, 6.01, 0.5, dtype=np.float32)
    for t in (3, 6, 9):
        poses = np.repeat(markers[t][None], len(offsets), axis=0)
        poses[:, marker, 0] += offsets
        scores = np.asarray(batch_log_likelihood(poses, grey[t], templates))
        assert abs(offsets[np.argmax(scores)]) <= 1.5, (t, scores)
        assert scores.max() - scores[[0, -1]].max() > 0.05  # a peak, not a plateau


def test_invariant_to_brightness_and_contrast():
    grey, markers, templates = wave()
    pose = markers[5] + np.float32(0.37)  # off the pixel grid
    for dtype, tolerance in ((np.float64, 1e-10), (np.float32, 1e-5)):
        image = grey[5].astype(dtype)
        reference = log_likelihood(pose.astype(dtype), image, templates)
        for gain, offset in ((2.5, -0.3), (0.05, 0.9), (40.0, 7.0)):
            changed = log_likelihood(pose.astype(dtype), gain * image + offset, templates)
            assert changed.dtype == dtype
            np.testing.assert_allclose(changed, reference, rtol=0, atol=tolerance)
    # a negative gain flips the sign of every NCC: not invariant
    flipped = scores_of(pose, 1 - grey[5], templates)
    np.testing.assert_allclose(flipped, -scores_of(pose, grey[5], templates), atol=1e-5)


def test_flat_image_gives_zero_correlation_and_finite_gradients():
    _, markers, templates = wave()
    for value in (0.0, 0.7, 255.0):
        flat = jnp.full((480, 640), value, jnp.float32)
        np.testing.assert_array_equal(scores_of(markers[3], flat, templates), 0)
        value_and_grad = value_and_grad_of(markers[3], flat, templates)
        assert float(value_and_grad[0]) == -12 * DEFAULT_NCC_SHARPNESS
        assert np.all(np.isfinite(value_and_grad[1]))
    # a flat template scores 0 wherever it is compared
    flat_templates = make_templates(jnp.ones((480, 640), jnp.float32), markers[0], 6)
    np.testing.assert_array_equal(flat_templates.patches, 0)
    grey, _, _ = wave()
    np.testing.assert_array_equal(scores_of(markers[3], grey[3], flat_templates), 0)


def test_vmap_over_particles_equals_a_loop_and_jit_equals_eager():
    grey, markers, templates = wave()
    particles = markers[2] + np.random.default_rng(1).normal(0, 3, (6, 12, 2)).astype(np.float32)
    sharpness = jnp.float32(2.5)
    batched = jax.vmap(ncc_log_likelihood, in_axes=(0, None, None, None))(
        particles, grey[2], templates, sharpness)
    looped = [ncc_log_likelihood(p, grey[2], templates, sharpness) for p in particles]
    np.testing.assert_allclose(batched, looped, rtol=1e-5, atol=1e-5)
    jitted = jax.jit(ncc_log_likelihood)(particles[0], grey[2], templates, sharpness)
    np.testing.assert_allclose(jitted, looped[0], rtol=1e-5, atol=1e-5)
    assert batched.dtype == jnp.float32  # float32 inputs stay float32 (x64 is on in the tests)


def test_dtypes_and_misuse():
    grey, markers, templates = wave()
    uint8_image = np.round(grey[1] * 255).astype(np.uint8)
    assert scores_of(np.round(markers[1]).astype(np.int32), uint8_image,
                      templates).dtype == jnp.float32
    with pytest.raises(ValueError, match="11 markers but 12 templates"):
        ncc_scores(markers[1, :11], grey[1], templates)
    with pytest.raises(ValueError, match="to_grey"):
        sample_patches(np.zeros((4, 4, 3)), markers[1], 2)


# --- nearest-pixel version -----------------------------------------------------------------


def test_sample_patches_nearest_cuts_blocks_kept_inside_the_image():
    image = np.random.default_rng(2).random((23, 31))
    half = 3
    centres = np.array([[10.3, 7.8], [20.5, 3.5], [12.0, 9.0], [0.0, 0.0], [30.0, 22.0],
                        [-40.2, 11.5], [1e9, -np.inf], [15.0, 25.9]])
    # nearest pixel (halves up), then the top-left corner clamped to [0, size − side]
    expected_corners = [(7, 5), (18, 1), (9, 6), (0, 0), (24, 16), (0, 9), (24, 0), (12, 16)]
    patches = np.asarray(patches_nearest_of(image, centres, half))
    assert patches.shape == (8, 7, 7)
    for patch, (x, y) in zip(patches, expected_corners, strict=True):
        np.testing.assert_array_equal(patch, image[y:y + 7, x:x + 7])
    # at integer centres away from the border: the bilinear sampler's patches exactly
    inner = np.array([[12.0, 9.0], [5.0, 17.0], [27.0, 3.0]])
    np.testing.assert_array_equal(patches_nearest_of(image, inner, half),
                                  patches_of(image, inner, half))
    with pytest.raises(ValueError, match="smaller than"):
        sample_patches_nearest(np.zeros((6, 40)), centres, half)
    with pytest.raises(ValueError, match="to_grey"):
        sample_patches_nearest(np.zeros((40, 40, 3)), centres, half)


def test_nearest_equals_bilinear_at_integer_markers():
    grey, markers, templates = wave()
    rng = np.random.default_rng(3)
    for t in (0, 3, 6, 9):
        # the true markers rounded, and integer poses a few pixels off (scores far from 1 too)
        poses = np.round(markers[t] + rng.integers(-5, 6, (8, 12, 2))).astype(np.float32)
        poses[0] = np.round(markers[t])
        for pose in poses:
            np.testing.assert_allclose(scores_nearest_of(pose, grey[t], templates),
                                       scores_of(pose, grey[t], templates), rtol=0, atol=1e-5)
        np.testing.assert_allclose(batch_log_likelihood_nearest(poses, grey[t], templates),
                                   batch_log_likelihood(poses, grey[t], templates),
                                   rtol=0, atol=1e-4)
    # off the grid: the bilinear score at the nearest pixel
    pose = markers[4] + np.float32(0.3)
    np.testing.assert_array_equal(scores_nearest_of(pose, grey[4], templates),
                                  scores_nearest_of(np.round(pose), grey[4], templates))


def test_nearest_true_pose_beats_markers_shifted_by_a_few_pixels():
    grey, markers, templates = wave()
    directions = np.random.default_rng(0).normal(size=(16, 12, 2))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    for t in (3, 6, 9):
        truth = float(log_likelihood_nearest(markers[t], grey[t], templates))
        shifted = np.asarray(batch_log_likelihood_nearest(
            (markers[t] + 4 * directions).astype(np.float32), grey[t], templates))
        assert np.all(shifted < truth), (t, truth, shifted)
        assert truth - shifted.mean() > 2 * DEFAULT_NCC_SHARPNESS


def test_nearest_invariant_to_brightness_and_contrast():
    grey, markers, templates = wave()
    pose = markers[5] + np.float32(0.37)
    for dtype, tolerance in ((np.float64, 1e-10), (np.float32, 1e-5)):
        image = grey[5].astype(dtype)
        reference = log_likelihood_nearest(pose.astype(dtype), image, templates)
        for gain, offset in ((2.5, -0.3), (0.05, 0.9), (40.0, 7.0)):
            changed = log_likelihood_nearest(pose.astype(dtype), gain * image + offset,
                                             templates)
            assert changed.dtype == dtype
            np.testing.assert_allclose(changed, reference, rtol=0, atol=tolerance)
        # very low contrast on a large offset, where Σp² − (Σp)²/n about the mean would cancel
        # in float32; the looser bound is the rounding of the input image itself (its 0.001
        # range spans only ~8000 float32 steps), not of the sums
        changed = log_likelihood_nearest(pose.astype(dtype), 0.001 * image + 1, templates)
        np.testing.assert_allclose(changed, reference, rtol=0, atol=10 * tolerance)
    flipped = scores_nearest_of(pose, 1 - grey[5], templates)
    np.testing.assert_allclose(flipped, -scores_nearest_of(pose, grey[5], templates), atol=1e-5)


def test_nearest_flat_patches_give_zero_never_nan():
    grey, markers, templates = wave()
    value_and_grad = jax.jit(jax.value_and_grad(ncc_log_likelihood_nearest, argnums=(0, 1)))
    for value in (0.0, 0.7, 255.0, 3e4):
        flat = jnp.full((480, 640), value, jnp.float32)
        np.testing.assert_array_equal(scores_nearest_of(markers[3], flat, templates), 0)
        log_l, (grad_markers, grad_image) = value_and_grad(markers[3], flat, templates)
        assert float(log_l) == -12 * DEFAULT_NCC_SHARPNESS
        np.testing.assert_array_equal(grad_markers, 0)  # piecewise constant in the markers
        assert np.all(np.isfinite(grad_image))
    # one flat patch among textured ones: only that marker scores 0
    image = np.array(grey[3])
    x, y = np.round(markers[3, HEAD]).astype(int)
    image[y - 6:y + 7, x - 6:x + 7] = 0.25
    scores = np.asarray(scores_nearest_of(markers[3], image, templates))
    assert scores[HEAD] == 0 and np.all(scores[np.arange(12) != HEAD] != 0)
    flat_templates = make_templates(jnp.ones((480, 640), jnp.float32), markers[0], 6)
    np.testing.assert_array_equal(scores_nearest_of(markers[3], grey[3], flat_templates), 0)


def test_nearest_markers_outside_the_image_use_the_border_patch():
    grey, markers, templates = wave()
    outside = np.array(markers[2])
    outside[HEAD] = [-50.0, -3.0]  # beyond the top-left corner
    outside[RIGHT_WRIST] = [700.0, 1e6]  # beyond the bottom-right corner
    outside[LEFT_WRIST] = [np.inf, 200.0]
    clamped = np.array(markers[2])
    clamped[HEAD] = [6, 6]
    clamped[RIGHT_WRIST] = [633, 473]
    clamped[LEFT_WRIST] = [633, 200]
    scores = np.asarray(scores_nearest_of(outside, grey[2], templates))
    assert np.all(np.isfinite(scores)) and np.all(np.abs(scores) <= 1)
    np.testing.assert_array_equal(scores, scores_nearest_of(clamped, grey[2], templates))


def test_nearest_vmap_equals_loop_and_dtypes():
    grey, markers, templates = wave()
    particles = markers[2] + np.random.default_rng(1).normal(0, 3, (6, 12, 2)).astype(np.float32)
    sharpness = jnp.float32(2.5)
    batched = jax.jit(jax.vmap(ncc_log_likelihood_nearest, in_axes=(0, None, None, None)))(
        particles, grey[2], templates, sharpness)
    looped = [log_likelihood_nearest(p, grey[2], templates, sharpness) for p in particles]
    np.testing.assert_allclose(batched, looped, rtol=1e-6, atol=1e-6)
    eager = ncc_log_likelihood_nearest(particles[0], grey[2], templates, sharpness)
    np.testing.assert_allclose(eager, looped[0], rtol=1e-6, atol=1e-6)
    assert batched.dtype == jnp.float32
    uint8_image = np.round(grey[1] * 255).astype(np.uint8)
    integer_markers = np.round(markers[1]).astype(np.int32)
    scores = scores_nearest_of(integer_markers, uint8_image, templates)
    assert scores.dtype == jnp.float32
    np.testing.assert_allclose(scores, scores_of(integer_markers, uint8_image, templates),
                               atol=1e-5)
    assert scores_nearest_of(markers[1].astype(np.float64), grey[1],
                             templates).dtype == jnp.float64
    with pytest.raises(ValueError, match="11 markers but 12 templates"):
        ncc_scores_nearest(markers[1, :11], grey[1], templates)
