"""The paper's CONDENSATION baseline: particles in the full 25-d SPM state, AR(2) dynamics.

Tian, Li & Sclaroff (2005, §5) compare their latent-space tracker with "CONDENSATION in the
original 25-D state space with second-order auto-regressive dynamics learned from the first 30
frames" of ground truth. This module is that baseline, on the same engine and the same NCC
likelihood (eq. 7) as :mod:`jaxtrack.trackers.latent`:

    x_t = A₁ x_{t−1} + A₂ x_{t−2} + d + w_t,   w_t ~ N(0, Q),

with diagonal A₁, A₂ and Q (:func:`fit_ar2`). A particle holds ``(x_t, x_{t−1})``. Its weight is
the same appearance likelihood as the latent tracker's at the markers ``spm_forward(x_t)``
(limb strips by default, ``likelihood="markers"`` for the paper's patches; nearest-pixel by
default, ``nearest=False`` for bilinear); the estimate is the markers of
the weighted mean state (SPM angles are measured from the template's directions, so ordinary
poses sit near 0, far from the ±π wrap, and plain means are fine).

:func:`random_walk_tracker` is the same filter with ``x_t = x_{t−1} + w_t``: the ablation
"prior replaced by a random walk in the full state".
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPM_STATE_SIZE, SPMTemplate, spm_forward, spm_initial_state
from jaxtrack.likelihoods import (
    DEFAULT_LIKELIHOOD,
    AppearanceTemplates,
    default_sharpness,
    make_appearance_templates,
)
from jaxtrack.trackers._runner import ParticleTracker

__all__ = [
    "AR2Dynamics",
    "CondensationModel",
    "CondensationTracker",
    "condensation_tracker",
    "default_noise_floor",
    "fit_ar2",
    "random_walk_dynamics",
    "random_walk_tracker",
]

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
def _fit_ar2(states: Array, ridge: Array, min_noise_std: Array, max_root: float) -> AR2Dynamics:
    mean = jnp.mean(states, axis=0)
    centred = states - mean
    target, lag1, lag2 = centred[2:], centred[1:-1], centred[:-2]
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
    dof = jnp.maximum(target.shape[0] - 2, 1)
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
) -> AR2Dynamics:
    """Learn diagonal AR(2) dynamics from a trajectory by ridge least squares.

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
    return _fit_ar2(states, jnp.asarray(ridge, states.dtype), floor, float(max_root))


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


def default_noise_floor(torso_pixels: float, relative: float = 0.002) -> np.ndarray:
    """A ``(25,)`` noise floor for SPM states: ``relative`` in log scale, angles (radians) and
    log lengths, ``relative × torso`` pixels in the translation."""
    floor = np.full(SPM_STATE_SIZE, relative)
    floor[1:3] = relative * torso_pixels
    return floor


class CondensationModel(smc.StateSpaceModel):
    """CONDENSATION in the 25-d SPM state (one particle: ``{"current", "previous"}``).

    Attributes:
        dynamics: the AR(2) (or random-walk) dynamics.
        template: the SPM template.
        templates: appearance templates from the first frame (limb strips or marker patches).
        initial_state: ``(25,)`` SPM state of frame 0.
        initial_std: ``(25,)`` spread of the initial particles around it.
        sharpness: λ of the likelihood.
        nearest: read pixels at the nearest sample point (fast; the latent tracker's default)
            instead of bilinearly.
    """

    dynamics: AR2Dynamics
    template: SPMTemplate
    templates: AppearanceTemplates
    initial_state: Float[Array, " state"]
    initial_std: Float[Array, " state"]
    sharpness: Float[Array, ""]
    nearest: bool = eqx.field(static=True, default=True)

    def init(self, key: PRNGKeyArray) -> dict:
        noise = smc.fast_normal(key, self.initial_state.shape, self.initial_state.dtype)
        state = self.initial_state + self.initial_std * noise
        return {"current": state, "previous": state}  # at rest: no velocity at frame 0

    def propagate(self, key: PRNGKeyArray, particle: dict, time) -> dict:
        # Tian et al. §5's baseline: second-order AR dynamics in the full state
        new = self.dynamics.sample(key, particle["current"], particle["previous"])
        return {"current": new, "previous": particle["current"]}

    def markers_of(self, particle: dict) -> Float[Array, "markers 2"]:
        return spm_forward(particle["current"], self.template)

    def log_likelihood(self, particle: dict, observation) -> Float[Array, ""]:
        # Tian et al. eq. 7, the same likelihood as the latent tracker's
        return self.templates.log_likelihood(self.markers_of(particle), observation,
                                             self.sharpness, self.nearest)


class CondensationTracker(ParticleTracker):
    """CONDENSATION in the full SPM state (see :func:`condensation_tracker`)."""

    condensation_model: CondensationModel
    particles: int = eqx.field(static=True)

    @property
    def model(self) -> CondensationModel:
        return self.condensation_model

    @property
    def num_particles(self) -> int:
        return self.particles

    def markers_of(self, particle) -> Array:
        return self.condensation_model.markers_of(particle)


