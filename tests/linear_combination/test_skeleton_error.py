"""The 3-D skeleton errors: plain, and after a similarity alignment per frame."""

import numpy as np
import pytest

from jaxtrack.experiments.linear_combination import aligned_skeleton_error, skeleton_error


def _rotation(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def test_a_moved_rotated_and_scaled_skeleton_aligns_exactly():
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(4, 12, 3))
    moved = np.stack([1.7 * frame @ _rotation(0.4 * t).T + [0.3, -1.0, 2.0]
                      for t, frame in enumerate(truth)])
    assert np.all(skeleton_error(moved, truth) > 0.1)
    np.testing.assert_allclose(aligned_skeleton_error(moved, truth), 0.0, atol=1e-9)


def test_a_mirrored_or_different_skeleton_keeps_its_error():
    rng = np.random.default_rng(1)
    truth = rng.normal(size=(3, 12, 3))
    mirrored = truth * [-1.0, 1.0, 1.0]  # a reflection is not a rotation
    assert np.all(aligned_skeleton_error(mirrored, truth) > 0.1)
    other = truth + rng.normal(scale=0.2, size=truth.shape)
    aligned = aligned_skeleton_error(other, truth)
    assert np.all(aligned > 0.01) and np.all(aligned <= skeleton_error(other, truth) + 1e-12)


def test_mismatched_shapes_are_refused():
    with pytest.raises(ValueError, match="must be equal"):
        aligned_skeleton_error(np.zeros((2, 12, 3)), np.zeros((2, 11, 3)))


def test_every_view_turns_its_camera_frame_skeleton_into_the_same_world_skeleton():
    from jaxtrack.experiments.linear_combination import render_hybrid_sequences

    sequences = render_hybrid_sequences("animateddrawings/history_c119d6b/cmu_1006_wave_hello_1",
                                        views=(0, 2), num_contour=20, fps=6.0, max_frames=3)
    world = [sequence.skeleton @ sequence.rotation for sequence in sequences]
    for sequence in sequences:
        np.testing.assert_allclose(sequence.rotation @ sequence.rotation.T, np.eye(3),
                                   atol=1e-6)
    assert not np.allclose(sequences[0].skeleton, sequences[1].skeleton, atol=1e-2)
    np.testing.assert_allclose(world[0], world[1], atol=1e-5)


def test_multi_view_refuses_an_unknown_skeleton_estimate_before_any_work():
    from types import SimpleNamespace

    from jaxtrack.experiments.linear_combination import SKELETON_ESTIMATES, multi_view

    assert tuple(SKELETON_ESTIMATES) == ("best", "mean")
    trained = SimpleNamespace(model=SimpleNamespace(layout=None))
    with pytest.raises(ValueError, match="estimate must be one of \\('best', 'mean'\\)"):
        multi_view(trained, "no/such/clip", estimate="median")
