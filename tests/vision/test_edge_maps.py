"""Edge maps (Canny, distance transform, nearest edge's tangent) on OpenCV drawings."""

import cv2
import numpy as np
import pytest

from jaxtrack.vision import edge_distance_maps, edge_observations


def rectangle_frame(shape=(120, 160), corners=((40, 30), (120, 90)), level=0.8):
    frame = np.full(shape, 0.2, np.float32)
    cv2.rectangle(frame, corners[0], corners[1], level, thickness=-1)
    return frame


def test_distance_is_zero_on_the_outline_and_grows_away_from_it():
    frame = rectangle_frame()
    distances = edge_distance_maps(frame[None], blur=0.0)[0]
    assert distances.shape == frame.shape and distances.dtype == np.float32
    # the rectangle's left side is at column 40: the edge lies on it or next to it
    assert distances[60, 39:42].min() == 0
    # 20 columns left of the outline and 20 right of it (inside the rectangle, whose centre
    # row is 30 px from the top and bottom sides)
    np.testing.assert_allclose(distances[60, 20], 20, atol=1.5)
    np.testing.assert_allclose(distances[60, 60], 20, atol=1.5)
    assert distances[60, 80] > distances[60, 60]  # further inside, further from every side


def test_uint8_and_float_frames_agree_and_a_flat_frame_has_no_edge():
    frame = rectangle_frame()
    as_float = edge_distance_maps(frame[None])
    as_uint8 = edge_distance_maps(np.rint(frame * 255).astype(np.uint8)[None])
    np.testing.assert_array_equal(as_float, as_uint8)
    flat = edge_distance_maps(np.full((1, 50, 40), 0.5, np.float32))
    np.testing.assert_allclose(flat, np.hypot(50, 40))  # as far as any pixel can be


def test_observations_stack_the_grey_frame_its_distance_map_and_the_nearest_edges_tangent():
    frames = np.stack([rectangle_frame(), rectangle_frame(level=0.6)])
    observations = edge_observations(frames)
    assert observations.shape == (2, 3, 120, 160) and observations.dtype == np.float32
    tangent = observations[0, 2]
    assert np.all((tangent >= 0) & (tangent < np.pi))
    # left of the rectangle the nearest edge is its vertical left side; above it, its top
    assert abs(np.cos(tangent[60, 20])) < 0.2 and abs(np.cos(tangent[60, 45])) < 0.2
    assert abs(np.sin(tangent[10, 80])) < 0.2 and abs(np.sin(tangent[35, 80])) < 0.2
    np.testing.assert_array_equal(observations[:, 0], frames)
    # the labelled transform rounds differently in the last digits
    np.testing.assert_allclose(observations[:, 1], edge_distance_maps(frames), rtol=1e-4)
    from_uint8 = edge_observations(np.rint(frames * 255).astype(np.uint8))
    np.testing.assert_allclose(from_uint8[:, 0], frames, atol=0.5 / 255)


def test_bad_input_is_reported():
    frame = rectangle_frame()
    with pytest.raises(ValueError, match="time, height, width"):
        edge_distance_maps(frame)
    with pytest.raises(ValueError, match="low <= high"):
        edge_distance_maps(frame[None], low=100, high=50)
    with pytest.raises(ValueError, match="blur"):
        edge_distance_maps(frame[None], blur=-1)
    with pytest.raises(ValueError, match="non-finite"):
        edge_distance_maps(np.full((1, 10, 10), np.nan, np.float32))
    with pytest.raises(ValueError, match="out must be float32"):
        edge_observations(frame[None], out=np.empty((1, 3, 120, 160), np.float64))


def test_written_into_a_given_array_by_any_number_of_threads_and_negative_grey_is_black():
    frames = np.stack([rectangle_frame(), rectangle_frame(level=0.6), rectangle_frame(level=0.4)])
    out = np.full((3, 3, 120, 160), np.nan, np.float32)
    assert edge_observations(frames, out=out, workers=2) is out
    np.testing.assert_array_equal(out, edge_observations(frames, workers=1))
    with pytest.raises(ValueError, match="workers"):
        edge_distance_maps(frames, workers=0)
    frames = frames[:2]
    below = frames.copy()
    below[below < 0.5] = -0.2  # below black: clipped to 0, never folded up to +0.2
    np.testing.assert_array_equal(edge_distance_maps(below),
                                  edge_distance_maps(np.maximum(below, 0)))
