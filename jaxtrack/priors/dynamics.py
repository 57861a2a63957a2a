"""Dynamics every tracker can take: how a pose or a latent point moves from frame to frame.

* :class:`AR2Dynamics` — diagonal second-order auto-regression, Tian, Li & Sclaroff's (2005, §5)
  CONDENSATION baseline ("second-order auto-regressive dynamics learned from the first 30
  frames"), learned by :func:`fit_ar2`; :func:`random_walk_dynamics` is its A₁ = I, A₂ = 0 case.
* :class:`LatentWalk` — Tian et al.'s random walk in the GPLVM's latent space (§4, eq. 6:
  ``x_{t+1} = x_t + ω``, ``ω ~ N(0, diag ν²)``) with jumps to training latents (the mixture
  ``(1 − ε) N(x, ν²) + ε p̂(x)``, like Ong & Gong's jumps between clusters), and a random walk
  of the SPM placement.
* :class:`LatentVelocity` — a second-order alternative to the random walk in the latent space,
  ``x_{t+1} = x_t + a (x_t − x_{t−1}) + ω``, learned from the training latents'
  trajectories by :func:`fit_latent_velocity` (the linear-kernel case of Wang, Fleet &
  Hertzmann's GPDM dynamics, learned after the GPLVM rather than with it).
* :func:`constant_velocity` — the MHT baseline's prediction ``x + v (x − x_prev)``.

Reasoning and measurements: ``docs/trackers.md``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special as jsp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPM_STATE_SIZE

__all__ = ["AR2Dynamics", "DEFAULT_RIDGE", "LatentVelocity", "LatentWalk", "constant_velocity",
           "default_noise_floor", "fit_ar2", "fit_latent_velocity", "random_walk_dynamics",
           "step_std_within"]

DEFAULT_RIDGE = 1e-4
"""Relative ridge of :func:`fit_ar2`: the penalty is this fraction of the lag Gram matrix's mean
diagonal, so it is unit-free and the same for pixels and radians. The lags of a smooth
trajectory are nearly collinear (x_{t−1} ≈ x_{t−2}), so even this little damps an oscillation
a bit (a sine of 0.2 rad/frame over 30 frames: root modulus 1 → 0.997; 1e-3 gives 0.97)."""


class AR2Dynamics(eqx.Module):
    """Diagonal second-order auto-regressive dynamics ``x_t = A₁ x_{t−1} + A₂ x_{t−2} + d + w``.

    Attributes:
        first_coefficients: ``(state,)`` the diagonal of A₁.
        second_coefficients: ``(state,)`` the diagonal of A₂.
        offset: ``(state,)`` d.
        noise_std: ``(state,)`` standard deviations of w (the square root of diag Q).
    """

    first_coefficients: Float[Array, " state"]
    second_coefficients: Float[Array, " state"]
    offset: Float[Array, " state"]
    noise_std: Float[Array, " state"]

    def predict(self, current: Float[Array, " state"], previous: Float[Array, " state"]
                ) -> Float[Array, " state"]:
        """The noise-free prediction ``A₁ x_{t−1} + A₂ x_{t−2} + d``."""
        return self.first_coefficients * current + self.second_coefficients * previous + self.offset

    def sample(self, key: PRNGKeyArray, current: Float[Array, " state"],
               previous: Float[Array, " state"]) -> Float[Array, " state"]:
        """One draw of x_t given ``current = x_{t−1}`` and ``previous = x_{t−2}``."""
        noise = smc.fast_normal(key, current.shape, current.dtype)
        return self.predict(current, previous) + self.noise_std * noise

    def astype(self, dtype) -> AR2Dynamics:
        return jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), self)


def _check_states(states: Array, minimum: int) -> None:
    if states.ndim != 2 or states.shape[0] < minimum:
        raise ValueError(f"states must be (time, state) with at least {minimum} frames, got "
                         f"shape {states.shape}")
    if not bool(jnp.all(jnp.isfinite(states))):
        raise ValueError("states hold non-finite values")


def _stabilise(first: Array, second: Array, max_root: float) -> tuple[Array, Array]:
    """Shrink the roots of z² − A₁ z − A₂ to modulus ≤ ``max_root`` (per dimension)."""
    discriminant = first**2 + 4 * second
    # complex pair r e^{±iθ}: A₁ = 2 r cos θ, A₂ = −r², so scaling r scales A₁ by the same factor
    modulus = jnp.sqrt(jnp.maximum(-second, 0.0))
    factor = jnp.minimum(1.0, max_root / jnp.maximum(modulus, 1e-30))
    complex_first, complex_second = first * factor, second * factor**2
    # two real roots p, q: clip each, then A₁ = p + q, A₂ = −p q
    root = jnp.sqrt(jnp.maximum(discriminant, 0.0))
    p = jnp.clip((first + root) / 2, -max_root, max_root)
    q = jnp.clip((first - root) / 2, -max_root, max_root)
    real = discriminant >= 0
    return (jnp.where(real, p + q, complex_first), jnp.where(real, -p * q, complex_second))


@eqx.filter_jit
def _fit_ar2(centred: Array, mean: Array, valid: Array, ridge: Array, min_noise_std: Array,
             max_root: float) -> AR2Dynamics:
    # rows of `valid` False straddle two trajectories: they drop out of every sum
    mask = valid[:, None].astype(centred.dtype)
    target, lag1, lag2 = centred[2:] * mask, centred[1:-1] * mask, centred[:-2] * mask
    # per-dimension 2×2 normal equations of target ≈ a₁ lag1 + a₂ lag2
    g11, g12, g22 = (jnp.sum(lag1 * lag1, 0), jnp.sum(lag1 * lag2, 0), jnp.sum(lag2 * lag2, 0))
    b1, b2 = jnp.sum(lag1 * target, 0), jnp.sum(lag2 * target, 0)
    # ridge toward the random walk (a₁, a₂) = (1, 0): a constant dimension becomes a random walk
    penalty = ridge * 0.5 * (g11 + g22)
    g11, g22 = g11 + penalty, g22 + penalty
    b1 = b1 + penalty
    determinant = g11 * g22 - g12 * g12
    solvable = determinant > 0  # not so for a constant dimension, or collinear lags and no ridge
    safe = jnp.where(solvable, determinant, 1)
    first = jnp.where(solvable, (g22 * b1 - g12 * b2) / safe, 1)
    second = jnp.where(solvable, (g11 * b2 - g12 * b1) / safe, 0)
    first, second = _stabilise(first, second, max_root)
    residuals = target - first * lag1 - second * lag2
    dof = jnp.maximum(jnp.sum(valid) - 2, 1)
    noise_std = jnp.sqrt(jnp.sum(residuals**2, axis=0) / dof)
    return AR2Dynamics(
        first_coefficients=first,
        second_coefficients=second,
        offset=(1 - first - second) * mean,  # x − μ follows the AR(2): d = (1 − A₁ − A₂) μ
        noise_std=jnp.maximum(noise_std, min_noise_std),
    )


def fit_ar2(
    states: Float[ArrayLike, "time state"],
    *,
    ridge: float = DEFAULT_RIDGE,
    min_noise_std: float | Float[ArrayLike, " state"] = 1e-6,
    max_root: float = 1.0,
    sequence_ids: ArrayLike | None = None,
) -> AR2Dynamics:
    """Learn diagonal AR(2) dynamics from a trajectory (or several) by ridge least squares.

    Each dimension is its own AR(2) process about the trajectory's mean μ,
    ``x_t − μ = a₁ (x_{t−1} − μ) + a₂ (x_{t−2} − μ) + w`` (so ``d = (1 − a₁ − a₂) μ``).
    A full 25 × 50 coefficient matrix cannot be learned from the 28 transitions of the paper's
    30 training frames (it would interpolate them exactly and leave no noise); per dimension it
    is two numbers from 28 equations. The ridge pulls (a₁, a₂) toward the random walk (1, 0)
    with weight ``ridge × mean(diag of the lag Gram matrix)``, which keeps the nearly collinear
    lags of a smooth trajectory well conditioned and makes a constant dimension a random walk.
    The characteristic roots are then shrunk to modulus ≤ ``max_root`` so that the dynamics
    cannot explode when run past the training frames (1 allows a random walk; less than 1
    makes every dimension revert to μ).

    Args:
        states: ``(time, state)`` trajectory, at least 4 frames (Tian et al.: the first 30
            frames of ground-truth SPM states).
        ridge: relative ridge (see above); 0 is plain least squares.
        min_noise_std: floor of the noise standard deviation (scalar or ``(state,)``), so that
            no dimension gets zero noise.
        max_root: largest modulus allowed for the roots of ``z² − a₁ z − a₂``.
        sequence_ids: ``(time,)`` one id per row when ``states`` stacks several trajectories
            (e.g. training clips × views, ``PoseSet.sequence_ids``): only lags inside one
            trajectory are fitted, each trajectory is centred on its own mean for the fit, and
            μ is the mean over all rows. None: one trajectory.

    Returns:
        :class:`AR2Dynamics` in the dtype of ``states`` (float32 unless float64 comes in).
    """
    states = jnp.asarray(states)
    if not jnp.issubdtype(states.dtype, jnp.floating):
        states = states.astype(jnp.float32)
    _check_states(states, 4)
    if ridge < 0 or max_root <= 0:
        raise ValueError(f"ridge must be >= 0 and max_root > 0, got {ridge}, {max_root}")
    floor = jnp.broadcast_to(jnp.asarray(min_noise_std, states.dtype), states.shape[1:])
    if not bool(jnp.all(floor > 0)):
        raise ValueError("min_noise_std must be positive in every dimension")
    if sequence_ids is None:
        centred, valid = states - jnp.mean(states, axis=0), jnp.ones(states.shape[0] - 2, bool)
    else:
        centred, valid = _centre_sequences(states, sequence_ids)
    return _fit_ar2(centred, jnp.mean(states, axis=0), valid,
                    jnp.asarray(ridge, states.dtype), floor, float(max_root))


def _centre_sequences(states: Array, sequence_ids: ArrayLike) -> tuple[Array, Array]:
    """Each trajectory minus its own mean, and which (t−2, t−1, t) triples lie in one."""
    ids = np.asarray(sequence_ids)
    if ids.shape != (states.shape[0],):
        raise ValueError(f"sequence_ids must have one id per row of states ({states.shape[0]}), "
                         f"got shape {ids.shape}")
    _, index = np.unique(ids, return_inverse=True)
    values = np.asarray(states, np.float64)
    means = np.zeros((index.max() + 1, values.shape[1]))
    np.add.at(means, index, values)
    means /= np.bincount(index)[:, None]
    valid = (index[2:] == index[1:-1]) & (index[1:-1] == index[:-2])
    if not valid.any():
        raise ValueError("no trajectory in sequence_ids has the 3 consecutive rows an AR(2) needs")
    return jnp.asarray(values - means[index], states.dtype), jnp.asarray(valid)


def random_walk_dynamics(
    states: Float[ArrayLike, "time state"],
    *,
    min_noise_std: float | Float[ArrayLike, " state"] = 1e-6,
) -> AR2Dynamics:
    """A random walk ``x_t = x_{t−1} + w`` as :class:`AR2Dynamics` (A₁ = I, A₂ = 0, d = 0).

    The noise standard deviation of each dimension is the RMS of its frame-to-frame differences
    in ``states`` (``(time, state)``, at least 2 frames), floored at ``min_noise_std``.
    """
    states = jnp.asarray(states)
    if not jnp.issubdtype(states.dtype, jnp.floating):
        states = states.astype(jnp.float32)
    _check_states(states, 2)
    steps = jnp.sqrt(jnp.mean(jnp.diff(states, axis=0) ** 2, axis=0))
    floor = jnp.broadcast_to(jnp.asarray(min_noise_std, states.dtype), steps.shape)
    return AR2Dynamics(
        first_coefficients=jnp.ones_like(steps), second_coefficients=jnp.zeros_like(steps),
        offset=jnp.zeros_like(steps), noise_std=jnp.maximum(steps, floor),
    )


def step_std_within(states: ArrayLike, sequence_ids: ArrayLike | None = None) -> np.ndarray:
    """``(state,)`` RMS frame-to-frame step of stacked trajectories, never across two."""
    steps = np.diff(np.asarray(states, np.float64), axis=0)
    if sequence_ids is not None:
        ids = np.asarray(sequence_ids)
        steps = steps[ids[1:] == ids[:-1]]
    if len(steps) == 0:
        raise ValueError("training_states need two consecutive frames of one trajectory")
    return np.sqrt(np.mean(steps**2, axis=0))


def default_noise_floor(torso_pixels: float, relative: float = 0.002) -> np.ndarray:
    """A ``(25,)`` noise floor for SPM states: ``relative`` in log scale, angles (radians) and
    log lengths, ``relative × torso`` pixels in the translation."""
    floor = np.full(SPM_STATE_SIZE, relative)
    floor[1:3] = relative * torso_pixels
    return floor


class LatentVelocity(eqx.Module):
    """Damped constant velocity of a latent point, ``x_{t+1} = x_t + a (x_t − x_{t−1}) + ω``,
    ``ω ~ N(0, diag σ²)`` (:func:`fit_latent_velocity`).

    Attributes:
        coefficient: ``(latent,)`` a, the share of the last step carried on (0: a random walk).
        noise_std: ``(latent,)`` σ, the std of what the carried step leaves unexplained.
        fps: the frame rate of the trajectories it was learned from.
    """

    coefficient: Float[Array, " latent"]
    noise_std: Float[Array, " latent"]
    fps: float = eqx.field(static=True, default=float("nan"))


def fit_latent_velocity(latents: Float[ArrayLike, "n latent"], sequence_ids: ArrayLike, *,
                        fps: float = float("nan")) -> LatentVelocity:
    """Learn :class:`LatentVelocity` from training latents in frame order.

    Per latent dimension, a = Σ Δ_t Δ_{t−1} / Σ Δ_{t−1}² over the steps Δ_t = x_t − x_{t−1} of
    each sequence (rows with the same id, in order), clipped to [0, 1); σ is the RMS of the
    residuals Δ_t − a Δ_{t−1}. A latent space whose trajectories are smooth (a back-constrained
    GPLVM's) gives a near 1; one whose training poses sit in islands, a near 0.
    """
    latents = np.asarray(latents, np.float64)
    ids = np.asarray(sequence_ids)
    if latents.ndim != 2 or ids.shape != (latents.shape[0],):
        raise ValueError(f"latents must be (n, latent) with one sequence id per row, got "
                         f"{latents.shape} and {ids.shape}")
    steps = np.diff(latents, axis=0)
    same = ids[1:] == ids[:-1]
    pairs = same[1:] & same[:-1]  # Δ_{t−1}, Δ_t both inside one sequence
    if not pairs.any():
        raise ValueError("sequence_ids has no three consecutive frames of one sequence")
    previous, current = steps[:-1][pairs], steps[1:][pairs]
    coefficient = np.clip(np.sum(previous * current, 0)
                          / np.maximum(np.sum(previous**2, 0), 1e-30), 0.0, 0.999)
    noise = np.sqrt(np.mean((current - coefficient * previous) ** 2, axis=0))
    return LatentVelocity(jnp.asarray(coefficient), jnp.asarray(np.maximum(noise, 1e-9)),
                          float(fps))


class LatentWalk(eqx.Module):
    """Random walk of a latent point (Tian et al. eq. 6) with jumps to training latents, and of
    the SPM placement.

    Attributes:
        latent_std: ``(latent,)`` ν, the latent step per frame.
        jump_threshold: Φ⁻¹(jump probability): a particle jumps when its normal draw falls
            below it (−inf: never, the paper's random walk).
        pool: ``(points, latent)`` the training latents a jump lands on.
        placement_std: ``(3,)`` step of (log scale, x, y) per frame.
        velocity: ``(latent,)`` a of :class:`LatentVelocity`: the walk starts from
            ``x + a (x − x_prev)`` (``latent_std`` then being its σ); None: from x.
    """

    latent_std: Float[Array, " latent"]
    jump_threshold: Float[Array, ""]
    pool: Float[Array, "points latent"]
    placement_std: Float[Array, " 3"]
    velocity: Float[Array, " latent"] | None = None

    def sample(self, key: PRNGKeyArray, latent: Float[Array, " latent"],
               placement: Float[Array, " 3"], dims: tuple[int, ...] | None = None,
               move_placement: bool = True, previous: Float[Array, " latent"] | None = None
               ) -> tuple[Array, ...]:
        """One step of ``(latent, placement)``; with ``dims`` (static indices), of those latent
        dimensions alone (a jump lands them on a training latent's), the placement moving only
        with ``move_placement`` (partitioned sampling, ``jaxtrack.trackers._partitioned``).

        With :attr:`velocity`, ``previous`` is x_{t−1} and a third value comes back: the
        new x_{t−1} (the old latent; the landing point where a particle jumped, so that a jump
        carries no velocity)."""
        index = slice(None) if dims is None else jnp.asarray(dims)
        part, pool, latent_std = latent[index], self.pool[:, index], self.latent_std[index]
        part_dim, placement_dim = part.shape[0], placement.shape[0]
        noise = smc.fast_normal(key, (part_dim + placement_dim + 2,), latent.dtype)
        step, jump_draw, pick_draw = (noise[:part_dim + placement_dim], noise[-2], noise[-1])
        centre = part
        if self.velocity is not None:
            centre = part + self.velocity[index] * (part - previous[index])
        # Tian et al. eq. 6: random walk x_{t+1} = x_t + ω, ω ~ N(0, diag ν²) ... or, with
        # probability ε, from a random training latent
        pick = jnp.minimum((jsp.ndtr(pick_draw) * pool.shape[0]).astype(jnp.int32),
                           pool.shape[0] - 1)
        jumped = jump_draw < self.jump_threshold
        start = jnp.where(jumped, pool[pick], centre)
        moved = start + latent_std * step[:part_dim]
        if move_placement:
            placement = placement + self.placement_std * step[part_dim:]
        if self.velocity is None:
            return latent.at[index].set(moved), placement
        return (latent.at[index].set(moved), placement,
                previous.at[index].set(jnp.where(jumped, start, part)))

    def move(self, key: PRNGKeyArray, particle: dict, dims: tuple[int, ...] | None = None,
             move_placement: bool = True) -> dict:
        """:meth:`sample` on a latent tracker's particle ``{"latent", "placement"}`` (and
        ``"previous"``, x_{t−1}, with :attr:`velocity`)."""
        if self.velocity is None:
            latent, placement = self.sample(key, particle["latent"], particle["placement"],
                                            dims, move_placement)
            return {"latent": latent, "placement": placement}
        latent, placement, previous = self.sample(key, particle["latent"],
                                                  particle["placement"], dims, move_placement,
                                                  particle["previous"])
        return {"latent": latent, "placement": placement, "previous": previous}


def constant_velocity(current: Float[Array, "... state"], previous: Float[Array, "... state"],
                      weight: Float[ArrayLike, ""]) -> Float[Array, "... state"]:
    """The prediction ``x_t + v (x_t − x_{t−1})`` (v = 0: constant position, 1: constant
    velocity)."""
    return current + weight * (current - previous)
