"""Damped Gauss–Newton for likelihoods that are sums of parts, each reading a few markers.

:func:`jaxtrack.trackers.refine_pose` minimises ``½ ‖r(y)‖²`` over one SPM state ``y`` (25
numbers), ``r`` being the likelihood's residuals at the markers ``m = spm_forward(y)`` and a
Gaussian prior's. optimistix's Gauss–Newton (:class:`jaxtrack.trackers.mht.ArmijoGaussNewton`)
builds the whole Jacobian ``∂r/∂y`` by pushing 25 tangents through the likelihood, then
``JᵀJ``: with the limb strips and their edges, 961 residuals, that is most of the latent
tracker's per-frame cost. But every likelihood here is a sum of parts (a strip, a patch) and
each part reads only a few markers (``templates.part_markers``: a strip's two ends, and the
neck and pelvis, whose distance sets its width), so ``∂r/∂m`` is block sparse. Here:

* **Compressed tangents.** Two markers that no part reads together can share a tangent: the
  derivative of each part along their summed direction is its derivative in the one marker it
  reads. A greedy colouring of the markers (two markers clash when a part reads both) gives
  the tangents (x and y per colour) that give every part's Jacobian block exactly; 2 for
  marker patches (one colour).
* **The spine length as an input of its own.** Every strip reads the neck and pelvis, but only
  through their distance ``s`` (its width, the edge term's σ). Given ``s`` as a second input
  (``spine_markers``; ``part_residuals(..., spine=s)``), a strip reads its two ends alone
  (``templates.direct_part_markers``): the skeleton's segments form a tree, so 2 colours, and
  ``∂r/∂s`` one more tangent: 5 tangents instead of the 8 of colouring all the markers read
  (neck and pelvis would each need a colour of their own), and ``∂s/∂y`` one more row of
  ``∂m/∂y``. The Jacobian is the same, by the chain rule.
* **Normal equations per part.** ``JᵀJ = Σ_p D_pᵀ (B_pᵀ B_p) D_p`` with ``B_p`` part p's
  compressed block and ``D_p`` the rows of ``∂(m, s)/∂y`` (from the 25-tangent Jacobian of the
  SPM's 12 markers and the spine length, which is cheap) for the markers p reads; ``Jᵀr``
  likewise.
* **Terms of the whole pose** (the coverage and keypoint terms of
  ``jaxtrack.likelihoods.edges``), which no part holds, come as a second, short residual
  vector ``whole(m)``: its Jacobian in the markers is taken densely (one tangent per marker
  coordinate, 24; cheap, since these terms read no image but a few values) and chained
  through ``∂m/∂y``, then added to ``JᵀJ`` and ``Jᵀr``.
* **The same iteration as optimistix's.** Each trial step costs one residual and Jacobian
  evaluation; a step is accepted when it lowers the cost by at least ``slope`` times the
  decrease the linearisation predicts (Armijo), and then the Newton direction (Cholesky of
  ``JᵀJ``, positive definite thanks to the prior's rows) is recomputed and the step size reset
  to 1; otherwise the step is halved. It stops after ``max_steps`` evaluations, the first
  included, or when an accepted step moves neither the state nor the residuals by more than
  ``tolerance`` (optimistix's Cauchy test). Given the same start it reaches optimistix's
  iterate to rounding (tested), in about half the time (``benchmarks/tracker_step.py``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from jaxtrack.likelihoods.limbs import spine_length


def marker_colours(part_markers: Sequence[Sequence[int]], num_markers: int) -> tuple[int, ...]:
    """A colour per marker such that no part reads two markers of one colour (greedy, the
    markers that clash with the most others first)."""
    clashes = [set() for _ in range(num_markers)]
    for markers in part_markers:
        for marker in markers:
            if not 0 <= marker < num_markers:
                raise ValueError(f"part markers must be indices below {num_markers}, got "
                                 f"{tuple(markers)}")
            clashes[marker].update(set(markers) - {marker})
    colours: dict[int, int] = {}
    for marker in sorted(range(num_markers), key=lambda m: (-len(clashes[m]), m)):
        taken = {colours[other] for other in clashes[marker] if other in colours}
        colours[marker] = next(colour for colour in range(num_markers) if colour not in taken)
    return tuple(colours[marker] for marker in range(num_markers))


@functools.cache
def _structure(part_markers: tuple[tuple[int, ...], ...], num_markers: int, spine: bool
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(tangents, spine_tangents, rows, mask)``: the compressed tangents ``(2 colours (+ 1),
    markers, 2)`` of the markers and, with ``spine``, ``(2 colours + 1,)`` of the spine length
    (the last tangent moves it alone); for each part and tangent the row of ``∂(m, s)/∂y``
    (flattened markers, then the spine length) it stands for there, and 1 where the part
    reads a marker of that colour, or the spine length (else 0)."""
    colours = marker_colours(part_markers, num_markers)
    num_tangents = 2 * (max(colours) + 1) + spine
    tangents = np.zeros((num_tangents, num_markers, 2))
    for marker, colour in enumerate(colours):
        tangents[2 * colour, marker, 0] = tangents[2 * colour + 1, marker, 1] = 1
    spine_tangents = np.zeros(num_tangents)
    rows = np.zeros((len(part_markers), num_tangents), np.int32)
    mask = np.zeros((len(part_markers), num_tangents))
    for part, markers in enumerate(part_markers):
        for marker in set(markers):
            for axis in range(2):
                rows[part, 2 * colours[marker] + axis] = 2 * marker + axis
                mask[part, 2 * colours[marker] + axis] = 1
    if spine:  # every part reads the spine length
        spine_tangents[-1], rows[:, -1], mask[:, -1] = 1, 2 * num_markers, 1
    return tangents, spine_tangents, rows, mask


