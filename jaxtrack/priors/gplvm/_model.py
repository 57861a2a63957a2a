"""A trained GPLVM: the pose mean μ(x), its variance σ²(x), the objective L′ and μ⁻¹(y).

Tian, Li & Sclaroff (2005), eqs. 2–5, with the active set I chosen by the IVM:

    μ(x)  = ȳ + Y_Iᵀ K_II⁻¹ k_I(x)                                   (eq. 3)
    σ²(x) = k(x, x) − k_I(x)ᵀ K_II⁻¹ k_I(x),  k(x, x) = α + β⁻¹        (eq. 4)
    L′(x, y) = |y − μ(x)|² / 2σ²(x) + D/2 ln σ²(x) + ½ |x|²          (eq. 2)
    μ⁻¹(y) = argmin_x L′(x, y)                                         (eq. 5)

``inverse(..., objective="reconstruction")`` is the other μ⁻¹: argmin_x ½|y − μ(x)|², the latent
point whose decoded pose is nearest (what a held-out reconstruction error asks of a manifold).

μ and σ² are written for ONE latent point so that trackers vmap them over particles.
"""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jax.custom_derivatives import SymbolicZero
from jax.dtypes import float0
from jax.scipy.linalg import cho_solve, solve_triangular
from jaxtyping import Array, ArrayLike, Float, Int

from jaxtrack.priors.gplvm._kernel import KernelParameters, kernel_matrix, rbf

__all__ = ["GPLVM", "INVERSE_OBJECTIVES", "InverseResult"]


class InverseResult(eqx.Module):
    """μ⁻¹ of a batch of poses: latents, L′ at the solution and the solver status."""

    latents: Float[Array, "poses latent"]
    objective: Float[Array, " poses"]
    result: optx.RESULTS


