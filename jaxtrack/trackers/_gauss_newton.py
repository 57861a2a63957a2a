"""Damped Gauss–Newton refinement of one SPM pose on a frame (Cham & Rehg's local search).

:func:`refine_pose` minimises the MAP cost

    ½‖r(x)‖² = λ Σ_m (1 − NCC_m(x)) + ½ Σ_d ((x_d − μ_d) / σ_d)²,

the NCC dissimilarity of Tian et al.'s eq. 7 plus a Gaussian prior about ``μ``, by Gauss–Newton
with a backtracking Armijo line search (:class:`ArmijoGaussNewton`, optimistix), or by the same
iteration with a Jacobian built part by part (``solver="parts"``,
:mod:`jaxtrack.trackers._parts_gauss_newton`). The image residuals are the per-pixel
differences of the zero-mean, unit-norm patches and templates, ``√λ (p̂_m − t̂_m)``: since
``‖p̂ − t̂‖² = 2 − 2 NCC`` their half squared norm is exactly the NCC cost, and their Jacobian
(one row per patch pixel) is far better conditioned than that of a single ``1 − NCC_m`` per
marker. The MHT baseline refines its modes with it, and the refinement stage
(:mod:`jaxtrack.trackers._refinement`) the pose any tracker reports.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx
from jaxtyping import Array, ArrayLike, Float, PyTree, Scalar

from jaxtrack.body import SPMTemplate, spm_forward
from jaxtrack.likelihoods import DEFAULT_NCC_SHARPNESS, PartTemplates
from jaxtrack.trackers._parts_gauss_newton import parts_gauss_newton
from jaxtrack.trackers._tracker import FrameInChunk, frame_at

__all__ = ["ArmijoGaussNewton", "refine_pose", "refinement_cost"]

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
    frame: PyTree[Array]  # the frame's observation (an image array or an ImageObservation)
    templates: PartTemplates
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
    templates: PartTemplates,
    template: SPMTemplate,
    prior_mean: Float[ArrayLike, " 25"],
    prior_std: Float[ArrayLike, " 25"],
    sharpness: float | Float[ArrayLike, ""] = DEFAULT_NCC_SHARPNESS,
) -> Float[Array, ""]:
    """The cost :func:`refine_pose` minimises: ``λ Σ_m (1 − NCC_m) + ½ Σ_d ((x_d − μ_d)/σ_d)²``
    (exactly, for markers whose image patch and template both have texture)."""
    state = jnp.asarray(state)
    problem = _Problem(jax.tree.map(lambda leaf: jnp.asarray(leaf, state.dtype), frame),
                       templates, template,
                       jnp.asarray(prior_mean, state.dtype), jnp.asarray(prior_std, state.dtype),
                       jnp.asarray(sharpness, state.dtype))
    return 0.5 * jnp.sum(_residuals(state, problem) ** 2)


def refine_pose(
    state: Float[ArrayLike, " 25"],
    frame: Float[ArrayLike, "height width"],
    templates: PartTemplates,
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
    optimistix's; the refinement stage uses it.

    A frame sliced out of a chunk of frames and handed to the solver's loop is copied whole
    first (3.7 MB per 640 × 480 frame with edge maps). Given as a ``FrameInChunk``, the parts
    solver reads it from the chunk in place instead (the same values).

    Args:
        state: ``(25,)`` starting SPM state.
        frame: ``(height, width)`` grey frame (the templates' observation: ``(3, height,
            width)`` with edge maps), or a ``FrameInChunk`` standing for ``frames[index]``.
        templates: appearance templates (limb strips or marker patches).
        template: the SPM template.
        prior_mean: ``(25,)`` mean of the Gaussian prior on the state (MHT: the prediction).
        prior_std: ``(25,)`` its standard deviations (MHT: the per-frame step std).
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
    if isinstance(frame, FrameInChunk):
        frames, index = frame.frames, frame.index
        frame = frame_at(frame)
    elif isinstance(frame, tuple):
        raise ValueError("frame must be an array or a FrameInChunk (the chunk and an index), "
                         f"got a tuple of {len(frame)}")
    else:
        frames = index = None
    cast = lambda leaf: jnp.asarray(leaf, dtype)  # noqa: E731
    problem = _Problem(jax.tree.map(cast, frame), templates, template,
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
            return markers, jax.tree.map(lambda leaf: leaf[index_now], frames)

        def parts(markers, *spine):  # the spine length, where the templates read it apart
            markers, observation = read(markers)
            return templates.part_residuals(markers, observation, problem.sharpness, *spine)

        def whole(markers):  # the terms of the whole pose (coverage, keypoints)
            return templates.whole_pose_residuals(*read(markers))

        return parts_gauss_newton(
            parts, templates.direct_part_markers, lambda pose: spm_forward(pose, template),
            state, problem.prior_mean, problem.prior_std, spine_markers=templates.spine_markers,
            whole=whole if templates.has_whole_pose_terms else None,
            max_steps=max_steps, tolerance=tolerance)
    solver = _solver(tolerance, dtype)
    solution = optx.least_squares(_residuals, solver, state, args=problem, max_steps=max_steps,
                                  throw=False)
    return solution.value, solution.result
