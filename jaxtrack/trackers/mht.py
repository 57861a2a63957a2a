"""Multiple-hypothesis tracking in the 25-d SPM state (after Cham & Rehg 1999), the paper's
second baseline.

Cham & Rehg (1999) keep a few modes of the pose posterior instead of a particle cloud: every
frame each mode is predicted, sharpened by a local optimiser on the image matching cost, re-weighted
by its likelihood, and the pool is pruned and refilled by sampling around the best modes. Tian,
Li & Sclaroff (2005) compare with it using 10 modes. Here, per frame:

1. **predict** each mode: ``x̂ = x_{t−1} + v (x_{t−1} − x_{t−2})`` with ``v = velocity_weight``
   (0: constant position, 1: constant velocity); the slots dropped at the previous frame are
   **refilled** by samples ``x̂_parent + refill_spread · σ ⊙ ε`` around surviving modes chosen by
   weight, inheriting the parent's past (so its velocity);
2. **refine** every candidate by damped Gauss–Newton with a backtracking Armijo line search
   (:func:`~jaxtrack.trackers.refine_pose`; optimistix, vmapped over modes, ``throw=False``,
   ``max_steps`` capped) on the MAP cost

       ½‖r(x)‖² = λ Σ_m (1 − NCC_m(x)) + ½ Σ_d ((x_d − x̂_d) / (prior_scale · σ_d))²,

   the NCC dissimilarity of eq. 7 of Tian et al. plus a Gaussian prior about the candidate. The
   image residuals are the per-pixel differences of the zero-mean, unit-norm patches and
   templates, ``√λ (p̂_m − t̂_m)``: since ``‖p̂ − t̂‖² = 2 − 2 NCC`` their half squared norm is
   exactly the NCC cost, and their Jacobian (one row per patch pixel) is far better conditioned
   than that of a single ``1 − NCC_m`` per marker (or its square root, singular at a match);
3. **weight** each refined mode by its NCC likelihood, **merge** near-duplicates (a mode whose
   markers all lie within ``merge_radius`` pixels of a better kept mode's is dropped) and
   **prune** modes more than ``prune_below`` nats under the best; the dropped slots are refilled
   at the next frame (step 1), so every slot is refined every frame.

Patches are read bilinearly throughout (refinement and weights): Gauss–Newton needs patches that
vary smoothly with the markers, and nearest-pixel ones are piecewise constant.

σ (``step_std``) is the per-frame state step, by default the RMS frame-to-frame difference of the
same 30 ground-truth frames the CONDENSATION baseline learns from. The estimate is the best mode;
``FrameEstimate.ess`` is the number of modes kept after merging and pruning. A frame where no
mode has a finite likelihood (a numerical failure: the NCC cost is bounded) or stays on the
frame (a finite state whose markers all lie within half a frame of its border; a
constant-velocity prediction can run away) is reported as degenerate, with frame 0's pose as its
estimate, and the pool is re-seeded at frame 0's state.

Given a :class:`~jaxtrack.trackers.Refinement`, the reported best mode is refined in the full
state by the same stage as the other trackers' estimates (arm search, then the parts solver).
Why the defaults are what they are: ``docs/trackers.md``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Float, Int, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPM_STATE_SIZE, SPMTemplate, spm_forward
from jaxtrack.likelihoods import PartTemplates
from jaxtrack.priors.dynamics import constant_velocity, default_noise_floor, step_std_within
from jaxtrack.trackers._gauss_newton import refine_pose
from jaxtrack.trackers._options import Likelihood, Refinement, options_record
from jaxtrack.trackers._particles import (
    ImageTracker,
    check_initial_pose,
    frame0_state,
    frame0_templates,
)
from jaxtrack.trackers._refinement import RefinementState, refine, start_refinement
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, frame_at
from jaxtrack.vision.observations import detections_of, images_of

__all__ = ["MHTModel", "MHTState", "MHTTracker", "ModePool", "mht_tracker"]


class ModePool(eqx.Module):
    """The MHT tracker's modes at one frame.

    Attributes:
        modes: ``(modes, 25)`` SPM states at the current frame.
        previous: ``(modes, 25)`` each mode's state one frame before (its velocity's tail).
        log_weights: ``(modes,)`` normalised log weights (NCC likelihoods).
        kept: ``(modes,)`` the modes that survived merging and pruning; the others are
            replaced by samples around these at the next frame.
        time: frame index.
        failed_refinements: how many of this frame's refinements failed (a solver error other
            than running out of steps, or a non-finite result; those modes keep their
            prediction).
    """

    modes: Float[Array, "modes 25"]
    previous: Float[Array, "modes 25"]
    log_weights: Float[Array, " modes"]
    kept: Bool[Array, " modes"]
    time: Int[Array, ""]
    failed_refinements: Int[Array, ""]


def _surviving(markers: Array, log_likelihoods: Array, radius: Array, prune_below: Array
               ) -> Bool[Array, " modes"]:
    """Greedy merging, best first: a mode is kept unless a kept better mode lies within
    ``radius`` pixels at every marker, or its log-likelihood is more than ``prune_below``
    under the best one's."""
    num = markers.shape[0]
    distance = jnp.max(jnp.linalg.norm(markers[:, None] - markers[None], axis=-1), axis=-1)
    log_likelihoods = jnp.where(jnp.isnan(log_likelihoods), -jnp.inf, log_likelihoods)
    order = jnp.argsort(-log_likelihoods)
    plausible = jnp.isfinite(log_likelihoods) & (
        log_likelihoods >= jnp.max(log_likelihoods) - prune_below)

    def visit(rank, kept):
        mode = order[rank]
        close = (distance[mode] < radius) & kept
        return kept.at[mode].set(~jnp.any(close) & plausible[mode])

    kept = jax.lax.fori_loop(0, num, visit, jnp.zeros(num, bool))
    return kept.at[order[0]].set(True)  # the best mode always survives (even a NaN pool)


