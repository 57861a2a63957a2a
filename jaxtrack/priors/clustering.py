"""k-means, shared by the priors that cluster their training data: Ong & Gong's clusters in
the PCA coefficient space (``jaxtrack.priors.linear_combinations``) and the posture model's
mixture components (``jaxtrack.priors.postures``)."""

from __future__ import annotations

import numpy as np

__all__ = ["kmeans"]


def kmeans(points: np.ndarray, num_clusters: int, *, seed: int = 0, iterations: int = 100
           ) -> tuple[np.ndarray, np.ndarray]:
    """k-means of ``points`` ``(n, d)``: k-means++ seeding, then Lloyd iterations to a fixed
    point. Returns ``(centres (k, d), labels (n,))``; no cluster is left empty (an empty one is
    re-seeded at the point farthest from its centre)."""
    points = np.asarray(points, np.float64)
    n = len(points)
    if not 1 <= num_clusters <= n:
        raise ValueError(f"num_clusters must be between 1 and the {n} training vectors, got "
                         f"{num_clusters}")
    rng = np.random.default_rng(seed)
    centres = [points[rng.integers(n)]]
    nearest = np.sum((points - centres[0]) ** 2, axis=1)
    for _ in range(1, num_clusters):
        total = nearest.sum()
        pick = rng.choice(n, p=nearest / total) if total > 0 else rng.integers(n)
        centres.append(points[pick])
        nearest = np.minimum(nearest, np.sum((points - points[pick]) ** 2, axis=1))
    centres = np.array(centres)
    labels = np.full(n, -1)
    for _ in range(iterations):
        distances = (np.sum(points**2, axis=1)[:, None] - 2 * points @ centres.T
                     + np.sum(centres**2, axis=1)[None])
        new_labels = np.argmin(distances, axis=1)
        for cluster in range(num_clusters):
            if not np.any(new_labels == cluster):  # re-seed an empty cluster
                far = np.argmax(distances[np.arange(n), new_labels])
                new_labels[far] = cluster
        if np.array_equal(new_labels, labels):
            break
        labels = new_labels
        centres = np.array([points[labels == c].mean(axis=0) for c in range(num_clusters)])
    return centres, labels
