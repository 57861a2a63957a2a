"""Training a linear-combination model from hybrid vectors (Ong & Gong 2002, §3.2–4.1).

1. Part weights: each part of the hybrid vector (contour, hands, skeleton) is scaled so that
   its total variance over the training set is the same, so no part's units dominate the PCA.
2. Global PCA (§3.2): eigenvectors of the scaled vectors' covariance, kept until they explain
   ``variance_fraction`` of the variance; coefficients by eq. 2.
3. Constraints (§3.3): k-means (k-means++ seeding, Lloyd iterations) of the coefficients; for
   each cluster its mean μ_i, local eigenvectors P_i (kept to ``local_variance_fraction``) and
   extents Λ_i (the largest |projection| of its members, so its ±1 box holds them all).
4. Structural dynamics (§4.1): U_ab counts the frames in cluster a followed by a frame in cluster
   b, over consecutive frames of each training sequence (never across two sequences); each row
   is normalised. A cluster never followed by a frame (every member the last frame of its
   sequence) has an unseen row: it gets a self-transition of 1, so a particle there stays and
   moves within the cluster. ``floor`` adds that much probability to every transition before
   normalising (0: the paper's counts alone).

NumPy in float64: training runs once, on the host.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.body.hybrid import HybridLayout
from jaxtrack.priors.clustering import kmeans
from jaxtrack.priors.linear_combinations._model import LinearCombinationModel

__all__ = ["LinearCombinationFit", "fit_linear_combinations", "kmeans", "part_weights",
           "transition_matrix"]


@dataclass(frozen=True)
class LinearCombinationFit:
    """A trained model and what training saw.

    Attributes:
        model: the :class:`LinearCombinationModel` (float64).
        explained_variance: fraction of the scaled variance the kept eigenvectors explain.
        counts: ``(clusters, clusters)`` the raw transition counts behind U.
        unseen_rows: clusters whose row of U had no count (given a self-transition).
    """

    model: LinearCombinationModel
    explained_variance: float
    counts: np.ndarray
    unseen_rows: tuple[int, ...]


def part_weights(vectors: np.ndarray, layout: HybridLayout) -> np.ndarray:
    """``(3,)`` weights of the contour, hands and skeleton entries that give each part the same
    total variance (that of the contour part, so contour pixels keep their units)."""
    slices = (layout.contour_slice, layout.hands_slice, layout.skeleton_slice)
    totals = np.array([np.sum(np.var(vectors[:, part], axis=0)) for part in slices])
    if np.any(totals <= 0):
        empty = [name for name, total in zip(("contour", "hands", "skeleton"), totals,
                                             strict=True) if total <= 0]
        raise ValueError(f"the training vectors' {', '.join(empty)} never vary: a PCA needs "
                         "training frames whose poses differ")
    return np.sqrt(totals[0] / totals)


def transition_matrix(labels: np.ndarray, sequence_ids: np.ndarray, num_clusters: int, *,
                      floor: float = 0.0) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Ong & Gong §4.1's U from cluster labels of consecutive frames.

    Args:
        labels: ``(frames,)`` cluster of each training frame, in time order within a sequence.
        sequence_ids: ``(frames,)`` which sequence each frame belongs to; a pair of frames
            counts only when both are in the same sequence and adjacent in the arrays.
        num_clusters: number of clusters.
        floor: added to every count before normalising (0: none).

    Returns:
        ``(U, counts, unseen_rows)``: U row-normalised, the raw counts, and the clusters whose
        row had no count (module docstring: they get a self-transition).
    """
    labels, sequence_ids = np.asarray(labels), np.asarray(sequence_ids)
    if labels.shape != sequence_ids.shape or labels.ndim != 1:
        raise ValueError(f"labels {labels.shape} and sequence_ids {sequence_ids.shape} must be "
                         "one number per training frame")
    if not floor >= 0:
        raise ValueError(f"floor must be >= 0, got {floor}")
    counts = np.zeros((num_clusters, num_clusters))
    same = sequence_ids[1:] == sequence_ids[:-1]
    np.add.at(counts, (labels[:-1][same], labels[1:][same]), 1.0)
    unseen = tuple(int(row) for row in np.flatnonzero(counts.sum(axis=1) == 0))
    weights = counts + floor
    weights[list(unseen), list(unseen)] += 1.0
    return weights / weights.sum(axis=1, keepdims=True), counts, unseen


def _local_pca(members: np.ndarray, fraction: float) -> tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray]:
    """(mean, local eigenvectors (d, m), extents (m,)) of one cluster's coefficients."""
    mean = members.mean(axis=0)
    centred = members - mean
    if len(members) < 2 or not np.any(centred):
        return mean, np.zeros((members.shape[1], 0)), np.zeros(0)
    _, singular, vt = np.linalg.svd(centred, full_matrices=False)
    variances = singular**2
    keep = int(np.searchsorted(np.cumsum(variances) / variances.sum(), fraction) + 1)
    keep = min(keep, int(np.sum(variances > 1e-12 * variances[0])))
    axes = vt[:keep].T
    extents = np.max(np.abs(centred @ axes), axis=0)
    return mean, axes, extents


