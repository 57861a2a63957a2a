"""The body-part likelihood of Kwatra, Bobick & Johnson (2002, eq. 4–7): a truncated Gaussian of
the distances between a particle's parts and its posture's part hypotheses.

A particle holds a posture q and part positions x = (x_1 … x_P) (head, two hands, two feet). The
frame's observation is every posture's hypotheses Z = {z^q' : q' ∈ Q}
(:mod:`jaxtrack.vision.parts`).
Only the hypotheses of the particle's own posture say anything about x; the others contribute a
constant k each (eq. 5–6):

    p(Z | x, q) = k^{|Q|−1} p(z^q | x, q),    p(z^q | x, q) = exp(−Σ_i f(i))          (eq. 4, 7)
    f(i) = min(δ, (z_i^q − x_i)ᵀ R_i⁻¹ (z_i^q − x_i))

The cutoff δ keeps one wrong hypothesis (a hand the heuristics put on a knee) from vetoing an
otherwise good particle. This likelihood is not one of the appearance templates of
:mod:`jaxtrack.likelihoods._base`: it reads hypotheses, not pixels. See ``docs/mixed-state.md``.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

__all__ = ["PartDistances", "part_distance_terms"]


def part_distance_terms(parts: Float[Array, "parts 2"], hypotheses: Float[Array, "parts 2"],
                        inverse_covariances: Float[Array, "parts 2 2"],
                        cutoff: Float[Array, ""]) -> Float[Array, " parts"]:
    """f(i) = min(δ, dᵢᵀ Rᵢ⁻¹ dᵢ), dᵢ = zᵢ − xᵢ (eq. 7), for every part."""
    difference = hypotheses - parts
    distance = jnp.einsum("pi,pij,pj->p", difference, inverse_covariances, difference)
    return jnp.minimum(distance, cutoff)


class PartDistances(eqx.Module):
    """log p(Z | x, q) of eq. 4–7 for one particle.

    Attributes:
        inverse_covariances: ``(parts, 2, 2)`` R_i⁻¹ (pixels⁻²).
        cutoff: δ.
        log_k: log k, the constant likelihood of another posture's hypotheses.
    """

    inverse_covariances: Float[Array, "parts 2 2"]
    cutoff: Float[Array, ""]
    log_k: Float[Array, ""]

    def __init__(self, standard_deviations: Float[ArrayLike, " parts"] = (8.0, 12.0, 12.0, 10.0,
                                                                           10.0),
                 cutoff: float = 25.0, log_k: float = 0.0):
        """Isotropic R_i = σ_i² I from per-part standard deviations in pixels (head, hands,
        feet), the cutoff δ and log k. δ = 25 (a hypothesis pulls a part from up to 5 σ away)
        is chosen on the validation clips with the tracker's other settings (``python -m
        papers.kwatra2002.mixed_state_evaluation``, 2026-11-27: smoothed MSE over all parts
        5 482 px² against 5 701 at δ = 9 and 5 740 at δ = 100, parts re-drawn on a posture
        switch, one tracker seed each; papers/kwatra2002/history.md)."""
        sigma = np.asarray(standard_deviations, np.float64)
        if sigma.ndim != 1 or not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
            raise ValueError(f"standard_deviations must be a 1-D array of positive pixels, got "
                             f"{sigma}")
        if not (np.isfinite(cutoff) and cutoff > 0):
            raise ValueError(f"cutoff must be positive and finite, got {cutoff}")
        self.inverse_covariances = jnp.asarray(np.eye(2)[None] / sigma[:, None, None] ** 2)
        self.cutoff = jnp.asarray(float(cutoff))
        self.log_k = jnp.asarray(float(log_k))

    @property
    def num_parts(self) -> int:
        return self.inverse_covariances.shape[0]

    def log_likelihood(self, posture: Int[Array, ""], parts: Float[Array, "parts 2"],
                       hypotheses: Float[Array, "postures parts 2"]) -> Float[Array, ""]:
        """log p(Z | x, q) (eq. 4): −Σ_i f(i) for the posture's own hypotheses + (|Q| − 1) log k."""
        own = hypotheses[posture]
        terms = part_distance_terms(parts, own, self.inverse_covariances, self.cutoff)
        return -jnp.sum(terms) + (hypotheses.shape[0] - 1) * self.log_k
