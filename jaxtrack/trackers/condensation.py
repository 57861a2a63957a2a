"""The paper's CONDENSATION baseline: particles in the full 25-d SPM state, AR(2) dynamics.

Tian, Li & Sclaroff (2005, §5) compare their latent-space tracker with "CONDENSATION in the
original 25-D state space with second-order auto-regressive dynamics learned from the first 30
frames" of ground truth. This module is that baseline, on the same engine and the same
likelihood as the latent tracker:

    x_t = A₁ x_{t−1} + A₂ x_{t−2} + d + w_t,   w_t ~ N(0, Q),

with diagonal A₁, A₂ and Q (:func:`jaxtrack.priors.dynamics.fit_ar2`). A particle holds
``(x_t, x_{t−1})``; its weight is the likelihood at the markers ``spm_forward(x_t)``; the
estimate is the markers of the weighted mean state (SPM angles are measured from the
template's directions, so ordinary poses sit near 0, far from the ±π wrap, and plain means are
fine). Given a :class:`~jaxtrack.trackers.Refinement`, the reported pose is refined in the full
state exactly as the latent tracker's is.

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
from jaxtrack.body import SPM_STATE_SIZE, SPMTemplate, spm_forward
from jaxtrack.likelihoods import PartTemplates
from jaxtrack.priors.dynamics import (
    DEFAULT_RIDGE,
    AR2Dynamics,
    default_noise_floor,
    fit_ar2,
    random_walk_dynamics,
    step_std_within,
)
from jaxtrack.trackers._options import Engine, Likelihood, Refinement, options_record
from jaxtrack.trackers._particles import (
    ImageTracker,
    check_initial_pose,
    cloud_estimate,
    device_observation,
    filter_step,
    first_info,
    frame0_state,
    frame0_templates,
    initialize_filter,
)
from jaxtrack.trackers._refinement import RefinementState, refine, start_refinement
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk

__all__ = ["CondensationModel", "CondensationState", "CondensationTracker",
           "condensation_tracker", "random_walk_tracker"]


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
    templates: PartTemplates
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


class CondensationState(eqx.Module):
    """What the CONDENSATION tracker carries between frames.

    Attributes:
        model: the state-space model assembled at frame 0 (its templates cut from the first
            frame); constant over the sequence.
        filter: the particle filter's state.
        refined: the refinement stage's carried poses (None without a refinement).
        refine_std: ``(25,)`` σ of the refinement's prior (None without a refinement).
    """

    model: CondensationModel
    filter: smc.FilterState
    refined: RefinementState | None
    refine_std: Float[Array, " 25"] | None


class CondensationTracker(ImageTracker):
    """CONDENSATION in the full SPM state (module docstring; :func:`condensation_tracker`).

    Attributes:
        dynamics: AR(2) (or random-walk) dynamics of the 25-d state.
        template: the SPM template the states are expressed in.
        likelihood: how frames are scored.
        engine: the particle filter's settings (N, resampler, ESS threshold).
        refinement: the full-state refinement of the reported pose; None: the weighted mean.
        background: ``(height, width)`` grey background of a static camera for the
            ``"limbs+edges"`` likelihood's foreground term; None: none.
        initial_spread: initial particles spread by this many noise stds about frame 0's state.
    """

    dynamics: AR2Dynamics
    template: SPMTemplate
    likelihood: Likelihood
    engine: Engine
    refinement: Refinement | None = None
    background: Float[Array, "height width"] | None = None
    initial_spread: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        if not self.initial_spread >= 0:
            raise ValueError(f"initial_spread must be >= 0, got {self.initial_spread!r}")

    @property
    def num_particles(self) -> int:
        return self.engine.num_particles

    @property
    def dtype(self):
        return self.dynamics.noise_std.dtype

    def options(self) -> dict:
        return {"method": "condensation", "particles": self.num_particles,
                "engine": options_record(self.engine),
                "likelihood": options_record(self.likelihood),
                "refinement": options_record(self.refinement),
                "foreground": self.background is not None,
                "initial_spread": self.initial_spread}

    def start(self, key: PRNGKeyArray, first_frame, initial_pose) -> CondensationState:
        markers = check_initial_pose(initial_pose)
        dtype = self.dtype
        initial = frame0_state(markers, self.template, dtype)
        model = CondensationModel(
            dynamics=self.dynamics, template=self.template,
            templates=frame0_templates(self.likelihood, first_frame, markers, self.background,
                                       dtype),
            initial_state=initial,
            initial_std=jnp.asarray(self.initial_spread, dtype) * self.dynamics.noise_std,
            sharpness=jnp.asarray(self.likelihood.lam, dtype),
            nearest=self.likelihood.nearest)
        refined, refine_std = start_refinement(self.refinement, initial)
        filtered = initialize_filter(key, model, device_observation(first_frame, dtype),
                                    self.num_particles)
        return CondensationState(model, filtered, refined, refine_std)

    def first_estimate(self, state: CondensationState) -> FrameEstimate:
        return self._estimate(state, state.filter, first_info(state.filter), None)

    def update(self, key: PRNGKeyArray, state: CondensationState, frame: Array | FrameInChunk
               ) -> tuple[CondensationState, FrameEstimate]:
        with jax.named_scope("filter"):
            filtered, info = filter_step(self.engine, key, state.filter, frame, state.model)
        return self._report(state, filtered, info, frame)

    def _report(self, state: CondensationState, filtered: smc.FilterState, info: smc.StepInfo,
                frame) -> tuple[CondensationState, FrameEstimate]:
        refined = state.refined
        if self.refinement is not None:
            model = state.model
            with jax.named_scope("candidates"):
                mean = smc.weighted_mean(filtered.particles, filtered.log_weights)["current"]
            refined, _ = refine(self.refinement, state.refined, mean, frame, model.templates,
                                model.template, model.sharpness, state.refine_std)
        new = CondensationState(state.model, filtered, refined, state.refine_std)
        return new, self._estimate(new, filtered, info, refined)

    def _estimate(self, state: CondensationState, filtered: smc.FilterState,
                  info: smc.StepInfo, refined: RefinementState | None) -> FrameEstimate:
        model = state.model
        if refined is None or self.refinement is None:
            mean = smc.weighted_mean(filtered.particles, filtered.log_weights)
            markers = model.markers_of(mean)
        else:
            markers = spm_forward(refined.pose, model.template)
        return cloud_estimate(filtered, info, markers, model.markers_of)



def _training_states(training_states) -> np.ndarray:
    states = np.asarray(training_states, np.float64)
    if states.ndim != 2 or states.shape[1] != SPM_STATE_SIZE:
        raise ValueError(f"training_states must be (time, {SPM_STATE_SIZE}) SPM states "
                         f"(jaxtrack.body.spm_fit of the first frames' markers), got "
                         f"{states.shape}")
    return states


def _noise_floor(states: np.ndarray, min_noise_std) -> np.ndarray:
    if min_noise_std is None:
        return default_noise_floor(float(np.exp(np.median(states[:, 0]))))
    return np.asarray(min_noise_std, np.float64)


def _placement_walks(dynamics, states, sequence_ids, floor):
    walk = np.zeros(SPM_STATE_SIZE, bool)
    walk[:3] = True
    steps = np.maximum(step_std_within(states, sequence_ids), np.broadcast_to(floor, walk.shape))
    dtype = dynamics.noise_std.dtype
    return type(dynamics)(
        first_coefficients=jnp.where(walk, 1.0, dynamics.first_coefficients).astype(dtype),
        second_coefficients=jnp.where(walk, 0.0, dynamics.second_coefficients).astype(dtype),
        offset=jnp.where(walk, 0.0, dynamics.offset).astype(dtype),
        noise_std=jnp.where(walk, jnp.asarray(steps, dtype), dynamics.noise_std))


def _cast(tree, dtype):
    return jax.tree.map(lambda leaf: jnp.asarray(np.asarray(leaf, np.float64), dtype), tree)


def condensation_tracker(
    template: SPMTemplate,
    training_states: Float[ArrayLike, "time 25"],
    *,
    engine: Engine = Engine(1000),
    likelihood: Likelihood = Likelihood(),
    refinement: Refinement | None = None,
    background: Float[ArrayLike, "height width"] | None = None,
    ridge: float = DEFAULT_RIDGE,
    min_noise_std: float | Float[ArrayLike, " 25"] | None = None,
    max_root: float = 1.0,
    initial_spread: float = 1.0,
    sequence_ids: ArrayLike | None = None,
    dtype=jnp.float32,
) -> CondensationTracker:
    """Tian et al.'s baseline: CONDENSATION in the 25-d SPM state with AR(2) dynamics learned
    from ``training_states``: the training clips' poses (``sequence_ids`` given, what the
    evaluation does by default) or, as the paper did, the first 30 frames of the test clip's
    ground truth (``spm_initial_state(truth[:30], template)``).

    Args:
        template: the SPM template the states are expressed in.
        training_states: ``(time, 25)`` SPM states to learn the dynamics from.
        engine: the particle filter's settings (:class:`~jaxtrack.trackers.Engine`: N,
            resampler, ESS threshold).
        likelihood: how frames are scored (:class:`~jaxtrack.trackers.Likelihood`).
        refinement: the full-state refinement of the reported pose; None: the weighted mean.
        background: grey background of a static camera for the foreground term; None: none.
        ridge: see :func:`~jaxtrack.priors.dynamics.fit_ar2`.
        max_root: see :func:`~jaxtrack.priors.dynamics.fit_ar2`.
        min_noise_std: floor of the AR noise std (scalar or ``(25,)``); None:
            ``default_noise_floor`` of the training torso length.
        initial_spread: initial particles spread by this many noise stds about frame 0's state.
        sequence_ids: ``(time,)`` when ``training_states`` stacks several trajectories (clips ×
            views): lags are fitted within each (:func:`~jaxtrack.priors.dynamics.fit_ar2`),
            and the placement (log scale, translation), which depends on each training
            camera, walks (A₁ = 1, A₂ = 0, d = 0, noise the RMS step within trajectories)
            instead of reverting to the training cameras' mean.
        dtype: the filter's float type.
    """
    states = _training_states(training_states)
    floor = _noise_floor(states, min_noise_std)
    dynamics = fit_ar2(states, ridge=ridge, min_noise_std=floor, max_root=max_root,
                       sequence_ids=sequence_ids)
    if sequence_ids is not None:
        dynamics = _placement_walks(dynamics, states, sequence_ids, floor)
    return CondensationTracker(
        dynamics=dynamics.astype(dtype), template=_cast(template, dtype), likelihood=likelihood,
        engine=engine, refinement=refinement, background=background,
        initial_spread=float(initial_spread))


def random_walk_tracker(
    template: SPMTemplate,
    training_states: Float[ArrayLike, "time 25"],
    *,
    engine: Engine = Engine(1000),
    likelihood: Likelihood = Likelihood(),
    refinement: Refinement | None = None,
    background: Float[ArrayLike, "height width"] | None = None,
    min_noise_std: float | Float[ArrayLike, " 25"] | None = None,
    step_scale: float = 1.0,
    initial_spread: float = 1.0,
    dtype=jnp.float32,
) -> CondensationTracker:
    """CONDENSATION in the 25-d SPM state with a random walk: the ablation of the learned prior.

    The step std of each dimension is ``step_scale`` × the RMS frame-to-frame difference of
    ``training_states`` (floored as in :func:`condensation_tracker`). Other arguments as
    :func:`condensation_tracker`.
    """
    states = _training_states(training_states)
    dynamics = random_walk_dynamics(states, min_noise_std=_noise_floor(states, min_noise_std))
    dynamics = eqx.tree_at(lambda d: d.noise_std, dynamics, step_scale * dynamics.noise_std)
    return CondensationTracker(
        dynamics=dynamics.astype(dtype), template=_cast(template, dtype), likelihood=likelihood,
        engine=engine, refinement=refinement, background=background,
        initial_spread=float(initial_spread))
