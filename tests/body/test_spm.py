"""Scaled Prismatic Model: exact round trip on real projected mocap, gradients, transformations."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

from jaxtrack.body.camera import project
from jaxtrack.body.spm import (
    SPM_LINKS,
    SPM_MARKERS,
    SPM_STATE_NAMES,
    SPM_STATE_SIZE,
    build_template,
    spm_fit,
    spm_fit_with_info,
    spm_forward,
    spm_initial_state,
)
from jaxtrack.body.viewpoints import Viewpoint, frame_subject

FRAMES = 30  # frames per sequence: one shape, so spm_fit compiles once for the whole module
IMAGE_SIZE = (640, 480)


@functools.cache
def real_sequences() -> dict[str, np.ndarray]:
    """Real upper-body markers projected at 640×480: two clips × two views, 30 frames each."""
    from jaxtrack.body.markers import UPPER_BODY_12, marker_positions
    from jaxtrack.data import load_clip

    sequences = {}
    for clip in ("animateddrawings/fair1_wave_hello", "cmu_bvh/131_01"):
        markers = marker_positions(load_clip(clip), UPPER_BODY_12)
        step = max(1, markers.shape[0] // FRAMES)
        markers = markers[::step][:FRAMES]
        for azimuth in (0.3, 2.0):
            view = Viewpoint(jnp.asarray(azimuth), jnp.asarray(0.2), jnp.asarray(4.0))
            camera = frame_subject(markers, view, IMAGE_SIZE, margin=0.1)
            sequences[f"{clip}@{azimuth}"] = np.asarray(project(camera, markers))
    return sequences


def test_marker_order_matches_the_marker_set():
    from jaxtrack.body.markers import UPPER_BODY_12

    assert SPM_MARKERS == UPPER_BODY_12
    assert len(SPM_LINKS) == 11 and len(SPM_STATE_NAMES) == SPM_STATE_SIZE == 25


def test_fit_reproduces_real_markers_to_subpixel_accuracy():
    sequences = real_sequences()
    names = list(sequences)
    # template from one clip, fitted to all: the template only sets the parametrisation
    template = build_template(np.concatenate([sequences[n] for n in names[:2]]))
    for name in names:
        markers = sequences[name]
        states, info = spm_fit_with_info(markers, template)
        assert states.shape == (FRAMES, 25)
        assert np.all(np.asarray(info.result._value) == optx.RESULTS.successful._value), name
        fitted = jax.vmap(spm_forward, in_axes=(0, None))(states, template)
        error = np.linalg.norm(np.asarray(fitted) - markers, axis=-1)
        assert error.max() < 0.1, (name, error.max())
        np.testing.assert_allclose(info.max_error, error.max(axis=-1), atol=1e-9)
        # unwrapped angles are continuous over time: no 2π jumps between frames
        assert np.abs(np.diff(states[:, 3::2], axis=0)).max() < np.pi, name
        # log s is the log neck–pelvis distance in pixels
        torso = np.linalg.norm(markers[:, 3] - markers[:, 1], axis=-1)
        np.testing.assert_allclose(np.exp(states[:, 0]), torso, rtol=1e-6)


def test_template_matches_an_upright_body():
    markers = np.concatenate(list(real_sequences().values()))
    template = build_template(markers)
    # image y points down: neck→thorax and thorax→pelvis point down, neck→head up
    link = {pair: k for k, pair in enumerate(SPM_LINKS)}
    assert abs(float(template.reference_angles[link["neck", "thorax"]]) - np.pi / 2) < 0.3
    assert abs(float(template.reference_angles[link["neck", "head"]]) + np.pi / 2) < 0.5
    assert np.all(np.asarray(template.reference_lengths) > 0.05)
    # the initial (closed-form) state of the mean pose is near zero angles
    states = spm_initial_state(markers, template)
    assert float(jnp.median(jnp.abs(states[:, 3::2]))) < 0.5


def test_length_regularisation_pulls_lengths_to_the_template():
    markers = next(iter(real_sequences().values()))
    template = build_template(markers)
    plain = spm_fit(markers, template)
    ridge = spm_fit(markers, template, length_regularisation=1e4)
    assert float(jnp.sum(ridge[:, 4::2] ** 2)) < 0.5 * float(jnp.sum(plain[:, 4::2] ** 2))


def test_forward_gradient_matches_finite_differences():
    markers = next(iter(real_sequences().values()))
    template = build_template(markers)
    state = spm_initial_state(markers[5], template)
    jacobian = jax.jacfwd(spm_forward)(state, template)
    assert jacobian.shape == (12, 2, 25)
    step = 1e-6
    offsets = step * jnp.eye(SPM_STATE_SIZE)
    forward = jax.vmap(spm_forward, in_axes=(0, None))
    central = (forward(state + offsets, template) - forward(state - offsets, template)) / (2 * step)
    np.testing.assert_allclose(jacobian, jnp.moveaxis(central, 0, -1), rtol=1e-6, atol=1e-5)


def test_an_angle_moves_only_the_links_descendants():
    markers = next(iter(real_sequences().values()))
    template = build_template(markers)
    state = spm_initial_state(markers[0], template)
    elbow = SPM_STATE_NAMES.index("angle_right_shoulder_right_elbow")
    moved = np.abs(np.asarray(spm_forward(state.at[elbow].add(0.3), template)
                              - spm_forward(state, template))).max(axis=-1) > 1e-9
    expected = [name in ("right_elbow", "right_wrist") for name in SPM_MARKERS]
    assert moved.tolist() == expected


def test_forward_jit_vmap_and_dtype():
    markers = next(iter(real_sequences().values()))
    template = build_template(markers)
    states = spm_initial_state(markers[:6], template)
    looped = np.stack([spm_forward(state, template) for state in states])
    batched = jax.jit(jax.vmap(spm_forward, in_axes=(0, None)))(states, template)
    np.testing.assert_allclose(batched, looped, atol=1e-10)
    np.testing.assert_allclose(jax.jit(spm_forward)(states[0], template), looped[0], atol=1e-10)
    single = spm_forward(states[0].astype(jnp.float32), template)
    assert single.dtype == jnp.float32
    np.testing.assert_allclose(single, looped[0], atol=1e-2)


def test_bad_shapes_raise():
    template = build_template(next(iter(real_sequences().values())))
    with pytest.raises(ValueError, match="12, 2"):
        spm_fit(np.zeros((3, 15, 2)), template)
    with pytest.raises(ValueError, match="25"):
        spm_forward(jnp.zeros(24), template)


def test_switching_jax_enable_x64_between_calls():
    """Regression: the SPM's index constants were module-level NumPy arrays, and JAX reuses the
    canonical (int32 or int64) form of such an array across ``jax.enable_x64`` settings, so
    ``spm_initial_state`` failed while tracing (int32 indices against int64 sizes) once it had
    run under the other setting in the same process."""
    upright = np.array([  # head, neck, thorax, pelvis, right arm and hip, left arm and hip
        [0, -30], [0, 0], [0, 40], [0, 90], [-25, 5], [-35, 45], [-40, 85], [-15, 95],
        [25, 5], [35, 45], [40, 85], [15, 95],
    ], np.float64) + [320.0, 100.0]
    markers = np.stack([upright, upright + np.linspace(-3.0, 3.0, 24).reshape(12, 2)])
    for x64 in (False, True, False):  # the suite runs with x64 on: both orders are covered
        with jax.enable_x64(x64):
            template = build_template(jnp.asarray(markers))
            states = spm_initial_state(jnp.asarray(markers), template)
            fitted = jax.vmap(spm_forward, in_axes=(0, None))(states, template)
            assert states.dtype == fitted.dtype == (jnp.float64 if x64 else jnp.float32)
            np.testing.assert_allclose(fitted, markers, atol=1e-3)
