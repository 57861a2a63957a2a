"""Ong & Gong's hybrid vector: layout, round trip, batching, a contour from a real mask."""

import cv2
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body.hybrid import HybridLayout, make_hybrid, split_hybrid
from jaxtrack.vision.contours import silhouette_contour


def random_parts(rng, batch=(), num_contour=100, num_skeleton=12):
    return (
        rng.uniform(0, 640, (*batch, num_contour, 2)),
        rng.uniform(0, 640, (*batch, 2, 2)),
        rng.uniform(0, 640, (*batch, 2)),
        rng.normal(size=(*batch, num_skeleton, 3)),
    )


def test_layout_and_round_trip():
    layout = HybridLayout()
    assert layout.size == 2 * 100 + 4 + 3 * 12
    contour, hands, head, skeleton = random_parts(np.random.default_rng(0))
    vector = make_hybrid(contour, hands, head, skeleton)
    assert vector.shape == (layout.size,)
    # Ong & Gong §5.1: contour and hands relative to the head, skeleton as given
    np.testing.assert_allclose(vector[:2], contour[0] - head)
    np.testing.assert_allclose(vector[200:204], (hands - head).ravel())
    np.testing.assert_allclose(vector[204:], skeleton.ravel())
    parts = split_hybrid(vector, layout, head)
    np.testing.assert_allclose(parts.contour, contour, atol=1e-12)
    np.testing.assert_allclose(parts.hands, hands, atol=1e-12)
    np.testing.assert_allclose(parts.skeleton_3d, skeleton)
    relative = split_hybrid(vector, layout)
    np.testing.assert_allclose(relative.contour, contour - head, atol=1e-12)


def test_batch_equals_loop_and_dtype():
    layout = HybridLayout(num_contour=20, num_skeleton=5)
    contour, hands, head, skeleton = random_parts(np.random.default_rng(1), (3,), 20, 5)
    batched = make_hybrid(contour, hands, head, skeleton)
    looped = np.stack([
        make_hybrid(c, h, d, s) for c, h, d, s in zip(contour, hands, head, skeleton, strict=True)
    ])
    np.testing.assert_allclose(batched, looped)
    parts = jax.jit(split_hybrid, static_argnums=1)(batched, layout, head)
    np.testing.assert_allclose(parts.hands, hands, atol=1e-12)
    as32 = make_hybrid(*(part.astype(np.float32) for part in (contour, hands, head, skeleton)))
    assert as32.dtype == jnp.float32


def test_contour_from_a_drawn_silhouette_survives_the_round_trip():
    mask = np.zeros((240, 320), np.uint8)
    body = np.array([[150, 40], [190, 60], [200, 200], [120, 200], [130, 60]], np.int32)
    cv2.fillPoly(mask, [body], 255)
    contour = silhouette_contour(mask, num_points=100)
    head = np.array([160.0, 45.0])
    hands = np.array([[120.0, 120.0], [200.0, 120.0]])
    vector = make_hybrid(contour, hands, head, np.zeros((12, 3)))
    np.testing.assert_allclose(split_hybrid(vector, HybridLayout(), head).contour, contour,
                               atol=1e-12)


def test_wrong_sizes_raise():
    with pytest.raises(ValueError, match="needs 240"):
        split_hybrid(jnp.zeros(239), HybridLayout())
    with pytest.raises(ValueError, match="skeleton_3d"):
        make_hybrid(np.zeros((4, 2)), np.zeros((2, 2)), np.zeros(2), np.zeros((3, 2)))