class GPLVM(eqx.Module):
    """A Gaussian Process Latent Variable Model with an active set (see the module docstring).

    Attributes:
        kernel: α, β, γ (log-parametrised).
        pose_mean: ``(dims,)`` ȳ, subtracted from the training poses.
        latents: ``(n, latent)`` latent position of every training pose.
        poses: ``(n, dims)`` the centred training poses (μ⁻¹ starts from their latents).
        active_indices: ``(active,)`` rows of ``latents`` in the active set I.
        active_latents, active_poses: X_I ``(active, latent)`` and centred Y_I ``(active, dims)``.
        weights: ``(active, dims)`` W in μ(x) = ȳ + k_I(x)ᵀ W; ``inverse_gram``:
            ``(active, active)`` S in σ²(x) = β⁻¹ + α − k_Iᵀ S k_I. K_II⁻¹ Y_I and K_II⁻¹ for the
            active set alone, the projected-process matrices for all poses
            (:meth:`from_active_set`).
        dynamics_std: ``(latent,)`` ν, the random-walk step std of the latent dynamics per frame
            at ``dynamics_fps`` frames per second (NaN until estimated).
    """

    kernel: KernelParameters
    pose_mean: Float[Array, " dims"]
    latents: Float[Array, "n latent"]
    poses: Float[Array, "n dims"]
    active_indices: Int[Array, " active"]
    active_latents: Float[Array, "active latent"]
    active_poses: Float[Array, "active dims"]
    weights: Float[Array, "active dims"]
    inverse_gram: Float[Array, "active active"]
    dynamics_std: Float[Array, " latent"]
    dynamics_fps: Float[Array, ""]

    @classmethod
    def from_active_set(cls, kernel: KernelParameters, poses: Float[ArrayLike, "n dims"],
                        pose_mean: Float[ArrayLike, " dims"], latents: Float[ArrayLike, "n latent"],
                        active_indices: Int[ArrayLike, " active"],
                        dynamics_std=None, dynamics_fps=float("nan"), *,
                        all_poses: bool = False) -> GPLVM:
        """Precompute ``weights`` and ``inverse_gram`` for centred ``poses`` and their latents.

        ``all_poses=False``: eqs. 3–4 on the active set, ``weights`` = K_II⁻¹ Y_I and
        ``inverse_gram`` = K_II⁻¹ (K with the noise β⁻¹ on its diagonal).

        ``all_poses=True``: the projected process (DTC; Seeger, Williams & Lawrence 2003,
        Quiñonero-Candela & Rasmussen 2005): every one of the n poses informs μ through the
        active set, at the same cost per evaluation. With K̃ the noise-free K_II and
        Σ = (K̃ + β K_IN K_NI)⁻¹,

            μ(x)  = ȳ + k_I(x)ᵀ β Σ K_IN Y
            σ²(x) = β⁻¹ + α − k_I(x)ᵀ (K̃⁻¹ − Σ) k_I(x),

        the same form as eqs. 3–4, so ``mean`` and ``variance`` are unchanged. Computed as
        Σ = L⁻ᵀ B⁻¹ L⁻¹ with K̃ = L Lᵀ and B = I + β L⁻¹ K_IN K_NI L⁻ᵀ (eigenvalues ≥ 1).
        """
        latents, poses = jnp.asarray(latents), jnp.asarray(poses)
        active_indices = jnp.asarray(active_indices)
        active_latents = latents[active_indices]
        active_poses = poses[active_indices]
        identity = jnp.eye(active_latents.shape[0], dtype=active_latents.dtype)
        if all_poses:
            # K̃ with a relative jitter of 1e-6 (GPy's for K_uu): near-duplicate active points
            # make the noise-free K_II singular, and B amplifies L⁻¹'s errors by β
            noise_free = (rbf(kernel, active_latents[:, None, :], active_latents[None, :, :])
                          + 1e-6 * kernel.alpha * identity)
            factor = jnp.linalg.cholesky(noise_free)
            cross = solve_triangular(
                factor, rbf(kernel, active_latents[:, None, :], latents[None, :, :]),
                lower=True)  # L⁻¹ K_IN
            inner = jnp.linalg.cholesky(identity + kernel.beta * cross @ cross.T)  # B
            projected = solve_triangular(factor, cho_solve((inner, True), cross @ poses),
                                         lower=True, trans=1)
            weights = kernel.beta * projected  # β L⁻ᵀ B⁻¹ L⁻¹ K_IN Y
            whitened = identity - cho_solve((inner, True), identity)  # I − B⁻¹
            inverse_gram = solve_triangular(
                factor, solve_triangular(factor, whitened, lower=True, trans=1).T,
                lower=True, trans=1)  # L⁻ᵀ (I − B⁻¹) L⁻¹
            inverse_gram = 0.5 * (inverse_gram + inverse_gram.T)
        else:
            factor = jnp.linalg.cholesky(kernel_matrix(kernel, active_latents))
            weights = cho_solve((factor, True), active_poses)
            inverse_gram = cho_solve((factor, True), identity)
        if dynamics_std is None:
            dynamics_std = jnp.full((latents.shape[1],), jnp.nan, latents.dtype)
        return cls(
            kernel=kernel, pose_mean=jnp.asarray(pose_mean), latents=latents, poses=poses,
            active_indices=active_indices, active_latents=active_latents,
            active_poses=active_poses, weights=weights, inverse_gram=inverse_gram,
            dynamics_std=jnp.asarray(dynamics_std, latents.dtype),
            dynamics_fps=jnp.asarray(dynamics_fps, latents.dtype),
        )

    @property
    def latent_dim(self) -> int:
        return self.latents.shape[1]

    @property
    def pose_dim(self) -> int:
        return self.pose_mean.shape[0]

    @property
    def active_size(self) -> int:
        return self.active_indices.shape[0]

    def astype(self, dtype) -> GPLVM:
        """The same model with every float array cast to ``dtype`` (e.g. float32 for tracking)."""
        return jax.tree.map(
            lambda leaf: leaf.astype(dtype) if jnp.issubdtype(leaf.dtype, jnp.floating) else leaf,
            self)

    def _cross(self, latent: Array) -> Array:
        return rbf(self.kernel, self.active_latents, latent[None, :])

    def mean(self, latent: Float[ArrayLike, " latent"]) -> Float[Array, " dims"]:
        """Eq. 3: μ(x) for one latent point (vmap over particles)."""
        return self.pose_mean + self._cross(jnp.asarray(latent)) @ self.weights

    def variance(self, latent: Float[ArrayLike, " latent"]) -> Float[Array, ""]:
        """Eq. 4: σ²(x) = α + β⁻¹ − k_Iᵀ K_II⁻¹ k_I, never below the noise β⁻¹."""
        return self.mean_and_variance(latent)[1]  # under jit the unused mean is dropped

    def mean_and_variance(self, latent: Float[ArrayLike, " latent"]) -> tuple[Array, Array]:
        """μ(x) and σ²(x) sharing one kernel row."""
        cross = self._cross(jnp.asarray(latent))
        explained = cross @ self.inverse_gram @ cross
        variance = self.kernel.noise_variance + jnp.maximum(self.kernel.alpha - explained, 0.0)
        return self.pose_mean + cross @ self.weights, variance

    def point_objective(self, latent: Float[ArrayLike, " latent"],
                        pose: Float[ArrayLike, " dims"]) -> Float[Array, ""]:
        """Eq. 2: L′(x, y), the negative log-posterior of one latent point given its pose."""
        latent = jnp.asarray(latent)
        mean, variance = self.mean_and_variance(latent)
        residual = jnp.asarray(pose) - mean
        return (0.5 * jnp.sum(residual**2) / variance + 0.5 * self.pose_dim * jnp.log(variance)
                + 0.5 * jnp.sum(latent**2))

    def reconstruction_objective(self, latent: Float[ArrayLike, " latent"],
                                 pose: Float[ArrayLike, " dims"]) -> Float[Array, ""]:
        """½|y − μ(x)|²: what ``inverse(..., objective="reconstruction")`` minimises."""
        return 0.5 * jnp.sum((jnp.asarray(pose) - self.mean(jnp.asarray(latent))) ** 2)

    def objective(self, name: str):
        """The per-point objective of μ⁻¹ by name: ``"posterior"`` (L′, eq. 2, whose argmin is
        eq. 5) or ``"reconstruction"``."""
        if name not in INVERSE_OBJECTIVES:
            raise ValueError(f"objective must be one of {INVERSE_OBJECTIVES}, got {name!r}")
        return self.point_objective if name == "posterior" else self.reconstruction_objective

    def initial_latents(self, poses: Float[ArrayLike, "poses dims"], grid: int = 64,
                        batch_size: int = 256, *, objective: str = "posterior"
                        ) -> Float[Array, "poses latent"]:
        """Start points for μ⁻¹: for each pose, the candidate with the lowest L′ among every
        training latent and a ``grid`` × ``grid`` lattice over their bounding box (10 % margin).

        L′ is rugged (σ² is tiny near active points and large between them), so where BFGS
        starts decides which minimum it finds. μ and σ² at the candidates do not depend on the
        pose, so L′ of every (pose, candidate) pair is one matrix product,
        L′ = (|y|² − 2 y·μ_c + |μ_c|²) / 2σ²_c + D/2 ln σ²_c + ½|x_c|², taken ``batch_size`` poses
        at a time (the training poses nearest in pose space were worse candidates: see
        docs/gplvm.md, "Inverse"). With
        ``objective="reconstruction"`` the candidates are scored by ½|y − μ_c|² instead.
        """
        self.objective(objective)  # validates the name
        poses = jnp.asarray(poses, self.active_poses.dtype)
        candidates = self.latents
        if grid > 0:
            low, high = jnp.min(candidates, axis=0), jnp.max(candidates, axis=0)
            margin = 0.1 * (high - low)
            axes = [jnp.linspace(low[i] - margin[i], high[i] + margin[i], grid)
                    for i in range(self.latent_dim)]
            lattice = jnp.stack(jnp.meshgrid(*axes), axis=-1).reshape(-1, self.latent_dim)
            candidates = jnp.concatenate([candidates, lattice.astype(candidates.dtype)])
        means, variances = jax.vmap(self.mean_and_variance)(candidates)
        if objective == "posterior":
            scale = 0.5 / variances
            offset = (scale * jnp.sum(means**2, axis=1)
                      + 0.5 * self.pose_dim * jnp.log(variances)
                      + 0.5 * jnp.sum(candidates**2, axis=1))
        else:  # ½|y − μ_c|² less the pose's own ½|y|², which does not change the argmin
            scale = jnp.full_like(variances, 0.5)
            offset = 0.5 * jnp.sum(means**2, axis=1)

        def best(pose: Array) -> Array:
            # the objective at every candidate; |y|²/2σ² is kept (σ² differs between them)
            values = scale * (jnp.sum(pose**2) - 2.0 * (means @ pose)) + offset
            return candidates[jnp.argmin(values)]

        return jax.lax.map(best, poses, batch_size=min(batch_size, poses.shape[0]))

    def inverse(self, poses: Float[ArrayLike, "poses dims"], *, max_steps: int = 64,
                initial_latents: Float[ArrayLike, "poses latent"] | None = None,
                tolerance: float | None = None, objective: str = "posterior") -> InverseResult:
        """Eq. 5: μ⁻¹(y) = argmin_x L′(x, y) for a batch of poses, one vmapped BFGS solve.

        ``objective="reconstruction"`` minimises ½|y − μ(x)|² instead. Eq. 5's D/2 ln σ²(x)
        pulls a pose towards training latents (σ² is smallest there), and the more tightly a
        model fits (small noise β⁻¹) the harder, so a tightly fitted model reconstructs
        held-out poses better through the reconstruction objective (see docs/gplvm.md,
        "Inverse"). ``InverseResult.objective`` is the chosen objective at the solution.

        The solve runs with ``throw=False`` and at most ``max_steps`` steps (a vmapped solve
        lasts as long as its slowest member); ``result`` says which poses did not converge.
        Differentiable with respect to the poses and the model by the implicit function theorem
        (optimistix's ``ImplicitAdjoint``).
        """
        poses = jnp.asarray(poses, self.active_poses.dtype)
        if poses.ndim != 2 or poses.shape[1] != self.pose_dim:
            raise ValueError(
                f"poses must have shape (num_poses, {self.pose_dim}), got {poses.shape}")
        self.objective(objective)  # validates the name
        if initial_latents is None:
            initial_latents = self.initial_latents(jax.lax.stop_gradient(poses),
                                                   objective=objective)
        initial_latents = jnp.asarray(initial_latents, poses.dtype)
        if tolerance is None:
            tolerance = 1e-8 if poses.dtype == jnp.float64 else 1e-4
        solver = optx.BFGS(rtol=tolerance, atol=tolerance)

        def solve(start: Array, pose: Array):
            solution = optx.minimise(
                lambda latent, args: _solver_objective(latent, *args, objective), solver,
                start, args=(self, pose), max_steps=max_steps, throw=False)
            return solution.value, solution.result

        latents, results = jax.vmap(solve)(initial_latents, poses)
        values = jax.vmap(self.objective(objective))(latents, poses)
        return InverseResult(latents=latents, objective=values, result=results)

    def reconstruct(self, poses: Float[ArrayLike, "poses dims"], **options) -> Array:
        """μ(μ⁻¹(y)) for a batch of poses (``options`` as for :meth:`inverse`)."""
        return jax.vmap(self.mean)(self.inverse(poses, **options).latents)


