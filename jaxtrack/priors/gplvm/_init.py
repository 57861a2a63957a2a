"""Initial latent positions: Isomap (Tenenbaum, de Silva & Langford 2000) or PCA.

Isomap builds a k-nearest-neighbour graph of the poses, takes geodesic distances as shortest
paths through it (``scipy.sparse.csgraph``) and embeds them by classical MDS. Beyond
``max_landmarks`` poses it is landmark Isomap (de Silva & Tenenbaum 2003): shortest paths from
a random subset of landmarks only, the rest placed by distance-based triangulation. A graph in
several pieces has no geodesic distances between them; the neighbourhood is then widened (up to
four times) and, if the graph stays disconnected, PCA is used and the reason is reported.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import eigh
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, shortest_path
from scipy.spatial import cKDTree

__all__ = ["isomap", "pca", "initial_latents"]


def pca(poses: np.ndarray, latent_dim: int) -> np.ndarray:
    """Principal-component scores ``(n, latent_dim)`` of ``poses`` (centred inside)."""
    centred = poses - poses.mean(axis=0)
    _, _, components = np.linalg.svd(centred, full_matrices=False)
    return centred @ components[:latent_dim].T


def _neighbour_graph(poses: np.ndarray, neighbours: int) -> csr_matrix:
    distances, indices = cKDTree(poses).query(poses, k=neighbours + 1)
    n = poses.shape[0]
    rows = np.repeat(np.arange(n), neighbours)
    graph = csr_matrix((distances[:, 1:].ravel(), (rows, indices[:, 1:].ravel())), shape=(n, n))
    return graph.maximum(graph.T)  # symmetric: i ~ j if either is among the other's neighbours


def _classical_mds(squared: np.ndarray, latent_dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Classical MDS of an ``(L, L)`` squared-distance matrix: coordinates and the pseudo-inverse
    map used to place further points (landmark MDS)."""
    count = squared.shape[0]
    # double centring −½ J D² J written with means (J D² J as two dense products costs O(L³))
    means = squared.mean(axis=0)
    gram = -0.5 * (squared - means[:, None] - means[None, :] + means.mean())
    # only the top latent_dim eigenpairs (all of a 1 000 × 1 000 matrix took 1.6 s)
    count_top = min(latent_dim, count)
    values, vectors = eigh(gram, subset_by_index=[count - count_top, count - 1])
    order = np.argsort(values)[::-1]
    values = np.maximum(values[order], 1e-12)
    vectors = vectors[:, order]
    return vectors * np.sqrt(values), vectors / np.sqrt(values)


def isomap(poses: np.ndarray, latent_dim: int, *, neighbours: int = 10,
           max_landmarks: int = 1000, seed: int = 0) -> tuple[np.ndarray | None, str]:
    """Isomap coordinates ``(n, latent_dim)``, or ``None`` and the reason when the graph is
    disconnected even with four times ``neighbours``."""
    n = poses.shape[0]
    for k in (neighbours, 2 * neighbours, 4 * neighbours):
        k = min(k, n - 1)
        graph = _neighbour_graph(poses, k)
        components, _ = connected_components(graph, directed=False)
        if components == 1:
            break
    else:
        return None, f"neighbour graph has {components} components even with k = {k}"
    rng = np.random.default_rng(seed)
    landmarks = np.arange(n) if n <= max_landmarks else np.sort(
        rng.choice(n, max_landmarks, replace=False))
    geodesic = shortest_path(graph, method="D", directed=False, indices=landmarks)
    squared = geodesic**2  # (landmarks, n)
    coordinates, pseudo_inverse = _classical_mds(squared[:, landmarks], latent_dim)
    if len(landmarks) == n:
        return coordinates, f"isomap (k = {k})"
    # landmark MDS triangulation: x = −½ L# (δ² − mean landmark δ²)
    mean_squared = squared[:, landmarks].mean(axis=1)
    placed = -0.5 * (squared - mean_squared[:, None]).T @ pseudo_inverse
    return placed, f"landmark isomap (k = {k}, {len(landmarks)} landmarks)"


def initial_latents(poses: np.ndarray, latent_dim: int, method: str = "isomap", *,
                    neighbours: int = 10, seed: int = 0) -> tuple[np.ndarray, str]:
    """Initial X, scaled so its first coordinate has unit standard deviation, and how it was
    made (``"isomap (k = 10)"``, ``"pca"``, ``"pca (isomap: graph has 3 components ...)"``)."""
    if method not in ("isomap", "pca"):
        raise ValueError(f"init must be 'isomap' or 'pca', got {method!r}")
    poses = np.asarray(poses, np.float64)
    latents, description = None, "pca"
    if method == "isomap":
        latents, reason = isomap(poses, latent_dim, neighbours=neighbours, seed=seed)
        description = reason if latents is not None else f"pca (isomap failed: {reason})"
    if latents is None:
        latents = pca(poses, latent_dim)
    latents = latents - latents.mean(axis=0)
    return latents / max(float(latents[:, 0].std()), 1e-12), description
