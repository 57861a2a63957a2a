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
   (optimistix, vmapped over modes, ``throw=False``, ``max_steps`` capped) on the MAP cost

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
mode has a finite likelihood (a numerical failure: the NCC cost is bounded) is reported as
degenerate and the pool is re-seeded at frame 0's state.

The defaults (``velocity_weight = 0.5``, ``prior_scale = 4``, ``prune_below = 1``) were chosen
on the bundled wave clip (640 × 480, frontal, 120 frames); constant position or constant
velocity, a tighter prior or no pruning were each worse there.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Float, Int, PRNGKeyArray, PyTree, Scalar

from jaxtrack import smc
from jaxtrack.body import SPM_STATE_SIZE, SPMTemplate, spm_forward, spm_initial_state
from jaxtrack.likelihoods import (
    DEFAULT_LIKELIHOOD,
    DEFAULT_NCC_SHARPNESS,
    AppearanceTemplates,
    default_sharpness,
    make_appearance_templates,
)
from jaxtrack.trackers._parts_gauss_newton import parts_gauss_newton
from jaxtrack.trackers._runner import FrameEstimate
from jaxtrack.trackers.condensation import default_noise_floor

__all__ = ["ArmijoGaussNewton", "MHTState", "MHTTracker", "mht_tracker", "refine_pose",
           "refinement_cost"]


_SOLVERS = ("optimistix", "parts")


def _no_verbose(**kwargs) -> None:
    del kwargs


class ArmijoGaussNewton(optx.AbstractGaussNewton):
    """Gauss–Newton whose steps are damped by a backtracking Armijo line search.

    ``optx.GaussNewton`` always takes the full step (a fixed learning rate of 1); here the
    Newton direction is scaled by 1, ½, ¼, ... until the cost falls by at least ``slope`` times
    the decrease the linearisation predicts, so a refinement never ends worse than it began.
    Every trial step counts toward ``max_steps``.
    """

    rtol: float
    atol: float
    norm: Callable[[PyTree], Scalar] = optx.max_norm
    # normal equations by Cholesky: JᵀJ is positive definite thanks to the prior rows, and on CPU
    # it is an order of magnitude faster than the default QR of the tall (pixels + 25) × 25 J
    descent: optx.NewtonDescent = optx.NewtonDescent(linear_solver=lx.Normal(lx.Cholesky()))
    search: optx.BacktrackingArmijo = optx.BacktrackingArmijo()
    verbose: Callable[..., None] = _no_verbose


def _solver(tolerance: float, dtype) -> ArmijoGaussNewton:
    # the line search's constants in the problem's dtype, so that a float32 solve stays float32
    # when jax_enable_x64 is on (Python floats would become float64 step sizes)
    constant = lambda value: jnp.asarray(value, dtype)  # noqa: E731
    search = optx.BacktrackingArmijo(decrease_factor=constant(0.5), slope=constant(0.1),
                                     step_init=constant(1.0))
    return ArmijoGaussNewton(rtol=tolerance, atol=tolerance, search=search)


class _Problem(eqx.Module):
    frame: Float[Array, "height width"]
    templates: AppearanceTemplates
    template: SPMTemplate
    prior_mean: Float[Array, " 25"]
    prior_std: Float[Array, " 25"]
    sharpness: Float[Array, ""]


def _residuals(state: Array, problem: _Problem) -> Array:
    markers = spm_forward(state, problem.template)
    # ½‖√λ (p̂ − t̂)‖² = λ Σ_m (1 − NCC_m): Tian et al.'s eq. 7 cost as a sum of squares
    image = problem.templates.residuals(markers, problem.frame, problem.sharpness)
    prior = (state - problem.prior_mean) / problem.prior_std
    return jnp.concatenate([image, prior])


def refinement_cost(
    state: Float[ArrayLike, " 25"],
    frame: Float[ArrayLike, "height width"],
    templates: AppearanceTemplates,
    template: SPMTemplate,
    prior_mean: Float[ArrayLike, " 25"],
    prior_std: Float[ArrayLike, " 25"],
    sharpness: float | Float[ArrayLike, ""] = DEFAULT_NCC_SHARPNESS,
) -> Float[Array, ""]:
    """The cost :func:`refine_pose` minimises: ``λ Σ_m (1 − NCC_m) + ½ Σ_d ((x_d − μ_d)/σ_d)²``
    (exactly, for markers whose image patch and template both have texture)."""
    state = jnp.asarray(state)
    problem = _Problem(jnp.asarray(frame, state.dtype), templates, template,
                       jnp.asarray(prior_mean, state.dtype), jnp.asarray(prior_std, state.dtype),
                       jnp.asarray(sharpness, state.dtype))
    return 0.5 * jnp.sum(_residuals(state, problem) ** 2)