def fit_linear_combinations(
    vectors: np.ndarray,
    sequence_ids: np.ndarray,
    layout: HybridLayout,
    *,
    variance_fraction: float = 0.8,
    num_clusters: int = 20,
    local_variance_fraction: float = 0.95,
    floor: float = 0.0,
    seed: int = 0,
) -> LinearCombinationFit:
    """Train Ong & Gong's model on hybrid vectors (module docstring).

    Args:
        vectors: ``(frames, layout.size)`` hybrid vectors (``jaxtrack.body.make_hybrid``), in
            time order within each sequence.
        sequence_ids: ``(frames,)`` the training sequence (clip and view) of each frame.
        layout: the hybrid vector's part sizes.
        variance_fraction: global eigenvectors are kept until they explain this fraction
            (Ong & Gong: 30 eigenvectors, about 80 %).
        num_clusters: k of the k-means (Ong & Gong: 10–100).
        local_variance_fraction: each cluster keeps local eigenvectors up to this fraction.
        floor: added to every transition count before normalising U.
        seed: the k-means seeding.
    """
    vectors = np.asarray(vectors, np.float64)
    sequence_ids = np.asarray(sequence_ids)
    if vectors.ndim != 2 or vectors.shape[1] != layout.size:
        raise ValueError(f"vectors must be (frames, {layout.size}) hybrid vectors for "
                         f"num_contour={layout.num_contour}, num_skeleton={layout.num_skeleton}; "
                         f"got shape {vectors.shape}")
    if sequence_ids.shape != (len(vectors),):
        raise ValueError(f"sequence_ids must hold one id per vector ({len(vectors)}), got shape "
                         f"{sequence_ids.shape}")
    if not np.all(np.isfinite(vectors)):
        raise ValueError("vectors hold non-finite values")
    if len(vectors) < max(2, num_clusters):
        raise ValueError(f"got {len(vectors)} hybrid vectors: fitting needs at least 2 and at "
                         f"least num_clusters ({num_clusters})")
    if not 0 < variance_fraction <= 1 or not 0 < local_variance_fraction <= 1:
        raise ValueError("variance_fraction and local_variance_fraction must be in (0, 1]")
    weights = part_weights(vectors, layout)
    entry_weights = np.concatenate([np.full(2 * layout.num_contour, weights[0]),
                                    np.full(4, weights[1]),
                                    np.full(3 * layout.num_skeleton, weights[2])])
    scaled = vectors * entry_weights
    mean = scaled.mean(axis=0)
    _, singular, vt = np.linalg.svd(scaled - mean, full_matrices=False)
    variances = singular**2 / max(len(vectors) - 1, 1)
    explained = np.cumsum(variances) / variances.sum()
    keep = int(np.searchsorted(explained, variance_fraction - 1e-12) + 1)
    keep = min(keep, int(np.sum(variances > 1e-12 * variances[0])))
    basis, eigenvalues = vt[:keep].T, variances[:keep]
    coefficients = (scaled - mean) @ basis / eigenvalues  # eq. 2
    _, labels = kmeans(coefficients, num_clusters, seed=seed)
    locals_ = [_local_pca(coefficients[labels == c], local_variance_fraction)
               for c in range(num_clusters)]
    width = max(1, max(axes.shape[1] for _, axes, _ in locals_))
    local_bases = np.zeros((num_clusters, keep, width))
    local_extents = np.zeros((num_clusters, width))
    for c, (_, axes, extents) in enumerate(locals_):
        local_bases[c, :, :axes.shape[1]] = axes
        local_extents[c, :axes.shape[1]] = extents
    transition, counts, unseen = transition_matrix(labels, sequence_ids, num_clusters,
                                                   floor=floor)
    prior = np.bincount(labels, minlength=num_clusters) / len(labels)
    with jax.enable_x64(True):
        model = _model(layout, weights, mean, basis, eigenvalues, locals_, local_bases,
                       local_extents, transition, prior, coefficients, labels)
    return LinearCombinationFit(model=model, explained_variance=float(explained[keep - 1]),
                                counts=counts, unseen_rows=unseen)


def _model(layout, weights, mean, basis, eigenvalues, locals_, local_bases, local_extents,
           transition, prior, coefficients, labels) -> LinearCombinationModel:
    cast = lambda value: jnp.asarray(value, jnp.float64)  # noqa: E731
    return LinearCombinationModel(
        layout=layout, part_weights=cast(weights), mean=cast(mean), basis=cast(basis),
        eigenvalues=cast(eigenvalues), cluster_means=cast(np.array([m for m, _, _ in locals_])),
        local_bases=cast(local_bases), local_extents=cast(local_extents),
        transition=cast(transition), cluster_prior=cast(prior),
        training_coefficients=cast(coefficients),
        training_clusters=jnp.asarray(labels, jnp.int32))
