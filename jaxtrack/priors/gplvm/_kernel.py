"""The GPLVM's RBF kernel and its objectives (Tian, Li & Sclaroff 2005, eqs. 1–4).

k(x, x′) = α exp(−γ/2 |x − x′|²) + δ(x, x′) β⁻¹, with α (signal variance), β (inverse noise
variance) and γ (inverse squared length scale) kept positive by storing their logarithms.
"""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg
from jax.scipy.linalg import cho_solve
from jaxtyping import Array, Float

__all__ = [
    "KernelParameters",
    "active_objective",
    "exact_objective",
    "gaussian_process_term",
    "kernel_matrix",
    "rbf",
    "squared_distances",
]

# From this many points on (the exact GPLVM's sizes) K is built elementwise and eq. 1's
# gradient takes K⁻¹ from LAPACK's potri (13–15 % and ~22 % faster per step at n = 1 000).
# Smaller active sets keep the arithmetic that the tracking protocol's priors were trained and
# validated with: the two differ only in rounding, but Algorithm 1's BFGS and IVM turn rounding
# into a different prior (the protocol's three priors with both changes: 86.2 % of frames
# within 15 % of the torso, against 98.7 % without, on one machine).
FAST_SIZE = 512

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
    reduces an axis of length 2, which XLA on CPU does several times slower (docs/gplvm.md,
    "Speed of the kernel"). Same value, same rounding, any dtype, differentiable.
    """
    if x1.shape[-1] != x2.shape[-1]:
        raise ValueError(f"latent points of different dimensions: {x1.shape} and {x2.shape}")
    squares = [(x1[..., axis] - x2[..., axis]) ** 2 for axis in range(x1.shape[-1])]
    return sum(squares[1:], squares[0])


def kernel_matrix(kernel: KernelParameters, latents: Float[Array, "n latent"]) -> Array:
    """K with the noise (and a small relative jitter) on the diagonal, ``(n, n)``."""
    if latents.shape[0] >= FAST_SIZE:
        # elementwise (one fused pass, exact zeros on the diagonal), not |x|² + |x′|² − 2 x·x′:
        # that dot of inner dimension 2 and the clamp cost 3× the fusion (~14 of ~80 ms in
        # eq. 1's gradient at n = 1 000)
        gram = rbf(kernel, latents[:, None, :], latents[None, :, :])
    else:
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


def _cholesky_inverse(factor: Float[Array, "n n"]) -> Array:
    """K⁻¹ = L⁻ᵀ L⁻¹ by two triangular solves (2n³ flops)."""
    return cho_solve((factor, True), jnp.eye(factor.shape[0], dtype=factor.dtype))


def _lapack_inverse(bits, dtype) -> np.ndarray:
    # bits: U = Lᵀ in C order (= L in Fortran order, what LAPACK reads without a copy), as words
    upper = np.ascontiguousarray(bits).view(dtype).reshape(bits.shape[:2])
    potri = scipy.linalg.lapack.get_lapack_funcs("potri", (upper,))
    inverse, info = potri(upper.T, lower=True)  # K⁻¹ in the lower triangle, Fortran order
    if info != 0:  # a factor from a successful Cholesky has a positive diagonal
        inverse = np.full_like(upper, np.nan)
    # in C order the transpose holds K⁻¹ in its upper triangle; the caller symmetrises
    return np.ascontiguousarray(inverse.T, dtype).view(np.int32).reshape(bits.shape)


def _inverse_upper(factor: Float[Array, "n n"]) -> Array:
    """A matrix whose upper triangle (diagonal included) is K⁻¹, from K's lower factor L.

    On CPU by LAPACK's potri through a host callback: 2n³/3 flops, where ``cho_solve(L, I)``
    (two triangular solves with n right-hand sides, what XLA offers) costs 2n³ (timings:
    docs/gplvm.md, "Speed of the kernel"). The strict lower triangle is
    then left over from L. Elsewhere (GPU) the whole K⁻¹ by ``cho_solve``.

    The factor goes to LAPACK as Lᵀ (XLA's Cholesky leaves L column-major, so Lᵀ row-major is
    the same memory) and comes back as one triangle. Both travel as 32-bit words: JAX casts
    float64 callback arguments and results to float32 unless x64 is enabled in the thread that
    runs the callback, and ``jax.enable_x64`` (how training enables it) is a context of the
    calling thread only.
    """
    dtype = jnp.dtype(factor.dtype)

    def host(factor):
        bits = jax.lax.bitcast_convert_type(factor.T, jnp.int32)
        bits = bits.reshape(*factor.shape, -1)  # (n, n, words)
        shape = jax.ShapeDtypeStruct(bits.shape, jnp.int32)
        bits = jax.pure_callback(partial(_lapack_inverse, dtype=dtype), shape, bits,
                                 vmap_method="sequential")
        return jax.lax.bitcast_convert_type(bits if bits.shape[-1] > 1 else bits[..., 0], dtype)

    return jax.lax.platform_dependent(factor, cpu=host, default=_cholesky_inverse)


def inverse_from_factor(factor: Float[Array, "n n"]) -> Array:
    """K⁻¹ from the lower Cholesky factor L of K (LAPACK's potri on CPU, see
    :func:`_inverse_upper`), symmetrised here where XLA can fuse it into its consumer."""
    upper = _inverse_upper(factor)
    return jnp.triu(upper) + jnp.triu(upper, 1).T


def _term_backward(residuals, cotangent):
    factor, solved = residuals
    inverse = (inverse_from_factor if factor.shape[0] >= FAST_SIZE else _cholesky_inverse)(factor)
    gram_cotangent = 0.5 * (solved.shape[1] * inverse - solved @ solved.T)
    return cotangent * gram_cotangent, cotangent * solved


gaussian_process_term.defvjp(_term_forward, _term_backward)


def active_objective(kernel: KernelParameters, latents: Float[Array, "n latent"],
                     poses: Float[Array, "n dims"]) -> Array:
    """Eq. 1: L = D/2 ln|K| + ½ Σ_m Y_mᵀ K⁻¹ Y_m + ½ Σ_i |x_i|² (poses centred).

    From ``FAST_SIZE`` points on (the exact GPLVM) through :func:`exact_objective`, whose
    gradient is written out; the value is the same either way.
    """
    if latents.shape[0] >= FAST_SIZE:
        return exact_objective(kernel, latents, poses)
    return gaussian_process_term(kernel_matrix(kernel, latents), poses) + 0.5 * jnp.sum(latents**2)


@jax.custom_vjp
def exact_objective(kernel: KernelParameters, latents: Float[Array, "n latent"],
                    poses: Float[Array, "n dims"]) -> Array:
    """Eq. 1 with its gradient in closed form, for large n (the exact GPLVM).

    With G = ∂L/∂K = ½(D K⁻¹ − AAᵀ), A = K⁻¹Y, and W = G ∘ αE (E_ij = exp(−γ/2 |x_i − x_j|²),
    symmetric), the chain rule through K gives
        ∂L/∂x_i     = −2γ Σ_j W_ij (x_i − x_j) + x_i
        ∂L/∂ln α    = Σ_ij W_ij + jitter · α tr G
        ∂L/∂ln β    = −β⁻¹ tr G
        ∂L/∂ln γ    = −γ/2 Σ_ij W_ij |x_i − x_j|²
    which reads K⁻¹ in one triangle, straight from LAPACK's potri (:func:`_inverse_upper`), in
    one fused pass and two (n × 3) products: no symmetrised K⁻¹ and no K cotangent are built,
    where :func:`gaussian_process_term`'s VJP into :func:`kernel_matrix` builds both (timings:
    docs/gplvm.md, "Speed of the kernel"). Agrees with autodiff through the Cholesky to ~1e-12.
    """
    value, _ = _exact_forward(kernel, latents, poses)
    return value


def _exact_forward(kernel, latents, poses):
    value, (factor, solved) = _term_forward(kernel_matrix(kernel, latents), poses)
    return value + 0.5 * jnp.sum(latents**2), (kernel, latents, factor, solved)


def _exact_backward(residuals, cotangent):
    kernel, latents, factor, solved = residuals
    n, dims = solved.shape
    upper = _inverse_upper(factor)  # K⁻¹ in the upper triangle
    rows = jax.lax.broadcasted_iota(jnp.int32, (n, n), 0)
    columns = jax.lax.broadcasted_iota(jnp.int32, (n, n), 1)
    squared = squared_distances(latents[:, None, :], latents[None, :, :])
    gram_gradient = 0.5 * (dims * upper - solved @ solved.T)
    # W over the strict upper triangle (the diagonal's part cancels in ∂L/∂x, the rest below)
    weights = jnp.where(rows < columns,
                        gram_gradient * (kernel.alpha * jnp.exp(-0.5 * kernel.gamma * squared)),
                        0.0)
    trace = 0.5 * jnp.sum(dims * jnp.diagonal(upper) - jnp.sum(solved**2, axis=1))  # tr G
    # Σ_j W_ij (x_j, 1) over both triangles
    augmented = jnp.concatenate([latents, jnp.ones_like(latents[:, :1])], axis=1)
    sums = weights @ augmented + weights.T @ augmented
    d_latents = -2.0 * kernel.gamma * (latents * sums[:, -1:] - sums[:, :-1]) + latents
    d_kernel = KernelParameters(
        log_alpha=2.0 * jnp.sum(weights) + (1.0 + JITTER) * kernel.alpha * trace,
        log_beta=-kernel.noise_variance * trace,
        log_gamma=-kernel.gamma * jnp.sum(weights * squared))
    d_kernel = jax.tree.map(lambda leaf: cotangent * leaf, d_kernel)
    return d_kernel, cotangent * d_latents, cotangent * solved


exact_objective.defvjp(_exact_forward, _exact_backward)
