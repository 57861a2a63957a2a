"""The fitness of Ong & Gong (2002, §5.2): the normal search finds a drawn edge at a known
distance, the hand term pairs hands either way, a frame without observations is scored flat
(never NaN), and on a rendered frame the true hybrid vector fits best."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body.hybrid import split_hybrid
from jaxtrack.likelihoods.contour_normals import (
    ContourObservation,
    FitnessSettings,
    contour_distances,
    hand_distance,
    log_fitness,
)
from jaxtrack.vision.normals import gradient_magnitude


def _square(centre, half, per_side):
    """A closed square contour, clockwise on screen, ``4 × per_side`` points."""
    t = np.linspace(-half, half, per_side, endpoint=False)
    cx, cy = centre
    top = np.column_stack([cx + t, np.full_like(t, cy - half)])
    right = np.column_stack([np.full_like(t, cx + half), cy + t])
    bottom = np.column_stack([cx - t, np.full_like(t, cy + half)])
    left = np.column_stack([np.full_like(t, cx - half), cy - t])
    return np.concatenate([top, right, bottom, left])


@pytest.mark.parametrize("offset", [0, 3, -4, 7])
def test_normal_search_finds_a_drawn_edge(offset):
    """A bright square of half-size 30 drawn on black; the model square is ``offset`` px
    larger: every vertex away from the corners finds the edge |offset| px along its normal."""
    image = np.zeros((120, 120), np.float32)
    image[30:91, 30:91] = 200.0  # pixels 30..90: the edge lies between 29|30 and 90|91
    gradient = gradient_magnitude(image, sigma=0.0)
    contour = _square((60.0, 60.0), 30.0 + offset, 20)
    distances = np.asarray(contour_distances(jnp.asarray(gradient), jnp.asarray(contour), 10,
                                             0.05))
    sides = np.tile(np.arange(20), 4)
    middle = (sides >= 4) & (sides <= 16)  # away from the corners
    # the Sobel response of a step is two pixels wide: the found edge is within half a pixel
    assert np.all(np.abs(distances[middle] - abs(offset)) <= 1.0), distances[middle]
    far = np.asarray(contour_distances(jnp.asarray(gradient),
                                       jnp.asarray(_square((60.0, 60.0), 50.0, 20)), 10, 0.05))
    assert np.all(far[middle] == 10)  # no edge within reach: the search range


def test_hand_distance_pairs_either_way():
    model = jnp.array([[0.0, 0.0], [10.0, 0.0]])
    observed = jnp.array([[10.0, 1.0], [0.0, 2.0]])
    assert float(hand_distance(model, observed)) == pytest.approx(0.5 * (1 + 4))
    assert float(hand_distance(model, observed[::-1])) == pytest.approx(0.5 * (1 + 4))


def test_a_frame_without_observations_is_scored_flat_not_nan():
    observation = ContourObservation(jnp.zeros((40, 40)), jnp.full(2, jnp.nan),
                                     jnp.full((2, 2), jnp.nan), jnp.asarray(False))
    contour = jnp.asarray(_square((0.0, 0.0), 5.0, 4))
    value = log_fitness(contour, jnp.zeros((2, 2)), observation, FitnessSettings())
    assert float(value) == 0.0


def test_fitness_is_eq9():
    """Perfect contour and hands give log(O + R); hands off by (3, 4) give
    log(O + R exp(-f_S / 2Q)) with f_S = ½ (25 + 25)."""
    image = np.zeros((120, 120), np.float32)
    image[30:91, 30:91] = 200.0
    gradient = jnp.asarray(gradient_magnitude(image, sigma=0.0))
    head = jnp.array([60.0, 60.0])
    contour = jnp.asarray(_square((0.0, 0.0), 30.0, 20))
    hands = jnp.array([[-20.0, 10.0], [20.0, 10.0]])
    observation = ContourObservation(gradient, head, hands + head, jnp.asarray(True))
    settings = FitnessSettings(contour_weight=0.5, hands_weight=0.5, contour_tolerance=1e6,
                               hands_tolerance=64.0)
    value = float(log_fitness(contour, hands, observation, settings))
    assert value == pytest.approx(np.log(1.0), abs=1e-5)
    shifted = hands + jnp.array([3.0, 4.0])
    value = float(log_fitness(contour, shifted, observation, settings))
    expected = np.log(0.5 * np.exp(-np.mean(np.asarray(contour_distances(
        gradient, contour + head, 10, 0.05)) ** 2) / 2e6) + 0.5 * np.exp(-25.0 / 128.0))
    assert value == pytest.approx(expected, abs=1e-6)


def test_fitness_peaks_at_the_true_hybrid_vector(rendered):
    """On each rendered frame the frame's own hybrid vector (exact silhouette contour, skin
    blobs) outscores the vectors of every other frame of the clip."""
    sequence = rendered
    observations = sequence.observations
    layout_vectors = jnp.asarray(sequence.vectors[sequence.valid])
    from jaxtrack.body.hybrid import HybridLayout

    layout = HybridLayout(num_contour=40, num_skeleton=12)
    parts = split_hybrid(layout_vectors, layout)
    frames = np.flatnonzero(sequence.valid & np.asarray(observations.found))
    assert len(frames) >= 6
    score = jax.jit(jax.vmap(log_fitness, in_axes=(0, 0, None, None)), static_argnums=3)
    wins = 0
    for row, t in enumerate(frames):
        observation = jax.tree.map(lambda leaf, t=t: jnp.asarray(leaf[t]), observations)
        scores = np.asarray(score(parts.contour, parts.hands, observation, FitnessSettings()))
        assert np.all(np.isfinite(scores))
        wins += int(np.argmax(scores) == row)
    assert wins >= len(frames) - 1, f"the true vector fitted best on {wins} of {len(frames)}"
