"""The GPLVM's RBF kernel and its objectives (Tian, Li & Sclaroff 2005, eqs. 1–4).

k(x, x′) = α exp(−γ/2 |x − x′|²) + δ(x, x′) β⁻¹, with α (signal variance), β (inverse noise
variance) and γ (inverse squared length scale) kept positive by storing their logarithms.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.scipy.linalg import cho_solve
from jaxtyping import Array, Float

__all__ = [
    "KernelParameters",
    "active_objective",
    "gaussian_process_term",
    "kernel_matrix",
    "rbf",
    "squared_distances",
]

# Relative diagonal jitter added to K before its Cholesky factor: far below the noise β⁻¹ of
# any sensible fit, large enough that duplicated latent points do not break the factorisation.
JITTER = 1e-8


class KernelParameters(eqx.Module):
    """Log-parametrised RBF kernel hyperparameters (scalars, any float dtype)."""

    log_alpha: Float[Array, ""]
    log_beta: Float[Array, ""]
    log_gamma: Float[Array, ""]

    @property
    def alpha(self) -> Array:
        return jnp.exp(self.log_alpha)

    @property
    def beta(self) -> Array:
        return jnp.exp(self.log_beta)

    @property
    def gamma(self) -> Array:
        return jnp.exp(self.log_gamma)

    @property
    def noise_variance(self) -> Array:
        return jnp.exp(-self.log_beta)

    @classmethod
    def create(cls, alpha: float, beta: float, gamma: float, dtype=jnp.float64
               ) -> KernelParameters:
        return cls(*(jnp.log(jnp.asarray(value, dtype)) for value in (alpha, beta, gamma)))


def rbf(kernel: KernelParameters, x1: Float[Array, "... latent"],
        x2: Float[Array, "... latent"]) -> Array:
    """Noise-free part α exp(−γ/2 |x1 − x2|²), broadcasting over leading axes."""
    return kernel.alpha * jnp.exp(-0.5 * kernel.gamma * squared_distances(x1, x2))


def squared_distances(x1: Float[Array, "... latent"], x2: Float[Array, "... latent"]) -> Array:
    """|x1 − x2|² over the last axis, broadcasting over the leading ones.

    Written out coordinate by coordinate (the latent space has 2 or 3 of them): one fused
    elementwise pass, where ``sum((x1 − x2)², axis=-1)`` builds a ``(..., latent)`` array and
    reduces an axis of length 2, which XLA on CPU does ~5× slower (μ of 200 particles: 0.6 →
    0.2 ms). Same value, same rounding, any dtype, differentiable.
    """
    if x1.shape[-1] != x2.shape[-1]:
        raise ValueError(f"latent points of different dimensions: {x1.shape} and {x2.shape}")
    squares = [(x1[..., axis] - x2[..., axis]) ** 2 for axis in range(x1.shape[-1])]
    return sum(squares[1:], squares[0])


def kernel_matrix(kernel: KernelParameters, latents: Float[Array, "n latent"]) -> Array:
    """K with the noise (and a small relative jitter) on the diagonal, ``(n, n)``."""
    squared = jnp.sum(latents**2, axis=-1)
    distances = squared[:, None] + squared[None, :] - 2.0 * latents @ latents.T
    gram = kernel.alpha * jnp.exp(-0.5 * kernel.gamma * jnp.maximum(distances, 0.0))
    diagonal = kernel.noise_variance + JITTER * kernel.alpha
    return gram + diagonal * jnp.eye(latents.shape[0], dtype=latents.dtype)


@jax.custom_vjp
def gaussian_process_term(gram: Float[Array, "n n"], poses: Float[Array, "n dims"]) -> Array:
    """D/2 ln|K| + ½ tr(K⁻¹ Y Yᵀ), the data part of eq. 1, through a Cholesky factor of K.

    Its gradient is the closed form ∂/∂K = ½(D K⁻¹ − K⁻¹ Y Yᵀ K⁻¹) (a custom VJP): autodiff
    through the Cholesky costs several times the forward pass, this costs about one.
    """
    value, _ = _term_forward(gram, poses)
    return value


def _term_forward(gram, poses):
    factor = jnp.linalg.cholesky(gram)
    solved = cho_solve((factor, True), poses)  # K⁻¹ Y
    log_determinant = 2.0 * jnp.sum(jnp.log(jnp.diagonal(factor)))
    value = 0.5 * poses.shape[1] * log_determinant + 0.5 * jnp.sum(poses * solved)
    return value, (factor, solved)


def _term_backward(residuals, cotangent):
    factor, solved = residuals
    inverse = cho_solve((factor, True), jnp.eye(factor.shape[0], dtype=factor.dtype))
    gram_cotangent = 0.5 * (solved.shape[1] * inverse - solved @ solved.T)
    return cotangent * gram_cotangent, cotangent * solved


gaussian_process_term.defvjp(_term_forward, _term_backward)


def active_objective(kernel: KernelParameters, latents: Float[Array, "n latent"],
                     poses: Float[Array, "n dims"]) -> Array:
    """Eq. 1: L = D/2 ln|K| + ½ Σ_m Y_mᵀ K⁻¹ Y_m + ½ Σ_i |x_i|² (poses centred)."""
    return gaussian_process_term(kernel_matrix(kernel, latents), poses) + 0.5 * jnp.sum(latents**2)