class MHTModel(eqx.Module):
    """The MHT tracker's arrays, assembled at frame 0 (its templates cut from the first frame),
    and its per-frame step (module docstring).

    Attributes:
        template: the SPM template.
        templates: appearance templates from the first frame (limb strips or marker patches).
        initial_state: ``(25,)`` frame 0's SPM state.
        step_std: ``(25,)`` per-frame std of the state: the prediction prior's σ and the unit of
            the refill spread.
        sharpness: λ of the NCC likelihood.
        velocity_weight: v of the prediction (0: constant position, 1: constant velocity).
        prior_scale: the refinement prior's σ is ``prior_scale × step_std``.
        refill_spread: refilled modes are drawn this many ``step_std`` around their parent.
        merge_radius: modes closer than this (pixels, every marker) are merged.
        prune_below: modes whose log-likelihood is this far under the best are dropped.
        modes: static number of modes.
        max_steps: static cap on Gauss–Newton steps per mode and frame.
    """

    template: SPMTemplate
    templates: PartTemplates
    initial_state: Float[Array, " 25"]
    step_std: Float[Array, " 25"]
    sharpness: Float[Array, ""]
    velocity_weight: Float[Array, ""]
    prior_scale: Float[Array, ""]
    refill_spread: Float[Array, ""]
    merge_radius: Float[Array, ""]
    prune_below: Float[Array, ""]
    modes: int = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)

    def _markers(self, states: Array) -> Array:
        return jax.vmap(spm_forward, in_axes=(0, None))(states, self.template)

    def _log_likelihoods(self, states: Array, frame: Array) -> Array:
        values = jax.vmap(self.templates.log_likelihood, in_axes=(0, None, None, None))(
            self._markers(states), frame, self.sharpness, False)
        return jnp.where(jnp.isnan(values), -jnp.inf, values)

    def seed(self) -> ModePool:
        """One mode at frame 0's state, at rest; the next frame fills the pool around it."""
        dtype = self.initial_state.dtype
        modes = jnp.broadcast_to(self.initial_state, (self.modes, SPM_STATE_SIZE))
        kept = jnp.arange(self.modes) == 0
        log_weights = jnp.where(kept, 0.0, -jnp.inf).astype(dtype)
        return ModePool(modes, modes, log_weights, kept, jnp.asarray(0, jnp.int32),
                        jnp.asarray(0, jnp.int32))

    def first_estimate(self, state: ModePool) -> FrameEstimate:
        best = jnp.argmax(state.log_weights)
        markers = spm_forward(state.modes[best], self.template)
        # frame 0's pose is given, not scored: its log-likelihood is reported as 0 (every NCC
        # is 1 there, the templates having been cut at these markers)
        return FrameEstimate(markers=markers, best_markers=markers,
                             ess=jnp.sum(state.kept).astype(markers.dtype),
                             log_likelihood=jnp.asarray(0, markers.dtype),
                             degenerate=jnp.asarray(False))

    def step(self, key: PRNGKeyArray, state: ModePool, frame: Float[Array, "..."]
             ) -> tuple[ModePool, FrameEstimate]:
        """One frame: predict, refill, refine, weight, merge and prune (module docstring)."""
        dtype = self.initial_state.dtype
        frame = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), frame)
        key_parents, key_refill = jr.split(key)
        # 1. predict every mode
        predicted = constant_velocity(state.modes, state.previous, self.velocity_weight)
        # refill the slots dropped last frame around surviving modes chosen by weight; a
        # refilled mode inherits its parent's past, so its velocity too
        parents = jr.categorical(key_parents, jnp.where(state.kept, state.log_weights, -jnp.inf),
                                 shape=(self.modes,))
        parents = jnp.where(state.kept, jnp.arange(self.modes), parents)
        noise = smc.fast_normal(key_refill, (self.modes, SPM_STATE_SIZE), dtype)
        spread = jnp.where(state.kept[:, None], 0, self.refill_spread * self.step_std)
        candidates = predicted[parents] + spread * noise
        tails = state.modes[parents]

        # 2. refine each candidate on the frame, under a Gaussian prior about itself
        prior_std = self.prior_scale * self.step_std

        def refine(start):
            return refine_pose(start, frame, self.templates, self.template, start, prior_std,
                               self.sharpness, max_steps=self.max_steps)

        refined, results = jax.vmap(refine)(candidates)
        failed = ~jnp.all(jnp.isfinite(refined), axis=-1) | (
            (results != optx.RESULTS.successful)
            & (results != optx.RESULTS.nonlinear_max_steps_reached))
        refined = jnp.where(failed[:, None], candidates, refined)

        # 3. weight, merge and prune; a mode that ran away (a state or marker not finite, or
        # a marker more than half the frame beyond its border) cannot be scored: pixel reads
        # there return clamped, finite values, so it is ruled out here, not by its likelihood
        markers = self._markers(refined)
        images = images_of(frame)
        if images is None:  # detections alone: the frame's size is theirs
            size = detections_of(frame).image_size.astype(dtype)
        else:
            size = jnp.asarray(images.shape[-1:-3:-1], dtype)  # (width, height)
        on_frame = jnp.all((markers >= -0.5 * size) & (markers <= 1.5 * size), axis=(-2, -1))
        scorable = jnp.all(jnp.isfinite(refined), axis=-1) & on_frame
        log_likelihoods = jnp.where(scorable, self._log_likelihoods(refined, frame), -jnp.inf)
        kept = _surviving(markers, log_likelihoods, self.merge_radius, self.prune_below)
        best = jnp.argmax(log_likelihoods)
        total = jax.nn.logsumexp(jnp.where(kept, log_likelihoods, -jnp.inf))
        degenerate = ~jnp.isfinite(total)
        num_failed = jnp.sum(failed, dtype=jnp.int32)
        new_state = ModePool(refined, tails, jnp.where(kept, log_likelihoods - total, -jnp.inf),
                             kept, state.time + 1, num_failed)
        # nothing finite to follow (a numerical failure): start again from frame 0's state
        reseeded = eqx.tree_at(lambda s: (s.time, s.failed_refinements), self.seed(),
                               (state.time + 1, num_failed))
        new_state = jax.tree.map(lambda new, seed: jnp.where(degenerate, seed, new), new_state,
                                 reseeded)
        # a degenerate frame reports the pose the pool starts again from, never NaN
        reported = jnp.where(degenerate, spm_forward(self.initial_state, self.template),
                             markers[best])
        estimate = FrameEstimate(
            markers=reported, best_markers=reported,
            ess=jnp.sum(kept).astype(dtype), log_likelihood=log_likelihoods[best],
            degenerate=degenerate,
        )
        return new_state, estimate