def _linearise(state: Array, to_markers: Callable, parts: Callable, prior_mean: Array,
               prior_std: Array, part_markers: tuple[tuple[int, ...], ...],
               spine_markers: tuple[int, int] | None, whole: Callable | None = None
               ) -> tuple[Array, Array, Array, Array]:
    """``(cost, gradient Jᵀr, normal matrix JᵀJ, residuals)`` at ``state``, prior included."""
    dtype = state.dtype

    def observed(y):  # the markers and, with spine_markers, the spine length
        markers = to_markers(y)
        if spine_markers is None:
            return markers, jnp.zeros((), markers.dtype)
        return markers, spine_length(markers, spine_markers)

    (markers, spine), observed_tangent = jax.linearize(observed, state)
    num_markers = markers.shape[0]
    tangents, spine_tangents, rows, mask = _structure(part_markers, num_markers,
                                                      spine_markers is not None)
    tangents, mask = jnp.asarray(tangents, dtype), jnp.asarray(mask, dtype)
    # ∂(m, s)/∂y, (2 markers + 1, 25): small, so all 25 tangents
    marker_jacobian, spine_jacobian = jax.vmap(observed_tangent, out_axes=-1)(
        jnp.eye(state.shape[0], dtype=dtype))
    marker_jacobian = jnp.concatenate([marker_jacobian.reshape(2 * num_markers, -1),
                                       spine_jacobian[None]])
    # parts(markers) or, with spine_markers, parts(markers, spine length)
    inputs, directions = (markers,), (tangents,)
    if spine_markers is not None:
        inputs, directions = (markers, spine), (tangents, jnp.asarray(spine_tangents, dtype))
    residuals, part_tangent = jax.linearize(parts, *inputs)  # (parts, k)
    compressed = jax.vmap(part_tangent)(*directions)  # (tangents, parts, k)
    # per part: B_pᵀ B_p and B_pᵀ r_p in the compressed coordinates (broadcast products and
    # sums, which XLA on CPU fuses; batched small dots cost it more)
    gram = jnp.sum(compressed[:, None] * compressed[None], axis=-1)  # (tangents, tangents, parts)
    projected = jnp.sum(compressed * residuals[None], axis=-1)  # (tangents, parts)
    rows_of = marker_jacobian[rows] * mask[..., None]  # D_p: (parts, tangents, 25)
    weighted = jnp.sum(jnp.transpose(gram, (2, 0, 1))[..., None] * rows_of[:, None], axis=2)
    normal = (rows_of.reshape(-1, state.shape[0]).T @ weighted.reshape(-1, state.shape[0])
              + jnp.diag(1 / prior_std**2))
    prior = (state - prior_mean) / prior_std
    gradient = jnp.sum(rows_of * projected.T[..., None], axis=(0, 1)) + prior / prior_std
    cost = 0.5 * (jnp.sum(residuals**2) + jnp.sum(prior**2))
    flat = [residuals.reshape(-1)]
    if whole is not None:  # dense in the markers (module docstring)
        extra, whole_tangent = jax.linearize(whole, markers)
        marker_tangents = jnp.eye(2 * num_markers, dtype=dtype).reshape(-1, num_markers, 2)
        whole_jacobian = jax.vmap(whole_tangent, out_axes=-1)(marker_tangents) @ \
            marker_jacobian[:2 * num_markers]  # (k, 25)
        normal = normal + whole_jacobian.T @ whole_jacobian
        gradient = gradient + whole_jacobian.T @ extra
        cost = cost + 0.5 * jnp.sum(extra**2)
        flat.append(extra)
    return cost, gradient, normal, jnp.concatenate([*flat, prior])