def refine_pose(
    state: Float[ArrayLike, " 25"],
    frame: Float[ArrayLike, "height width"],
    templates: AppearanceTemplates,
    template: SPMTemplate,
    prior_mean: Float[ArrayLike, " 25"],
    prior_std: Float[ArrayLike, " 25"],
    sharpness: float | Float[ArrayLike, ""] = DEFAULT_NCC_SHARPNESS,
    *,
    max_steps: int = 10,
    tolerance: float = 1e-4,
    solver: str = "optimistix",
) -> tuple[Float[Array, " 25"], optx.RESULTS]:
    """Refine one SPM state on a frame: damped Gauss–Newton with Armijo line search.

    Minimises :func:`refinement_cost` from ``state`` with :class:`ArmijoGaussNewton`
    (``throw=False``, at most ``max_steps`` trial steps; running out of steps is normal here and
    the last accepted iterate is returned). Pure JAX for ONE state: ``vmap`` it over modes.

    ``solver="parts"`` runs the same iteration outside optimistix with a Jacobian built part
    by part from the templates' ``part_residuals``, ``direct_part_markers`` and
    ``spine_markers`` (``jaxtrack.trackers._parts_gauss_newton``): the same iterates to
    rounding, in a fraction of the time with the limb strips. The MHT baseline keeps
    optimistix's; the latent tracker's refinement uses it.

    A frame sliced out of a chunk of frames and handed to the solver's loop is copied whole
    first (3.7 MB per 640 × 480 frame with edge maps, ~10 % of the latent tracker's time per
    frame in :func:`jaxtrack.trackers.track`'s chunk scan). Given as ``(frames, index)``, the parts
    solver reads it from the chunk in place instead (the same values).

    Args:
        state: ``(25,)`` starting SPM state.
        frame: ``(height, width)`` grey frame (the templates' observation: ``(3, height,
            width)`` with edge maps), or ``(frames, index)`` standing for ``frames[index]``.
        templates: appearance templates (limb strips or marker patches).
        template: the SPM template.
        prior_mean, prior_std: ``(25,)`` Gaussian prior on the state (MHT: the prediction and
            the per-frame step std).
        sharpness: λ of the NCC cost.
        max_steps: static cap on solver steps.
        tolerance: rtol = atol of the Cauchy termination test.
        solver: ``"optimistix"`` or ``"parts"`` (above).

    Returns:
        The refined state and the solver's ``optx.RESULTS``.
    """
    if solver not in _SOLVERS:
        raise ValueError(f"solver must be one of {_SOLVERS}, got {solver!r}")
    state = jnp.asarray(state)
    dtype = state.dtype
    if isinstance(frame, tuple) and len(frame) != 2:
        raise ValueError(f"frame must be an array or a (frames, index) pair, got a tuple of "
                         f"{len(frame)}")
    frames, index = frame if isinstance(frame, tuple) else (None, None)
    if frames is not None:
        frame = frames[index]
    problem = _Problem(jnp.asarray(frame, dtype), templates, template,
                       jnp.asarray(prior_mean, dtype), jnp.asarray(prior_std, dtype),
                       jnp.asarray(sharpness, dtype))
    if solver == "parts":
        def read(markers):  # the markers, and the frame they are scored on
            if frames is None:
                return markers, problem.frame
            # sliced inside the solver's loop, where the slice fuses into the reads; the
            # barrier ties the index to the iterate, or XLA hoists the slice out of the loop
            # and copies the frame whole (docstring)
            index_now, markers = jax.lax.optimization_barrier((index, markers))
            return markers, frames[index_now]

        def parts(markers, *spine):  # the spine length, where the templates read it apart
            markers, observation = read(markers)
            return templates.part_residuals(markers, observation, problem.sharpness, *spine)

        return parts_gauss_newton(
            parts, templates.direct_part_markers, lambda pose: spm_forward(pose, template),
            state, problem.prior_mean, problem.prior_std, spine_markers=templates.spine_markers,
            max_steps=max_steps, tolerance=tolerance)
    solver = _solver(tolerance, dtype)
    solution = optx.least_squares(_residuals, solver, state, args=problem, max_steps=max_steps,
                                  throw=False)
    return solution.value, solution.result


