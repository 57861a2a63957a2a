"""Stick figures drawn with OpenCV: silhouettes whose head, hands and feet are known exactly."""

from __future__ import annotations

import numpy as np

THICKNESS = 5
HEAD_RADIUS = 6

# (head centre, neck, pelvis, hand 1, hand 2, foot 1, foot 2), pixels (x, y), on a 120 x 100 image
FIGURES = {
    "standing": ((50, 14), (50, 22), (50, 55), (25, 45), (75, 45), (40, 90), (60, 90)),
    "sitting": ((50, 30), (50, 38), (50, 65), (28, 62), (72, 62), (35, 92), (65, 92)),
    "crawling_bending": ((20, 55), (28, 55), (75, 45), (28, 85), (42, 85), (82, 88), (95, 88)),
    "lying_left": ((15, 70), (23, 70), (70, 70), (45, 60), (45, 80), (105, 64), (105, 78)),
    # a crouch seen from the front: taller than wide, so the bending rule reads it from the top
    "crouching": ((50, 14), (50, 22), (50, 50), (30, 52), (70, 52), (38, 90), (62, 90)),
}
IMAGE_SIZE = (120, 100)  # width, height


def draw(name: str, *, mirror: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A ``(100, 120)`` bool silhouette and its ``(5, 2)`` true extremes (head top, hand and foot
    ends), the figure mirrored left-right on request."""
    import cv2

    head, neck, pelvis, *ends = FIGURES[name]
    image = np.zeros(IMAGE_SIZE[::-1], np.uint8)
    cv2.circle(image, head, HEAD_RADIUS, 1, -1)
    cv2.line(image, neck, pelvis, 1, THICKNESS + 4)
    cv2.line(image, head, neck, 1, THICKNESS)
    for hand in ends[:2]:
        cv2.line(image, neck, hand, 1, THICKNESS)
    for foot in ends[2:]:
        cv2.line(image, pelvis, foot, 1, THICKNESS)
    truth = np.array([head, *ends], np.float64)
    if mirror:
        image = image[:, ::-1]
        truth[:, 0] = IMAGE_SIZE[0] - 1 - truth[:, 0]
    return image.astype(bool), truth


def figure_postures(num_bins: int = 16, cutoff: float = 1e9):
    """A posture model whose means are the drawn figures' projection histograms (``num_bins``
    bins; standing, sitting, crawling/bending, lying either way), unit-ish covariances and a
    sticky transition matrix: a tiny model with known answers for the filter's tests."""
    import jax.numpy as jnp

    from jaxtrack.priors.postures import NUM_POSTURES, PostureModel
    from jaxtrack.vision.histograms import projection_histograms

    figures = [draw("standing")[0], draw("sitting")[0], draw("crawling_bending")[0],
               draw("lying_left")[0], draw("lying_left", mirror=True)[0]]
    means = np.stack([projection_histograms(mask, num_bins) for mask in figures])
    dimension = means.shape[1]
    transition = np.full((NUM_POSTURES, NUM_POSTURES), 0.025) + np.eye(NUM_POSTURES) * 0.875
    return PostureModel(jnp.asarray(means), jnp.broadcast_to(
        jnp.eye(dimension) / 0.1 ** 2, (NUM_POSTURES, dimension, dimension)),
        jnp.zeros(NUM_POSTURES), jnp.asarray(np.log(transition)),
        jnp.full(NUM_POSTURES, -np.log(NUM_POSTURES)), jnp.asarray(cutoff))
