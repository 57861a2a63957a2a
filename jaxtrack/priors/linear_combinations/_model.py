"""A trained linear-combination model: global PCA, cluster constraints and cluster dynamics.

Ong & Gong (2002), §3–4, on Bowden et al.'s hybrid vectors (``jaxtrack.body.hybrid``), each
part scaled by one weight so that contour pixels and skeleton metres count alike:

    t = w ⊙ v                                  the scaled hybrid vector (``scale``)
    a_j = Σ_i e_ji (t_i − m_i) / λ_j            global coefficients (eq. 2)
    t = m + Σ_j λ_j a_j e_j                     reconstruction (eq. 7)
    r = clip(P_bᵀ (s − μ_b) / Λ_b, −1, 1)       cluster b's eigen-coordinates, clamped (eq. 5)
    s = μ_b + P_b Λ_b r                         back in the coefficient space (eq. 6)

λ_j are the global PCA's eigenvalues (variances); μ_b, P_b are cluster b's mean and local
eigenvectors in the coefficient space, and Λ_b the cluster's extent along each of them: the
largest |projection| of the cluster's training members, so the ±1 box is the smallest box in
P_b's axes that holds every training member. U (``transition``) is the matrix of cluster
transitions counted over consecutive training frames (§4.1). Why each choice:
``docs/linear-combination.md``.

Every method is written for ONE vector or particle; trackers vmap them.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from jaxtrack.body.hybrid import HybridLayout

__all__ = ["LinearCombinationModel"]


class LinearCombinationModel(eqx.Module):
    """Global PCA of hybrid vectors, k-means clusters with local PCA, cluster transitions.

    Attributes:
        layout: sizes of the hybrid vector's parts (static).
        part_weights: ``(3,)`` weight of the contour, hands and skeleton entries.
        mean: ``(vector,)`` m, mean scaled hybrid vector.
        basis: ``(vector, components)`` e_j, global eigenvectors (columns).
        eigenvalues: ``(components,)`` λ_j.
        cluster_means: ``(clusters, components)`` μ_i.
        local_bases: ``(clusters, components, local)`` P_i (zero columns pad a cluster with
            fewer local eigenvectors than ``local``).
        local_extents: ``(clusters, local)`` Λ_i (zero on padded columns).
        transition: ``(clusters, clusters)`` U, row a = p(next cluster | cluster a).
        cluster_prior: ``(clusters,)`` share of training frames in each cluster.
        training_coefficients: ``(examples, components)`` every training vector's coefficients.
        training_clusters: ``(examples,)`` every training vector's cluster.
    """

    layout: HybridLayout
    part_weights: Float[Array, " 3"]
    mean: Float[Array, " vector"]
    basis: Float[Array, "vector components"]
    eigenvalues: Float[Array, " components"]
    cluster_means: Float[Array, "clusters components"]
    local_bases: Float[Array, "clusters components local"]
    local_extents: Float[Array, "clusters local"]
    transition: Float[Array, "clusters clusters"]
    cluster_prior: Float[Array, " clusters"]
    training_coefficients: Float[Array, "examples components"]
    training_clusters: Int[Array, " examples"]

    @property
    def num_components(self) -> int:
        return self.basis.shape[1]

    @property
    def num_clusters(self) -> int:
        return self.cluster_means.shape[0]

    def weights(self) -> Float[Array, " vector"]:
        """The per-entry weight ``w`` of a hybrid vector (its parts' weights repeated)."""
        layout = self.layout
        return jnp.concatenate([
            jnp.full((2 * layout.num_contour,), self.part_weights[0]),
            jnp.full((4,), self.part_weights[1]),
            jnp.full((3 * layout.num_skeleton,), self.part_weights[2])])

    def coefficients(self, vector: Float[Array, " vector"]) -> Float[Array, " components"]:
        """Global coefficients of one hybrid vector (Ong & Gong eq. 2: a_j = e_jᵀ(t − m)/λ_j)."""
        scaled = vector * self.weights()
        return (self.basis.T @ (scaled - self.mean)) / self.eigenvalues

    def reconstruct(self, coefficients: Float[Array, " components"]) -> Float[Array, " vector"]:
        """The hybrid vector of global coefficients (Ong & Gong eq. 7: t = m + Σ_j λ_j a_j e_j)."""
        scaled = self.mean + self.basis @ (self.eigenvalues * coefficients)
        return scaled / self.weights()

    def cluster_coordinates(self, coefficients: Float[Array, " components"],
                            cluster: Int[Array, ""]) -> Float[Array, " local"]:
        """Cluster ``cluster``'s eigen-coordinates of ``coefficients``, unclamped
        (Ong & Gong eq. 5 before the clip: P_bᵀ(s − μ_b)/Λ_b; 0 on padded axes)."""
        extents = self.local_extents[cluster]
        projection = self.local_bases[cluster].T @ (coefficients - self.cluster_means[cluster])
        return jnp.where(extents > 0, projection / jnp.where(extents > 0, extents, 1.0), 0.0)

    def constrain(self, coefficients: Float[Array, " components"],
                  cluster: Int[Array, ""]) -> Float[Array, " components"]:
        """``coefficients`` held inside cluster ``cluster``'s box.

        Ong & Gong eq. 5: r = clip(P_bᵀ(s − μ_b)/Λ_b, −1, 1); eq. 6: s = μ_b + P_b Λ_b r. The
        part of ``s`` outside the cluster's local subspace is dropped by eq. 6.
        """
        # Ong & Gong eq. (5): clamp to the cluster's ±1 box
        clamped = jnp.clip(self.cluster_coordinates(coefficients, cluster), -1.0, 1.0)
        # Ong & Gong eq. (6): back into the coefficient space
        return self.cluster_means[cluster] + self.local_bases[cluster] @ (
            self.local_extents[cluster] * clamped)

    def astype(self, dtype) -> LinearCombinationModel:
        """The model with its float arrays in ``dtype`` (the tracker's float type)."""
        import jax

        return jax.tree.map(lambda leaf: leaf.astype(dtype)
                            if jnp.issubdtype(leaf.dtype, jnp.floating) else leaf, self)