def _build(dynamics: AR2Dynamics, template: SPMTemplate, first_frame, first_markers,
           num_particles: int, initial_spread: float, likelihood: str, sharpness: float | None,
           nearest: bool, dtype, background=None) -> CondensationTracker:
    if sharpness is None:
        sharpness = default_sharpness(likelihood)
    cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
    template = jax.tree.map(cast, template)
    initial = spm_initial_state(cast(first_markers), template)
    dynamics = dynamics.astype(dtype)
    model = CondensationModel(
        dynamics=dynamics, template=template,
        templates=make_appearance_templates(likelihood, cast(first_frame), cast(first_markers),
                                            background),
        initial_state=initial, initial_std=jnp.asarray(initial_spread, dtype) * dynamics.noise_std,
        sharpness=cast(sharpness), nearest=bool(nearest),
    )
    return CondensationTracker(condensation_model=model, particles=int(num_particles))


def _prepare(template, first_markers, training_states, min_noise_std):
    first_markers = np.asarray(first_markers, np.float64)
    if first_markers.shape != (12, 2) or not np.all(np.isfinite(first_markers)):
        raise ValueError(f"first_markers must be 12 finite (x, y) markers, got shape "
                         f"{first_markers.shape}")
    training_states = np.asarray(training_states, np.float64)
    if training_states.ndim != 2 or training_states.shape[1] != SPM_STATE_SIZE:
        raise ValueError(f"training_states must be (time, {SPM_STATE_SIZE}) SPM states "
                         f"(jaxtrack.body.spm_fit of the first frames' markers), got "
                         f"{training_states.shape}")
    if min_noise_std is None:
        min_noise_std = default_noise_floor(float(np.exp(np.median(training_states[:, 0]))))
    return first_markers, training_states, np.asarray(min_noise_std, np.float64)


def condensation_tracker(
    template: SPMTemplate,
    first_frame: Float[ArrayLike, "height width"],
    first_markers: Float[ArrayLike, "markers 2"],
    training_states: Float[ArrayLike, "time 25"],
    *,
    num_particles: int = 1000,
    likelihood: str = DEFAULT_LIKELIHOOD,
    background: Float[ArrayLike, "height width"] | None = None,
    sharpness: float | None = None,
    ridge: float = DEFAULT_RIDGE,
    min_noise_std: float | Float[ArrayLike, " 25"] | None = None,
    max_root: float = 1.0,
    initial_spread: float = 1.0,
    nearest: bool = True,
    dtype=jnp.float32,
) -> CondensationTracker:
    """Tian et al.'s baseline: CONDENSATION in the 25-d SPM state with AR(2) dynamics learned
    from ground truth.

    Args:
        template: the SPM template the states are expressed in.
        first_frame: ``(height, width)`` grey frame 0 (the NCC templates are cut from it).
        first_markers: ``(12, 2)`` its markers (``SPM_MARKERS`` order); they give the initial
            state.
        training_states: ``(time, 25)`` SPM states to learn the dynamics from (the paper: the
            first 30 frames of ground truth, ``spm_fit(truth[:30], template)``).
        num_particles: N.
        likelihood: ``"limbs+edges"``, ``"limbs"`` or ``"markers"``
            (:mod:`jaxtrack.likelihoods.appearance`).
        background: ``(height, width)`` grey background of a static camera for the
            ``"limbs+edges"`` likelihood's foreground term
            (``jaxtrack.vision.median_grey_background``); None: no foreground term.
        sharpness: λ of the likelihood; None for the likelihood's default.
        ridge, max_root: see :func:`fit_ar2`.
        min_noise_std: floor of the AR noise std (scalar or ``(25,)``); None:
            :func:`default_noise_floor` of the training torso length.
        initial_spread: initial particles spread by this many noise stds around frame 0's state.
        nearest: nearest-pixel sampling (fast, as the latent tracker) rather than bilinear.
        dtype: the filter's float type.
    """
    first_markers, training_states, floor = _prepare(template, first_markers, training_states,
                                                     min_noise_std)
    dynamics = fit_ar2(training_states, ridge=ridge, min_noise_std=floor, max_root=max_root)
    return _build(dynamics, template, first_frame, first_markers, num_particles, initial_spread,
                  likelihood, sharpness, nearest, dtype, background)


def random_walk_tracker(
    template: SPMTemplate,
    first_frame: Float[ArrayLike, "height width"],
    first_markers: Float[ArrayLike, "markers 2"],
    training_states: Float[ArrayLike, "time 25"],
    *,
    num_particles: int = 1000,
    likelihood: str = DEFAULT_LIKELIHOOD,
    background: Float[ArrayLike, "height width"] | None = None,
    sharpness: float | None = None,
    min_noise_std: float | Float[ArrayLike, " 25"] | None = None,
    step_scale: float = 1.0,
    initial_spread: float = 1.0,
    nearest: bool = True,
    dtype=jnp.float32,
) -> CondensationTracker:
    """CONDENSATION in the 25-d SPM state with a random walk: the ablation of the learned prior.

    The step std of each dimension is ``step_scale`` × the RMS frame-to-frame difference of
    ``training_states`` (floored as in :func:`condensation_tracker`). Other arguments as
    :func:`condensation_tracker`.
    """
    first_markers, training_states, floor = _prepare(template, first_markers, training_states,
                                                     min_noise_std)
    dynamics = random_walk_dynamics(training_states, min_noise_std=floor)
    dynamics = eqx.tree_at(lambda d: d.noise_std, dynamics, step_scale * dynamics.noise_std)
    return _build(dynamics, template, first_frame, first_markers, num_particles, initial_spread,
                  likelihood, sharpness, nearest, dtype, background)