class MHTState(eqx.Module):
    """What the MHT tracker carries between frames.

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


class MHTTracker(eqx.Module):
    """Cham & Rehg-style multiple-hypothesis tracking (see :func:`mht_tracker`).

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
    templates: AppearanceTemplates
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

    @property
    def num_particles(self) -> int:
        return self.modes

    def _markers(self, states: Array) -> Array:
        return jax.vmap(spm_forward, in_axes=(0, None))(states, self.template)

    def _log_likelihoods(self, states: Array, frame: Array) -> Array:
        values = jax.vmap(self.templates.log_likelihood, in_axes=(0, None, None, None))(
            self._markers(states), frame, self.sharpness, False)
        return jnp.where(jnp.isnan(values), -jnp.inf, values)

    def _seed(self) -> MHTState:
        """One mode at frame 0's state, at rest; the next frame fills the pool around it."""
        dtype = self.initial_state.dtype
        modes = jnp.broadcast_to(self.initial_state, (self.modes, SPM_STATE_SIZE))
        kept = jnp.arange(self.modes) == 0
        log_weights = jnp.where(kept, 0.0, -jnp.inf).astype(dtype)
        return MHTState(modes, modes, log_weights, kept, jnp.asarray(0), jnp.asarray(0))

    def start(self, key: PRNGKeyArray, frame: Float[Array, "height width"]) -> MHTState:
        del key, frame  # frame 0's state is given
        return self._seed()

    def first_estimate(self, state: MHTState) -> FrameEstimate:
        best = jnp.argmax(state.log_weights)
        markers = spm_forward(state.modes[best], self.template)
        # frame 0's pose is given, not scored: its log-likelihood is reported as 0 (every NCC
        # is 1 there, the templates having been cut at these markers)
        return FrameEstimate(markers=markers, best_markers=markers,
                             ess=jnp.sum(state.kept).astype(markers.dtype),
                             log_likelihood=jnp.asarray(0, markers.dtype),
                             degenerate=jnp.asarray(False))

    def update(self, key: PRNGKeyArray, state: MHTState, frame: Float[Array, "height width"]
               ) -> tuple[MHTState, FrameEstimate]:
        dtype = self.initial_state.dtype
        frame = jnp.asarray(frame, dtype)
        key_parents, key_refill = jr.split(key)
        # 1. predict every mode
        predicted = state.modes + self.velocity_weight * (state.modes - state.previous)
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

        # 3. weight, merge and prune
        log_likelihoods = self._log_likelihoods(refined, frame)
        markers = self._markers(refined)
        kept = _surviving(markers, log_likelihoods, self.merge_radius, self.prune_below)
        best = jnp.argmax(log_likelihoods)
        total = jax.nn.logsumexp(jnp.where(kept, log_likelihoods, -jnp.inf))
        degenerate = ~jnp.isfinite(total)
        num_failed = jnp.sum(failed, dtype=jnp.int32)
        new_state = MHTState(refined, tails, jnp.where(kept, log_likelihoods - total, -jnp.inf),
                             kept, state.time + 1, num_failed)
        # nothing finite to follow (a numerical failure): start again from frame 0's state
        reseeded = eqx.tree_at(lambda s: (s.time, s.failed_refinements), self._seed(),
                               (state.time + 1, num_failed))
        new_state = jax.tree.map(lambda new, seed: jnp.where(degenerate, seed, new), new_state,
                                 reseeded)
        estimate = FrameEstimate(
            markers=markers[best], best_markers=markers[best],
            ess=jnp.sum(kept).astype(dtype), log_likelihood=log_likelihoods[best],
            degenerate=degenerate,
        )
        return new_state, estimate


