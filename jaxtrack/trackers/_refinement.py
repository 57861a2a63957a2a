"""The full-state refinement stage: any tracker's reported pose refined on the frame.

A prior learned from a few takes holds poses near the subject's but not the subject's own, and
a sharp likelihood ranks such near misses below poses that fit some limbs exactly; a tracker's
own estimate (μ of the latent particles, the weighted mean SPM state, the best mode) inherits
that. So each frame the stage carries one full 25-d SPM pose and refines two candidates on
the new frame, the pose it reported at the last frame and the tracker's estimate:

1. **Arm search** (:class:`~jaxtrack.trackers.ArmSearch`, optional): Gauss–Newton is local and
   a waving forearm moves more between frames than its strip is wide, so each candidate's arms
   are first searched globally over a grid of upper-arm × forearm angle offsets, about the arm
   as it was and about the arm moved on at constant velocity; the best is kept only if it beats
   the arm as it was by a margin.
2. **Gauss–Newton** (:func:`~jaxtrack.trackers.refine_pose`, ``solver="parts"``) on the
   likelihood under a Gaussian prior about each start.
3. **Choice**: the better-scoring refined candidate is reported and carried.

The stage never feeds back into the tracker's particles or modes, so the tracker's own
robustness is kept and a carried pose that drifts off the subject is replaced as soon as the
tracker's estimate scores better. Every tracker takes the same stage (``refinement=``), so a
comparison between trackers can differ in the prior alone. Measurements: ``docs/trackers.md``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from jaxtrack.body import SPM_MARKERS, SPM_STATE_NAMES, SPM_STATE_SIZE, SPMTemplate, spm_forward
from jaxtrack.likelihoods import PartTemplates
from jaxtrack.priors.dynamics import default_noise_floor
from jaxtrack.trackers._gauss_newton import refine_pose
from jaxtrack.trackers._options import ArmSearch, Refinement
from jaxtrack.trackers._tracker import FrameInChunk, frame_at

__all__ = ["RefinementState", "refine", "refinement_prior_std", "score_pose", "search_arms",
           "start_refinement"]

# (upper arm, forearm) angle entries of the SPM state, right arm then left
_ARM_ANGLES = tuple(
    (SPM_STATE_NAMES.index(f"angle_{side}_shoulder_{side}_elbow"),
     SPM_STATE_NAMES.index(f"angle_{side}_elbow_{side}_wrist"))
    for side in ("right", "left"))
# True at those entries of the SPM state
_ARM_ANGLE_MASK = np.isin(np.arange(SPM_STATE_SIZE), np.ravel(_ARM_ANGLES))
# the markers those angles move (elbow and wrist), right arm then left
_ARM_MARKERS = tuple(
    frozenset(SPM_MARKERS.index(f"{side}_{joint}") for joint in ("elbow", "wrist"))
    for side in ("right", "left"))


class RefinementState(eqx.Module):
    """What the stage carries between frames.

    Attributes:
        pose: ``(25,)`` the SPM pose reported at the last frame (frame 0's at the start).
        previous: ``(25,)`` the pose reported the frame before (``pose`` at the start): the arm
            search's constant-velocity centre is extrapolated from the two.
    """

    pose: Float[Array, " 25"]
    previous: Float[Array, " 25"]


def refinement_prior_std(refinement: Refinement, torso: float) -> np.ndarray:
    """``(25,)`` σ of the Gaussian prior about each start, for a subject whose torso is
    ``torso`` pixels long (float64; :class:`~jaxtrack.trackers.Refinement`)."""
    return refinement.prior_std * default_noise_floor(torso)


def start_refinement(refinement: Refinement | None, initial: Float[Array, " 25"]
                     ) -> tuple[RefinementState | None, Float[Array, " 25"] | None]:
    """The stage's state at frame 0 (``initial``, the frame-0 SPM state, carried) and its
    prior σ for the subject's torso length there; ``(None, None)`` without a refinement."""
    if refinement is None:
        return None, None
    torso = float(np.exp(np.asarray(initial[0], np.float64)))
    prior_std = jnp.asarray(refinement_prior_std(refinement, torso), initial.dtype)
    return RefinementState(initial, initial), prior_std


def score_pose(pose: Float[Array, " 25"], frame: Array, appearance: PartTemplates,
               template: SPMTemplate, sharpness: Array,
               parts: tuple[int, ...] | None = None) -> Float[Array, ""]:
    """Log-likelihood of one SPM pose (bilinear reads), or the sum of its ``parts`` terms
    alone (``part_log_likelihoods``); −inf where it is NaN."""
    markers = spm_forward(pose, template)
    if parts is None:
        value = appearance.log_likelihood(markers, frame, sharpness, False)
    else:  # the terms no part holds depend on the parts too: they are scored with them
        value = jnp.sum(appearance.part_log_likelihoods(markers, frame, sharpness, False, parts))
        if appearance.has_whole_pose_terms:
            value = value + appearance.whole_pose_log_likelihood(markers, frame)
    return jnp.where(jnp.isnan(value), -jnp.inf, value)


def search_arms(search: ArmSearch, pose: Float[Array, " 25"], frame: Array,
                appearance: PartTemplates, template: SPMTemplate, sharpness: Array,
                predicted: Float[Array, " 25"] | None = None) -> Float[Array, " 25"]:
    """The arm search (module docstring): for each arm, the best of ``grid²`` offsets of its
    upper-arm and forearm angles if it beats offset 0 (the middle of the grid) by ``margin``
    nats, the rest of ``pose`` kept; with ``predicted`` (a pose whose arm angles are the
    constant-velocity prediction) the same grid about the predicted arm angles too.

    The offsets move only the elbow and the wrist, so only the terms that depend on them (the
    arm's two strips, ``part_markers``) are scored: the others cancel from the comparison. For
    the same reason the two arms are searched from ``pose`` independently."""
    half = search.grid // 2  # offset 0 exactly in the middle
    offsets = (search.span / max(half, 1)) * jnp.arange(-half, half + 1, dtype=pose.dtype)
    upper, fore = (grid.ravel() for grid in jnp.meshgrid(offsets, offsets))
    searched = pose
    for (upper_index, fore_index), moved in zip(_ARM_ANGLES, _ARM_MARKERS, strict=True):
        parts = tuple(part for part, markers in enumerate(appearance.part_markers)
                      if moved.intersection(markers))
        centres = [pose]
        if predicted is not None:
            centres.append(pose.at[upper_index].set(predicted[upper_index])
                           .at[fore_index].set(predicted[fore_index]))
        trials = jnp.concatenate([
            jnp.broadcast_to(centre, (upper.size, pose.shape[0]))
            .at[:, upper_index].add(upper).at[:, fore_index].add(fore)
            for centre in centres])
        values = jax.vmap(lambda trial, parts=parts: score_pose(
            trial, frame, appearance, template, sharpness, parts))(trials)
        best = jnp.argmax(values)
        better = values[best] - values[upper.size // 2] >= search.margin
        searched = (searched.at[upper_index].set(jnp.where(better, trials[best, upper_index],
                                                           pose[upper_index]))
                    .at[fore_index].set(jnp.where(better, trials[best, fore_index],
                                                  pose[fore_index])))
    return searched


def _predicted(search: ArmSearch | None, state: RefinementState) -> Array | None:
    """The carried pose with its arm angles moved on by ``momentum`` × their change over the
    last frame (wrapped to ±π), or None without a second centre."""
    if search is None or not search.momentum:
        return None
    change = state.pose - state.previous
    change = jnp.arctan2(jnp.sin(change), jnp.cos(change))
    return state.pose + jnp.where(_ARM_ANGLE_MASK, search.momentum * change, 0)


def _refine_one(refinement: Refinement, start: Array, observed: Array | FrameInChunk,
                predicted: Array | None, appearance: PartTemplates,
                template: SPMTemplate, sharpness: Array, prior_std: Array
                ) -> tuple[Array, Array]:
    """One candidate searched (arms) and refined, with its log-likelihood."""
    # the named scopes label the compiled ops by stage (python -m benchmarks.tracker_step --profile)
    frame = frame_at(observed)
    if refinement.arm_search is not None:
        with jax.named_scope("arm_search"):
            start = search_arms(refinement.arm_search, start, frame, appearance, template,
                                sharpness, predicted)
    with jax.named_scope("gauss_newton"):
        # a FrameInChunk is read from the chunk in place (refine_pose); terms of the whole
        # pose (coverage, keypoints) join the block-sparse solver's parts densely
        refined, _ = refine_pose(start, observed, appearance, template, start, prior_std,
                                 sharpness, max_steps=refinement.steps, solver="parts")
    with jax.named_scope("choice"):
        refined = jnp.where(jnp.all(jnp.isfinite(refined)), refined, start)
        return refined, score_pose(refined, frame, appearance, template, sharpness)


def refine(refinement: Refinement, state: RefinementState, estimate: Float[Array, " 25"],
           observed: Array | FrameInChunk, appearance: PartTemplates,
           template: SPMTemplate, sharpness: Array, prior_std: Float[Array, " 25"]
           ) -> tuple[RefinementState, Float[Array, " 25"]]:
    """One frame of the stage (module docstring): the carried pose and the tracker's
    ``estimate`` refined side by side on ``observed``; returns the new state and the pose to
    report."""
    carried = state.pose
    predicted = _predicted(refinement.arm_search, state)
    poses, values = jax.vmap(_refine_one, in_axes=(None, 0, None, None, None, None, None, None))(
        refinement, jnp.stack([carried, estimate.astype(carried.dtype)]), observed, predicted,
        appearance, template, sharpness, prior_std)
    pose = jnp.where(values[0] >= values[1], poses[0], poses[1])
    return RefinementState(pose, carried), pose