class MHTState(eqx.Module):
    """What the MHT tracker carries between frames.

    Attributes:
        model: the arrays assembled at frame 0; constant over the sequence.
        pool: the modes.
        refined: the refinement stage's carried poses (None without a refinement).
        refine_std: ``(25,)`` σ of the refinement's prior (None without a refinement).
    """

    model: MHTModel
    pool: ModePool
    refined: RefinementState | None
    refine_std: Float[Array, " 25"] | None


class MHTTracker(ImageTracker):
    """Cham & Rehg-style multiple-hypothesis tracking (module docstring; :func:`mht_tracker`).

    Attributes:
        template: the SPM template.
        likelihood: how frames are scored (bilinear reads throughout: Gauss–Newton needs
            patches that vary smoothly with the markers).
        modes: static number of modes.
        step_std: ``(25,)`` per-frame std of the state before flooring, or None for
            ``10 × default_noise_floor(torso)``.
        min_step_std: floor of ``step_std`` (scalar or ``(25,)``); None:
            ``default_noise_floor(torso)``.
        velocity_weight: v of the prediction (0: constant position, 1: constant velocity).
        prior_scale: the mode refinement's prior σ in units of ``step_std``.
        refill_spread: refilled modes are drawn this many ``step_std`` about their parent.
        merge_radius: pixels; None: 2 % of the torso.
        prune_below: nats under the best below which modes are dropped.
        max_steps: static Gauss–Newton steps per mode and frame.
        refinement: the full-state refinement stage of the reported mode; None: the best mode.
        background: grey background of a static camera for the foreground term; None: none.
    """

    template: SPMTemplate
    likelihood: Likelihood
    modes: int = eqx.field(static=True)
    step_std: tuple[float, ...] | None = eqx.field(static=True, default=None)
    min_step_std: tuple[float, ...] | None = eqx.field(static=True, default=None)
    # 0 (constant position) chosen on the validation subject over {0, 0.5, 1}: tied with 0.5,
    # the simpler prediction (python -m papers.tian2005.defaults_sweep, docs/defaults.md)
    velocity_weight: float = eqx.field(static=True, default=0.0)
    prior_scale: float = eqx.field(static=True, default=4.0)
    refill_spread: float = eqx.field(static=True, default=2.0)
    merge_radius: float | None = eqx.field(static=True, default=None)
    prune_below: float = eqx.field(static=True, default=1.0)
    max_steps: int = eqx.field(static=True, default=10)
    refinement: Refinement | None = None
    background: Float[Array, "height width"] | None = None

    def __check_init__(self):
        if not isinstance(self.modes, int) or self.modes < 1:
            raise ValueError(f"num_modes must be a positive integer, got {self.modes!r}")
        if not isinstance(self.max_steps, int) or self.max_steps < 1:
            raise ValueError(f"max_steps must be a positive integer, got {self.max_steps!r}")
        for name in ("velocity_weight", "prior_scale", "refill_spread", "prune_below"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if self.merge_radius is not None and not self.merge_radius >= 0:
            raise ValueError(f"merge_radius must be >= 0 pixels, got {self.merge_radius!r}")

    @property
    def num_particles(self) -> int:
        return self.modes

    @property
    def dtype(self):
        return self.template.reference_lengths.dtype

    def options(self) -> dict:
        return {"method": "mht", "particles": self.modes,
                "likelihood": options_record(self.likelihood),
                "refinement": options_record(self.refinement),
                "foreground": self.background is not None,
                "velocity_weight": self.velocity_weight, "prior_scale": self.prior_scale,
                "refill_spread": self.refill_spread, "merge_radius": self.merge_radius,
                "prune_below": self.prune_below, "max_steps": self.max_steps}

    def start(self, key: PRNGKeyArray, first_frame, initial_pose) -> MHTState:
        del key  # frame 0's pose is given: one mode at it, at rest
        markers = check_initial_pose(initial_pose)
        dtype = self.dtype
        cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
        initial = frame0_state(markers, self.template, dtype)
        torso = float(np.exp(np.asarray(initial[0], np.float64)))
        floor = (default_noise_floor(torso) if self.min_step_std is None
                 else np.asarray(self.min_step_std, np.float64))
        floor = np.broadcast_to(floor, (SPM_STATE_SIZE,))
        step_std = (10 * default_noise_floor(torso) if self.step_std is None
                    else np.asarray(self.step_std, np.float64))
        step_std = np.maximum(step_std, floor)
        merge_radius = 0.02 * torso if self.merge_radius is None else self.merge_radius
        model = MHTModel(
            template=self.template,
            templates=frame0_templates(self.likelihood, first_frame, markers, self.background,
                                       dtype),
            initial_state=initial, step_std=cast(step_std), sharpness=cast(self.likelihood.lam),
            velocity_weight=cast(self.velocity_weight), prior_scale=cast(self.prior_scale),
            refill_spread=cast(self.refill_spread), merge_radius=cast(merge_radius),
            prune_below=cast(self.prune_below), modes=self.modes, max_steps=self.max_steps)
        refined, refine_std = start_refinement(self.refinement, initial)
        return MHTState(model, model.seed(), refined, refine_std)

    def first_estimate(self, state: MHTState) -> FrameEstimate:
        return state.model.first_estimate(state.pool)

    def update(self, key: PRNGKeyArray, state: MHTState, frame: Array | FrameInChunk
               ) -> tuple[MHTState, FrameEstimate]:
        model = state.model
        with jax.named_scope("modes"):
            pool, estimate = model.step(key, state.pool, frame_at(frame))
        refined = state.refined
        if self.refinement is not None:
            best = pool.modes[jnp.argmax(pool.log_weights)]
            refined, pose = refine(self.refinement, state.refined, best, frame,
                                   model.templates, model.template, model.sharpness,
                                   state.refine_std)
            estimate = eqx.tree_at(lambda e: e.markers, estimate,
                                   spm_forward(pose, model.template))
        return MHTState(model, pool, refined, state.refine_std), estimate


def mht_tracker(
    template: SPMTemplate,
    training_states: Float[ArrayLike, "time 25"] | None = None,
    *,
    num_modes: int = 10,
    likelihood: Likelihood = Likelihood(),
    refinement: Refinement | None = None,
    background: Float[ArrayLike, "height width"] | None = None,
    step_std: Float[ArrayLike, " 25"] | None = None,
    velocity_weight: float = 0.0,
    prior_scale: float = 4.0,
    refill_spread: float = 2.0,
    merge_radius: float | None = None,
    prune_below: float = 1.0,
    max_steps: int = 10,
    min_step_std: float | Float[ArrayLike, " 25"] | None = None,
    sequence_ids: ArrayLike | None = None,
    dtype=jnp.float32,
) -> MHTTracker:
    """Multiple-hypothesis tracking with ``num_modes`` modes in the 25-d SPM state.

    Args:
        template: the SPM template.
        training_states: ``(time, 25)`` SPM states whose RMS frame-to-frame differences give
            ``step_std`` (the same first 30 ground-truth frames the CONDENSATION baseline
            learns from); ignored when ``step_std`` is given.
        num_modes: the pool size (Tian et al. compared with 10).
        likelihood: how frames are scored.
        refinement: the full-state refinement stage of the reported mode; None: the best mode.
        background: grey background of a static camera for the foreground term; None: none.
        step_std: ``(25,)`` per-frame state std; default from ``training_states`` or, without
            them, ``10 × default_noise_floor(torso)``.
        velocity_weight: see :class:`MHTTracker`.
        prior_scale: see :class:`MHTTracker`.
        refill_spread: see :class:`MHTTracker`.
        merge_radius: see :class:`MHTTracker`.
        prune_below: see :class:`MHTTracker`.
        max_steps: see :class:`MHTTracker`.
        min_step_std: see :class:`MHTTracker`.
        sequence_ids: ``(time,)`` when ``training_states`` stacks several trajectories
            (training clips × views): steps are measured within each, never across two.
        dtype: the tracker's float type.
    """
    if step_std is None and training_states is not None:
        training_states = np.asarray(training_states, np.float64)
        if (training_states.ndim != 2 or training_states.shape[1] != SPM_STATE_SIZE
                or training_states.shape[0] < 2):
            raise ValueError(f"training_states must be (time >= 2, {SPM_STATE_SIZE}) SPM "
                             f"states, got {training_states.shape}")
        step_std = step_std_within(training_states, sequence_ids)
    if step_std is not None:
        step_std = np.asarray(step_std, np.float64)
        if step_std.shape != (SPM_STATE_SIZE,) or not np.all(np.isfinite(step_std)):
            raise ValueError(f"step_std must be ({SPM_STATE_SIZE},) finite, got "
                             f"{step_std.shape}")
    if min_step_std is not None:
        min_step_std = tuple(np.broadcast_to(np.asarray(min_step_std, np.float64),
                                             (SPM_STATE_SIZE,)).tolist())
    cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
    return MHTTracker(
        template=jax.tree.map(cast, template), likelihood=likelihood, modes=num_modes,
        step_std=None if step_std is None else tuple(step_std.tolist()),
        min_step_std=min_step_std, velocity_weight=float(velocity_weight),
        prior_scale=float(prior_scale), refill_spread=float(refill_spread),
        merge_radius=None if merge_radius is None else float(merge_radius),
        prune_below=float(prune_below), max_steps=max_steps, refinement=refinement,
        background=background)