def mht_tracker(
    template: SPMTemplate,
    first_frame: Float[ArrayLike, "height width"],
    first_markers: Float[ArrayLike, "markers 2"],
    training_states: Float[ArrayLike, "time 25"] | None = None,
    *,
    num_modes: int = 10,
    likelihood: str = DEFAULT_LIKELIHOOD,
    background: Float[ArrayLike, "height width"] | None = None,
    sharpness: float | None = None,
    step_std: Float[ArrayLike, " 25"] | None = None,
    velocity_weight: float = 0.5,
    prior_scale: float = 4.0,
    refill_spread: float = 2.0,
    merge_radius: float | None = None,
    prune_below: float = 1.0,
    max_steps: int = 10,
    min_step_std: float | Float[ArrayLike, " 25"] | None = None,
    dtype=jnp.float32,
) -> MHTTracker:
    """Multiple-hypothesis tracking with ``num_modes`` modes in the 25-d SPM state.

    Args:
        template: the SPM template.
        first_frame: ``(height, width)`` grey frame 0 (the NCC templates are cut from it).
        first_markers: ``(12, 2)`` its markers (``SPM_MARKERS`` order).
        training_states: ``(time, 25)`` SPM states whose RMS frame-to-frame differences give
            ``step_std`` (the same first 30 ground-truth frames the CONDENSATION baseline
            learns from); ignored when ``step_std`` is given.
        num_modes: the pool size (Tian et al. compared with 10).
        likelihood: ``"limbs+edges"``, ``"limbs"`` or ``"markers"``
            (:mod:`jaxtrack.likelihoods.appearance`).
        background: ``(height, width)`` grey background of a static camera for the
            ``"limbs+edges"`` likelihood's foreground term; None: none.
        sharpness: λ of the likelihood and of the refinement cost; None for the likelihood's
            default.
        step_std: ``(25,)`` per-frame state std; default from ``training_states`` or, without
            them, :func:`~jaxtrack.trackers.condensation.default_noise_floor` × 10.
        velocity_weight: prediction ``x + v (x − x_prev)``; 0 is constant position.
        prior_scale: the refinement prior's σ in units of ``step_std``.
        refill_spread: std of refilled modes around their parent, in units of ``step_std``.
        merge_radius: pixels; default 2 % of the torso length.
        prune_below: nats; modes whose log-likelihood is further under the best one's are
            dropped and refilled.
        max_steps: Gauss–Newton trial steps per mode and frame.
        min_step_std: floor of ``step_std``; default ``default_noise_floor(torso)``.
        dtype: the tracker's float type.
    """
    first_markers = np.asarray(first_markers, np.float64)
    if first_markers.shape != (12, 2) or not np.all(np.isfinite(first_markers)):
        raise ValueError(f"first_markers must be 12 finite (x, y) markers, got shape "
                         f"{first_markers.shape}")
    if num_modes < 1 or max_steps < 1:
        raise ValueError(f"num_modes and max_steps must be positive, got {num_modes}, "
                         f"{max_steps}")
    if sharpness is None:
        sharpness = default_sharpness(likelihood)
    cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
    template = jax.tree.map(cast, template)
    initial = spm_initial_state(cast(first_markers), template)
    torso = float(np.exp(np.asarray(initial[0], np.float64)))
    floor = default_noise_floor(torso) if min_step_std is None else min_step_std
    floor = np.broadcast_to(np.asarray(floor, np.float64), (SPM_STATE_SIZE,))
    if step_std is None:
        if training_states is None:
            step_std = 10 * default_noise_floor(torso)
        else:
            training_states = np.asarray(training_states, np.float64)
            if (training_states.ndim != 2 or training_states.shape[1] != SPM_STATE_SIZE
                    or training_states.shape[0] < 2):
                raise ValueError(f"training_states must be (time >= 2, {SPM_STATE_SIZE}) SPM "
                                 f"states, got {training_states.shape}")
            step_std = np.sqrt(np.mean(np.diff(training_states, axis=0) ** 2, axis=0))
    step_std = np.asarray(step_std, np.float64)
    if step_std.shape != (SPM_STATE_SIZE,) or not np.all(np.isfinite(step_std)):
        raise ValueError(f"step_std must be ({SPM_STATE_SIZE},) finite, got {step_std.shape}")
    step_std = np.maximum(step_std, floor)
    if merge_radius is None:
        merge_radius = 0.02 * torso
    return MHTTracker(
        template=template,
        templates=make_appearance_templates(likelihood, cast(first_frame), cast(first_markers),
                                            background),
        initial_state=initial, step_std=cast(step_std), sharpness=cast(sharpness),
        velocity_weight=cast(velocity_weight), prior_scale=cast(prior_scale),
        refill_spread=cast(refill_spread), merge_radius=cast(merge_radius),
        prune_below=cast(prune_below),
        modes=int(num_modes), max_steps=int(max_steps),
    )
