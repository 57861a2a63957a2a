"""Informative Vector Machine active-set selection (Lawrence, Seeger & Herbrich 2003).

For GP regression with Gaussian noise the entropy reduction of including point j is
ΔH_j = ½ ln(1 + β ς_j), where ς_j is j's current posterior variance; the greedy IVM therefore
adds, one at a time, the point of largest posterior variance and updates every variance with a
rank-one step. The updates are the rows of a pivoted Cholesky factor of K + β⁻¹I, built column
by column from the kernel, so the cost is O(active² · n) time and O(active · n) memory.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from jaxtrack.priors.gplvm._kernel import KernelParameters, rbf

__all__ = ["entropy_reductions", "select_active_set"]


def _select(kernel: KernelParameters, latents: Array, active_size: int):
    n = latents.shape[0]
    noise = kernel.noise_variance
    dtype = latents.dtype

    def add_point(i, carry):
        variances, factor_rows, chosen, gains, selected = carry
        # IVM criterion: ΔH_j = ½ ln(1 + β ς_j); already chosen points are excluded.
        gain = jnp.where(selected, -jnp.inf, 0.5 * jnp.log1p(variances / noise))
        j = jnp.argmax(gain)
        column = rbf(kernel, latents, latents[j][None, :])
        column = column - factor_rows.T @ factor_rows[:, j]
        row = column / jnp.sqrt(variances[j] + noise)
        return (variances - row**2, factor_rows.at[i].set(row),
                chosen.at[i].set(j.astype(jnp.int32)), gains.at[i].set(gain[j]),
                selected.at[j].set(True))

    variances = jnp.full((n,), kernel.alpha, dtype)
    rows = jnp.zeros((active_size, n), dtype)
    chosen = jnp.full((active_size,), -1, jnp.int32)
    gains = jnp.zeros((active_size,), dtype)
    selected = jnp.zeros((n,), bool)
    _, _, chosen, gains, _ = jax.lax.fori_loop(
        0, active_size, add_point, (variances, rows, chosen, gains, selected))
    return chosen, gains


_select_jit = jax.jit(_select, static_argnums=2)


def select_active_set(kernel: KernelParameters, latents: Float[Array, "n latent"],
                      active_size: int) -> Int[Array, " active"]:
    """Greedy IVM selection of ``active_size`` rows of ``latents`` (in order of selection)."""
    n = latents.shape[0]
    if not 0 < active_size <= n:
        raise ValueError(f"active_size must be in [1, {n}] (the number of poses), "
                         f"got {active_size}")
    chosen, _ = _select_jit(kernel, jnp.asarray(latents), int(active_size))
    return chosen


def entropy_reductions(kernel: KernelParameters, latents: Float[Array, "n latent"],
                       active_size: int) -> Float[Array, " active"]:
    """ΔH of each point at the moment the IVM added it (non-increasing for a greedy choice)."""
    _, gains = _select_jit(kernel, jnp.asarray(latents), int(active_size))
    return gains