INVERSE_OBJECTIVES = ("posterior", "reconstruction")


@partial(jax.custom_jvp, nondiff_argnums=(3,))
def _solver_objective(latent: Array, model: GPLVM, pose: Array, objective: str) -> Array:
    """μ⁻¹'s objective for its BFGS (L′ or the reconstruction, by ``objective``): the same
    value, its derivative in x computed in the forward pass.

    optimistix linearises the objective and transposes the linear map inside a ``lax.cond``
    (accepted step or not). Under ``vmap`` that cond becomes a select over all its operands, so
    the model's constants in the linear map (K_II⁻¹, K_II⁻¹ Y_I) were broadcast to one copy per
    pose every step: (poses, 200, 200) and (poses, 200, D) arrays, several times the cost of
    the objective itself (docs/gplvm.md, "Inverse"). Here the linear map in x is only
    ``∇ₓL′ · ẋ``, whose residual is the (poses, latent) gradient. Tangents of the model and
    pose (implicit-function gradients of μ⁻¹) still go through the ordinary JVP of L′.
    """
    return model.objective(objective)(latent, pose)


def _is_symbolic_zero(tangent) -> bool:
    return isinstance(tangent, SymbolicZero)


def _solver_objective_jvp(objective, primals, tangents):
    latent, model, pose = primals
    latent_dot, model_dot, pose_dot = tangents
    value, gradient = jax.value_and_grad(lambda x: model.objective(objective)(x, pose))(latent)
    # (astype: a model with mixed float dtypes gives a value wider than the latent)
    tangent = (jnp.zeros_like(value) if _is_symbolic_zero(latent_dot)
               else jnp.dot(gradient, latent_dot).astype(value.dtype))
    others = jax.tree.leaves((model_dot, pose_dot), is_leaf=_is_symbolic_zero)
    if not all(_is_symbolic_zero(leaf) for leaf in others):
        def instantiate(primal, dot):
            if not _is_symbolic_zero(dot):
                return dot
            dtype = primal.dtype if jnp.issubdtype(primal.dtype, jnp.inexact) else float0
            return np.zeros(primal.shape, dtype) if dtype is float0 else jnp.zeros_like(primal)

        model_dot = jax.tree.map(instantiate, model, model_dot, is_leaf=_is_symbolic_zero)
        pose_dot = instantiate(pose, pose_dot)
        _, other = jax.jvp(lambda m, y: m.objective(objective)(latent, y), (model, pose),
                           (model_dot, pose_dot))
        tangent = tangent + other.astype(value.dtype)
    return value, tangent


_solver_objective.defjvp(_solver_objective_jvp, symbolic_zeros=True)