def parts_gauss_newton(
    parts: Callable[[Array], Float[Array, "parts k"]],
    part_markers: Sequence[Sequence[int]],
    to_markers: Callable[[Array], Float[Array, "markers 2"]],
    state: Float[Array, " n"],
    prior_mean: Float[Array, " n"],
    prior_std: Float[Array, " n"],
    *,
    spine_markers: tuple[int, int] | None = None,
    whole: Callable[[Array], Float[Array, " k"]] | None = None,
    max_steps: int,
    tolerance: float,
    slope: float = 0.1,
    decrease_factor: float = 0.5,
) -> tuple[Float[Array, " n"], optx.RESULTS]:
    """Minimise ``½ ‖parts(to_markers(y))‖² + ½ ‖(y − prior_mean) / prior_std‖²`` from
    ``state`` by Armijo-damped Gauss–Newton (module docstring).

    Args:
        parts: markers → residuals grouped by part, ``(parts, k)``; row p may depend only on
            the markers ``part_markers[p]`` names (that is what makes the Jacobian exact).
            With ``spine_markers``: ``(markers, spine length) → (parts, k)``.
        part_markers: static; the markers each part reads (with ``spine_markers``: other
            than through the spine length).
        to_markers: state → ``(markers, 2)``.
        state, prior_mean, prior_std: the start and the Gaussian prior, all ``(n,)``.
        spine_markers: static; None, or two markers (neck, pelvis) whose distance every part
            also reads, as ``parts``' second argument: it gets one tangent of its own (module
            docstring).
        whole: None, or markers → the residuals of terms of the whole pose, added to the
            cost (module docstring).
        max_steps: static cap on residual evaluations (the start's included).
        tolerance: rtol = atol of the Cauchy termination test.
        slope, decrease_factor: Armijo's sufficient-decrease fraction and the backtracking
            factor.

    Returns:
        The last accepted state, and ``successful`` if the termination test was met or
        ``max_steps_reached``.
    """
    part_markers = tuple(tuple(int(marker) for marker in markers) for markers in part_markers)
    if spine_markers is not None:
        spine_markers = tuple(int(marker) for marker in spine_markers)
    dtype = state.dtype
    linearise = functools.partial(_linearise, to_markers=to_markers, parts=parts,
                                  prior_mean=prior_mean, prior_std=prior_std,
                                  part_markers=part_markers, spine_markers=spine_markers,
                                  whole=whole)

    def newton(gradient, normal):
        return -jax.scipy.linalg.cho_solve((jnp.linalg.cholesky(normal), True), gradient)

    cost, gradient, normal, residuals = linearise(state)
    one = jnp.ones((), dtype)

    def body(_, carry):
        y, cost, gradient, direction, step, residuals, done = carry
        trial = y + step * direction
        trial_cost, trial_gradient, trial_normal, trial_residuals = linearise(trial)
        predicted = jnp.dot(gradient, trial - y)
        accept = ~done & (trial_cost - cost <= slope * predicted) & (predicted <= 0)
        converged = ((jnp.max(jnp.abs(trial - y) / (tolerance + tolerance * jnp.abs(trial)))
                      < 1)
                     & (jnp.max(jnp.abs(trial_residuals - residuals)
                                / (tolerance + tolerance * jnp.abs(trial_residuals))) < 1))

        def pick(new, old):
            return jnp.where(accept, new, old)

        return (pick(trial, y), pick(trial_cost, cost), pick(trial_gradient, gradient),
                pick(newton(trial_gradient, trial_normal), direction),
                jnp.where(accept, one, decrease_factor * step).astype(dtype),
                pick(trial_residuals, residuals), done | (accept & converged))

    carry = (state, cost, gradient, newton(gradient, normal), one, residuals, jnp.asarray(False))
    carry = jax.lax.fori_loop(1, max_steps, body, carry)
    result = optx.RESULTS.where(carry[-1], optx.RESULTS.successful,
                                optx.RESULTS.nonlinear_max_steps_reached)
    return carry[0], result
