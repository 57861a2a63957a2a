"""Mixed-state temporal integration of silhouette body-part hypotheses (Kwatra, Bobick & Johnson
2002, §3.2–3.3): a particle filter over (posture, part positions, part velocities), smoothed
over the whole sequence by ancestry tracing. The filter is the SMC engine
(:mod:`jaxtrack.smc`) running :class:`MixedStateModel`, whose proposal hooks
(``init_propose``, ``propose``) carry steps 1 and 3–5 below and whose log-weight correction is
the posture evidence of step 6.

A particle is ``{"posture": int, "parts": (5, 2), "velocities": (5, 2)}`` (head, two hands, two
feet, pixels). Per frame t, with the posture likelihoods p(h_t | q) of
:class:`jaxtrack.priors.postures.PostureModel` and the hypotheses Z_t of
:mod:`jaxtrack.vision.parts`:

1. (t = 1, §3.2 step 1) q ~ π(q) p(h_1 | q) normalised; parts ~ N(z_1^q, σ_init² I) about
   that posture's hypotheses; velocities ~ N(0, σ_v,init² I).
2. Resample (systematic) by the weights.
3. Posture, sampled directly from the prediction matrix (eq. 8–9):

       F_ij = p(h_t | q = j) T_ij / Σ_j' p(h_t | q = j') T_ij'

   The row normaliser Σ_j p(h_t | j) T_ij of the parent's posture i enters the weight (step 6):
   it is the exact importance weight of this proposal for the target p(q_1:t, x_1:t | h, Z),
   so the filter and the smoother estimate that posterior and not a heuristic of it (the
   paper's weighting omits it; with it the smoother's posture matches brute-force enumeration,
   tests/mixed_state/test_smoothing.py).
4. Parts, constant velocity plus white noise: v' = v + σ_v ε, x' = x + v' + σ_x ε'; a
   particle whose posture changed has its parts re-drawn about the new posture's hypotheses
   instead (``MixedStateModel.redraw_on_switch``, chosen on validation clips). With
   ``part_proposal="posterior"`` each part is drawn instead from that prediction times its
   term of the part likelihood (eq. 7), exactly: the paper's exp(−min(δ, d)) is bounded by the
   mixture exp(−d) + exp(−δ), whose product with the Gaussian prediction is a two-component
   Gaussian mixture (the prediction conditioned on the hypothesis, and the prediction itself);
   the correction log Z − log(exp(−d) + exp(−δ)) per part makes the weight that of the same
   target. Drawn from the prediction alone, 300 or 1000 particles in 20 dimensions (five
   parts' positions and velocities) keep an effective sample size of a few, and the smoothed
   parts are noisier than hypotheses of white noise they integrate; drawn from the posterior
   they average it (``python -m papers.kwatra2002.diagnosis --synthetic``,
   ``tests/papers/test_kwatra2002_stages.py``). Not the default: on HDM05 actor bd's
   validation takes, whose hypotheses' error persists for seconds, it scored worse (smoothed
   MSE 6 496 px² against 6 053, ``papers/kwatra2002/README.md``, 2026-11-29).
5. Any predicted part outside the silhouette is moved to the nearest silhouette pixel: one
   gather from the frame's nearest-point map
   (:func:`jaxtrack.vision.parts.nearest_silhouette_points`); the velocity becomes the
   displacement actually made.
6. Weight: log w = log p(Z_t | x, q) (eq. 4–7,
   :class:`jaxtrack.likelihoods.part_distances.PartDistances`) + log Σ_j p(h_t | j) T_{q_parent j}
   (at t = 1: + log Σ_q π(q) p(h_1 | q), the same for every particle, so that the log evidence
   is the model's).

A frame whose silhouette is empty or fills the image (status ≠ ok) carries no evidence: postures
follow T alone, parts are not projected, weights are unchanged, and the frame's status is
reported. Nothing there can produce NaN.

Estimates: the posture of largest total weight, and the weighted mean of the parts over the
particles in that posture (hand and foot slots follow each posture's own convention, so a mean
across postures would blur two conventions). The smoother (:func:`smooth`) traces every final
particle's ancestry (:func:`jaxtrack.smc.trace_ancestry`, §3.3) and reports, per frame, the MAP
posture of the paths' posture marginals under the final weights and the expected parts over the
paths in that posture. :func:`smooth_fixed_lag` gives the same for video streamed in chunks.
:func:`smooth_backward` is the two-pass smoother for comparison: forward filtering, backward
simulation (:func:`jaxtrack.smc.ffbsi`), which draws each path's particle at frame t from all
of frame t's particles, weighted by the dynamics' density of the path's next state, instead of
from its own ancestry: paths that do not collapse onto a few ancestors, at a cost of
paths × particles density evaluations per frame. See ``docs/mixed-state.md``.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax import lax
from jaxtyping import Array, Bool, Float, Int, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.likelihoods.part_distances import PartDistances
from jaxtrack.priors.postures import NUM_POSTURES, PostureModel
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk

__all__ = ["MixedStateEstimate", "MixedStateFrame", "MixedStateHistory", "MixedStateModel",
           "MixedStateResult", "MixedStateTracker",
           "SmoothedPostures", "filter_sequence", "instantaneous_estimates",
           "observations_from_silhouettes", "smooth", "smooth_backward", "smooth_fixed_lag",
           "with_detections"]

FRAME_OK = 0  # jaxtrack.vision.histograms.FRAME_OK (imported lazily: vision needs OpenCV)
KEYPOINT_CONFIDENCE = 0.5
"""The least confidence of a detector's keypoint that replaces a silhouette's part hypothesis
(:class:`MixedStateTracker`'s ``keypoint_confidence``): MediaPipe's own drawing threshold, as
the detection baselines' (``jaxtrack.experiments.detections_evaluation.MIN_CONFIDENCE``); not
chosen by a score."""


class MixedStateFrame(eqx.Module):
    """One frame's observation (or, with a leading ``time`` axis, a sequence's).

    Attributes:
        features: ``(features,)`` silhouette projection-histogram features h_t.
        hypotheses: ``(postures, parts, 2)`` every posture's part hypotheses Z_t (pixels).
        nearest: ``(height, width, 2)`` int16 nearest silhouette pixel (x, y) of every pixel.
        status: ``FRAME_OK`` (0), or why the frame holds no silhouette evidence.
    """

    features: Float[Array, "*time features"]
    hypotheses: Float[Array, "*time postures parts 2"]
    nearest: Int[Array, "*time height width 2"]
    status: Int[Array, "*time"]


class MixedStateModel(smc.StateSpaceModel):
    """The posture model, the part likelihood and the dynamics' noise (module docstring), as a
    model of the engine (:class:`jaxtrack.smc.StateSpaceModel`): a particle is
    ``{"posture": int32, "parts": (5, 2), "velocities": (5, 2)}``, an observation one
    :class:`MixedStateFrame`. It proposes (``init_propose``, ``propose``: steps 1 and 3–5 of
    the module docstring) with the posture evidence as the log-weight correction, and its
    ``log_likelihood`` is the parts' term alone (step 6).

    Attributes:
        postures: p(h | q), T and π.
        part_likelihood: eq. 4–7.
        position_std: σ_x, pixels per frame.
        velocity_std: σ_v, pixels per frame per frame.
        initial_std: σ_init, the spread of the first parts about z_1^q (pixels), and of
            parts re-drawn about a frame's hypotheses (``redetect_probability``).
        initial_velocity_std: σ_v,init.
        redetect_probability: per particle and frame, the chance that its parts are re-drawn
            about its own posture's hypotheses (velocity zero): the way back for parts that
            drifted beyond the likelihood's cutoff δ, where nothing pulls them back. Default 0,
            chosen on the validation clips with ``redraw_on_switch`` and the part likelihood's
            cutoff (``python -m papers.kwatra2002.mixed_state_evaluation``, 2026-11-27: at
            δ = 25 and parts re-drawn on a switch, smoothed MSE over all parts 5 482 px² at 0
            against 6 068 at 0.02).
        redraw_on_switch: whether a particle whose posture changes has its parts re-drawn
            about the new posture's hypotheses (velocity zero) instead of keeping them (the
            paper does not say). Kept, the parts of a particle that switches sit where the
            old posture's heuristics put them, and under the capped part likelihood the switch
            costs up to 5 δ in log weight, more than the truncated posture likelihood can ever
            charge a wrong posture: the filter can lock into a wrong posture. Default on,
            chosen on the validation clips (same run: 5 482 px² re-drawn against 5 926 kept at
            δ = 25; 5 701 against 5 958 at δ = 9; 5 740 against 5 942 at δ = 100).
        part_proposal: how the parts are drawn (:data:`PART_PROPOSALS`): ``"dynamics"``, from
            the prediction alone (the paper's), or ``"posterior"``, from the prediction times
            the part likelihood (step 4 of the module docstring); the target, and so the
            posterior the filter and smoother estimate, is the same.
    """

    postures: PostureModel
    part_likelihood: PartDistances
    position_std: Float[Array, ""]
    velocity_std: Float[Array, ""]
    initial_std: Float[Array, ""]
    initial_velocity_std: Float[Array, ""]
    redetect_probability: Float[Array, ""]
    redraw_on_switch: bool = eqx.field(static=True)
    part_proposal: str = eqx.field(static=True)

    def __init__(self, postures: PostureModel, part_likelihood: PartDistances | None = None, *,
                 position_std: float = 3.0, velocity_std: float = 2.0,
                 initial_std: float = 20.0, initial_velocity_std: float = 2.0,
                 redetect_probability: float = 0.0, redraw_on_switch: bool = True,
                 part_proposal: str = "dynamics"):
        values = dict(position_std=position_std, velocity_std=velocity_std,
                      initial_std=initial_std, initial_velocity_std=initial_velocity_std)
        for name, value in values.items():
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative finite number of pixels, got "
                                 f"{value}")
        if not 0.0 <= redetect_probability <= 1.0:
            raise ValueError(f"redetect_probability must be in [0, 1], got "
                             f"{redetect_probability}")
        self.redetect_probability = jnp.asarray(float(redetect_probability))
        if not isinstance(redraw_on_switch, (bool, np.bool_)):
            raise ValueError(f"redraw_on_switch must be True or False, got {redraw_on_switch!r}")
        self.redraw_on_switch = bool(redraw_on_switch)
        if part_proposal not in PART_PROPOSALS:
            raise ValueError(f"part_proposal must be one of {', '.join(PART_PROPOSALS)}, got "
                             f"{part_proposal!r}")
        self.part_proposal = part_proposal
        self.postures = postures
        self.part_likelihood = PartDistances() if part_likelihood is None else part_likelihood
        for name, value in values.items():
            setattr(self, name, jnp.asarray(float(value)))

    def options(self) -> dict:
        """The dynamics' and likelihoods' settings as plain numbers (for a run's JSON)."""
        return {"position_std": float(self.position_std),
                "velocity_std": float(self.velocity_std),
                "initial_std": float(self.initial_std),
                "initial_velocity_std": float(self.initial_velocity_std),
                "redetect_probability": float(self.redetect_probability),
                "redraw_on_switch": self.redraw_on_switch,
                "part_proposal": self.part_proposal,
                "part_cutoff": float(self.part_likelihood.cutoff),
                "posture_cutoff": float(self.postures.cutoff)}

    def log_posture_likelihoods(self, frame: MixedStateFrame) -> Float[Array, " postures"]:
        """log p(h_t | q), zero (no evidence) on a frame whose status is not ok."""
        values = self.postures.log_likelihoods(frame.features)
        return jnp.where(frame.status == FRAME_OK, values, 0.0)

    def init(self, key: PRNGKeyArray) -> dict:
        raise NotImplementedError(
            "MixedStateModel draws its first particles about the first frame's hypotheses "
            "(§3.2 step 1): call init_propose(key, first_frame), as the engine does")

    def init_propose(self, key: PRNGKeyArray, frame: MixedStateFrame
                     ) -> tuple[dict, Float[Array, ""]]:
        """§3.2 step 1: q ~ π(q) p(h_1 | q) normalised, parts ~ N(z_1^q, σ_init² I) projected
        into the silhouette, velocities ~ N(0, σ_v,init² I); the correction is the posture
        evidence log Σ_q π(q) p(h_1 | q) (the same for every particle)."""
        dtype = jnp.result_type(float)
        ok = frame.status == FRAME_OK
        logits = (self.postures.log_initial + self.log_posture_likelihoods(frame)).astype(dtype)
        log_evidence = jax.nn.logsumexp(logits)
        key_posture, key_noise = jr.split(key)
        posture = _draw_posture(jr.uniform(key_posture, (), dtype), logits - log_evidence)
        hypotheses = frame.hypotheses.astype(dtype)
        noise = smc.fast_normal(key_noise, (2, *hypotheses.shape[1:]), dtype)
        correction = jnp.zeros((), dtype)
        if self.part_proposal == "posterior":
            parts, correction = self._posterior_parts(
                jr.fold_in(key_noise, 1), hypotheses[posture],
                jnp.square(self.initial_std.astype(dtype)), hypotheses[posture])
        else:
            parts = hypotheses[posture] + self.initial_std.astype(dtype) * noise[0]
        parts = jnp.where(ok, _project(parts, frame.nearest), parts)
        velocities = self.initial_velocity_std.astype(dtype) * noise[1]
        particle = {"posture": posture, "parts": parts, "velocities": velocities}
        return particle, jnp.where(ok, log_evidence + correction, 0.0)

    def propose(self, key: PRNGKeyArray, particle: dict, time: Int[Array, ""],
                frame: MixedStateFrame) -> tuple[dict, Float[Array, ""]]:
        """Steps 3–5: the posture from the parent's row of F (eq. 8–9), the parts by constant
        velocity (or re-drawn), projected into the silhouette; the correction is the row's
        normaliser log Σ_j p(h_t | j) T_ij (zero on a frame whose status is not ok)."""
        ok = frame.status == FRAME_OK
        log_row = self.postures.log_transition[particle["posture"]] + (
            self.log_posture_likelihoods(frame))
        log_normaliser = jax.nn.logsumexp(log_row)
        moved, correction = self._move(key, particle, log_row - log_normaliser, frame)
        return moved, jnp.where(ok, log_normaliser + correction, 0.0).astype(
            particle["parts"].dtype)

    def propagate(self, key: PRNGKeyArray, particle: dict, time: Int[Array, ""]) -> dict:
        """The dynamics without a frame: the posture from T, the parts by constant velocity
        (what ``propose`` does on a frame whose status is not ok)."""
        return self._move(key, particle, self.postures.log_transition[particle["posture"]],
                          None)[0]

    def _move(self, key, particle: dict, log_probabilities, frame: MixedStateFrame | None
              ) -> tuple[dict, Float[Array, ""]]:
        """The posture drawn from ``log_probabilities`` (normalised), the parts predicted
        (step 4), re-drawn about the frame's hypotheses and projected (step 5) where the frame
        has a silhouette; and the parts' log-weight correction (zero unless
        ``part_proposal`` is ``"posterior"``)."""
        parts, velocities = particle["parts"], particle["velocities"]
        dtype = parts.dtype
        key_uniforms, key_noise = jr.split(key)
        uniforms = jr.uniform(key_uniforms, (2,), dtype)
        noise = smc.fast_normal(key_noise, (3, *parts.shape), dtype)
        posture = _draw_posture(uniforms[0], log_probabilities.astype(dtype)).astype(
            particle["posture"].dtype)
        velocities = velocities + self.velocity_std.astype(dtype) * noise[0]
        predicted = parts + velocities + self.position_std.astype(dtype) * noise[1]
        if frame is None:
            return ({"posture": posture, "parts": predicted, "velocities": predicted - parts},
                    jnp.zeros((), dtype))
        ok = frame.status == FRAME_OK
        # a few particles' parts re-drawn about their posture's hypotheses (recovery)
        redraw = uniforms[1] < self.redetect_probability.astype(dtype)
        if self.redraw_on_switch:  # a new posture starts from its own hypotheses
            redraw = redraw | (posture != particle["posture"])
        redraw = redraw & ok
        own = frame.hypotheses.astype(dtype)[posture]
        correction = jnp.zeros((), dtype)
        if self.part_proposal == "posterior":
            # the same prediction as the paper's (mean and variance per coordinate), drawn
            # with the part likelihood folded in
            mean = jnp.where(redraw, own, parts + particle["velocities"])
            variance = jnp.where(redraw, jnp.square(self.initial_std.astype(dtype)),
                                 jnp.square(self.velocity_std.astype(dtype))
                                 + jnp.square(self.position_std.astype(dtype)))
            drawn, correction = self._posterior_parts(jr.fold_in(key_noise, 1), mean,
                                                      variance, own)
            predicted = jnp.where(ok, drawn, predicted)
            correction = jnp.where(ok, correction, 0.0)
        else:
            fresh = own + self.initial_std.astype(dtype) * noise[2]
            predicted = jnp.where(redraw, fresh, predicted)
        predicted = jnp.where(ok, _project(predicted, frame.nearest), predicted)
        velocities = jnp.where(redraw, 0.0, predicted - parts)
        return {"posture": posture, "parts": predicted, "velocities": velocities}, correction

    def _posterior_parts(self, key, mean: Float[Array, "parts 2"], variance: Float[Array, ""],
                         hypotheses: Float[Array, "parts 2"]
                         ) -> tuple[Float[Array, "parts 2"], Float[Array, ""]]:
        """Each part drawn from N(mean, variance I) × (exp(−d) + exp(−δ)), d = (z − x)ᵀ R⁻¹
        (z − x) (eq. 7 without its cap), and the log-weight correction Σ_i log Z_i −
        log(exp(−d_i) + exp(−δ)) that makes this proposal's weight that of the prediction
        times exp(−min(δ, d_i)) (step 4 of the module docstring).

        With A = R⁻¹: exp(−dᵀAd) = π |A|^−½ N(z; x, (2A)⁻¹), so the Gaussian component has
        covariance (I / variance + 2A)⁻¹, mean that times (mean / variance + 2A z) and mass
        π |A|^−½ N(z; mean, variance I + (2A)⁻¹); the other component is the prediction, of
        mass exp(−δ)."""
        dtype = mean.dtype
        inverse = self.part_likelihood.inverse_covariances.astype(dtype)  # A, (parts, 2, 2)
        cutoff = self.part_likelihood.cutoff.astype(dtype)
        identity = jnp.eye(2, dtype=dtype)
        covariance = _inverse_2x2(2.0 * inverse + identity / variance)
        centre = jnp.einsum("pij,pj->pi", covariance, mean / variance
                            + jnp.einsum("pij,pj->pi", 2.0 * inverse, hypotheses))
        marginal = variance * identity + _inverse_2x2(2.0 * inverse)
        residual = hypotheses - mean
        log_gaussian_mass = (jnp.log(jnp.pi) - 0.5 * jnp.log(_det_2x2(inverse))
                             - 0.5 * jnp.einsum("pi,pij,pj->p", residual,
                                                _inverse_2x2(marginal), residual)
                             - jnp.log(2 * jnp.pi) - 0.5 * jnp.log(_det_2x2(marginal)))
        log_mass = jnp.logaddexp(log_gaussian_mass, -cutoff)  # log Z_i
        key_choice, key_noise = jr.split(key)
        take_gaussian = jnp.log(jr.uniform(key_choice, log_mass.shape, dtype)) < (
            log_gaussian_mass - log_mass)
        noise = smc.fast_normal(key_noise, mean.shape, dtype)
        drawn = jnp.where(take_gaussian[:, None],
                          centre + jnp.einsum("pij,pj->pi", _cholesky_2x2(covariance), noise),
                          mean + jnp.sqrt(variance) * noise)
        difference = hypotheses - drawn
        distance = jnp.einsum("pi,pij,pj->p", difference, inverse, difference)
        return drawn, jnp.sum(log_mass - jnp.logaddexp(-distance, -cutoff))

    def log_likelihood(self, particle: dict, frame: MixedStateFrame) -> Float[Array, ""]:
        """Step 6's parts term, log p(Z_t | x, q) (eq. 4–7); zero on a frame whose status is
        not ok. The posture's evidence is in ``propose``'s correction."""
        dtype = particle["parts"].dtype
        value = self.part_likelihood.log_likelihood(
            particle["posture"], particle["parts"], frame.hypotheses.astype(dtype))
        return jnp.where(frame.status == FRAME_OK, value, 0.0).astype(dtype)


class MixedStateResult(eqx.Module):
    """The filter's outputs for a sequence (leading ``time`` axis on per-frame fields).

    ``postures``/``parts``/``velocities``/``log_weights``/``ancestors`` are the particle
    history the smoothers trace; ``filtered_posture``/``filtered_parts`` the causal estimates.
    """

    postures: Int[Array, "time particles"]
    parts: Float[Array, "time particles parts 2"]
    velocities: Float[Array, "time particles parts 2"]
    log_weights: Float[Array, "time particles"]
    ancestors: Int[Array, "time particles"]
    log_evidence_increments: Float[Array, " time"]
    ess: Float[Array, " time"]
    status: Int[Array, " time"]
    filtered_posture: Int[Array, " time"]
    filtered_posture_probabilities: Float[Array, "time postures"]
    filtered_parts: Float[Array, "time parts 2"]


class SmoothedPostures(eqx.Module):
    """The smoothed estimate at every frame given the whole sequence (§3.3)."""

    posture: Int[Array, " time"]
    posture_probabilities: Float[Array, "time postures"]
    parts: Float[Array, "time parts 2"]


def _project(parts: Float[Array, "parts 2"], nearest: Int[Array, "height width 2"]
             ) -> Float[Array, "parts 2"]:
    """Each part moved to the nearest silhouette pixel (itself when inside): one gather."""
    height, width = nearest.shape[:2]
    columns = jnp.clip(jnp.round(parts[:, 0]), 0, width - 1).astype(jnp.int32)
    rows = jnp.clip(jnp.round(parts[:, 1]), 0, height - 1).astype(jnp.int32)
    target = nearest[rows, columns].astype(parts.dtype)
    inside = jnp.all(target == jnp.stack([columns, rows], axis=-1).astype(parts.dtype), axis=-1)
    return jnp.where(inside[:, None], parts, target)


PART_PROPOSALS = ("dynamics", "posterior")
"""How :class:`MixedStateModel` draws the parts: from the prediction (the paper's), or from
the prediction times the part likelihood."""


def _det_2x2(matrices: Float[Array, "... 2 2"]) -> Float[Array, "..."]:
    return matrices[..., 0, 0] * matrices[..., 1, 1] - matrices[..., 0, 1] * matrices[..., 1, 0]


def _inverse_2x2(matrices: Float[Array, "... 2 2"]) -> Float[Array, "... 2 2"]:
    """Closed-form inverse of 2 × 2 matrices (cheaper than a solver under vmap)."""
    adjugate = jnp.stack([jnp.stack([matrices[..., 1, 1], -matrices[..., 0, 1]], -1),
                          jnp.stack([-matrices[..., 1, 0], matrices[..., 0, 0]], -1)], -2)
    return adjugate / _det_2x2(matrices)[..., None, None]


def _cholesky_2x2(matrices: Float[Array, "... 2 2"]) -> Float[Array, "... 2 2"]:
    """Lower Cholesky factor of symmetric positive-definite 2 × 2 matrices."""
    first = jnp.sqrt(matrices[..., 0, 0])
    below = matrices[..., 1, 0] / first
    second = jnp.sqrt(matrices[..., 1, 1] - below ** 2)
    zero = jnp.zeros_like(first)
    return jnp.stack([jnp.stack([first, zero], -1), jnp.stack([below, second], -1)], -2)


def _draw_posture(uniform: Float[Array, ""], log_probabilities: Float[Array, " postures"]
                  ) -> Int[Array, ""]:
    """Inverse-CDF draw of one posture from normalised log probabilities, one uniform in
    [0, 1) (postures of probability zero are never drawn)."""
    cumulative = jnp.cumsum(jnp.exp(log_probabilities))
    index = jnp.searchsorted(cumulative, uniform * cumulative[-1], side="right")
    return jnp.minimum(index, log_probabilities.shape[0] - 1).astype(jnp.int32)


def _estimate(postures, parts, log_weights):
    """Posture of largest total weight; weighted mean of the parts of the particles in it."""
    weights = jax.nn.softmax(log_weights)
    probabilities = jnp.zeros(NUM_POSTURES, weights.dtype).at[postures].add(weights)
    best = jnp.argmax(probabilities)
    chosen = jnp.where(postures == best, weights, 0.0)
    chosen = chosen / jnp.sum(chosen)
    return best, probabilities, jnp.tensordot(chosen, parts, axes=1)


def _ess(log_weights):
    return 1.0 / jnp.sum(jax.nn.softmax(log_weights) ** 2)


@eqx.filter_jit
def filter_sequence(key: PRNGKeyArray, model: MixedStateModel, observations: MixedStateFrame,
                    num_particles: int) -> MixedStateResult:
    """Filter a whole sequence with the engine (:func:`jaxtrack.smc.filter_sequence`, one
    compiled scan, systematic resampling every frame) and keep the particle history.

    Args:
        key: PRNG key.
        model: the mixed-state model.
        observations: a :class:`MixedStateFrame` whose leaves have a leading ``time`` axis
            (:func:`observations_from_silhouettes`).
        num_particles: N.

    Returns:
        :class:`MixedStateResult`.
    """
    if not isinstance(num_particles, int) or num_particles < 1:
        raise ValueError(f"num_particles must be an int of at least 1, got {num_particles!r}")
    history = smc.filter_sequence(key, model, observations, num_particles, keep_history=True)
    particles = history.particles
    best, probabilities, mean_parts = jax.vmap(_estimate)(
        particles["posture"], particles["parts"], history.log_weights)
    return MixedStateResult(particles["posture"], particles["parts"], particles["velocities"],
                            history.log_weights, history.ancestors,
                            history.log_evidence_increments, history.ess, observations.status,
                            best, probabilities, mean_parts)


def _as_filter_result(result: MixedStateResult) -> smc.FilterResult:
    """The history in the engine's form, for its ancestry-tracing smoother."""
    num_frames = result.status.shape[0]
    flags = jnp.zeros(num_frames, bool)
    particles = {"posture": result.postures, "parts": result.parts,
                 "velocities": result.velocities}
    return smc.FilterResult(
        log_evidence=jnp.sum(result.log_evidence_increments),
        log_evidence_increments=result.log_evidence_increments, ess=result.ess,
        resampled=~flags, degenerate=flags, num_invalid=jnp.zeros(num_frames, jnp.int32),
        mean=None, best=None, particles=particles, log_weights=result.log_weights,
        ancestors=result.ancestors)


@eqx.filter_jit
def smooth(result: MixedStateResult) -> SmoothedPostures:
    """Kwatra et al.'s sequence smoother (§3.3): trace every final particle's ancestry
    (:func:`jaxtrack.smc.trace_ancestry`); per frame the MAP posture of the traced paths under
    the final weights, and the weighted mean parts of the paths in that posture."""
    return _smooth_history(result.postures, result.parts, result.log_weights, result.ancestors)


def _smooth_history(postures: Int[Array, "time particles"],
                    parts: Float[Array, "time particles parts 2"],
                    log_weights: Float[Array, "time particles"],
                    ancestors: Int[Array, "time particles"]) -> SmoothedPostures:
    """:func:`smooth` of a particle history (what the filter keeps, or what
    :class:`MixedStateTracker` reports frame by frame with ``keep_history``)."""
    num_frames = postures.shape[0]
    flags = jnp.zeros(num_frames, bool)
    history = smc.FilterResult(
        log_evidence=jnp.zeros((), log_weights.dtype),
        log_evidence_increments=jnp.zeros(num_frames, log_weights.dtype),
        ess=jnp.zeros(num_frames, log_weights.dtype), resampled=~flags, degenerate=flags,
        num_invalid=jnp.zeros(num_frames, jnp.int32), mean=None, best=None,
        particles={"posture": postures, "parts": parts}, log_weights=log_weights,
        ancestors=ancestors)
    paths = smc.trace_ancestry(history)
    best, probabilities, smoothed = jax.vmap(_estimate, in_axes=(0, 0, None))(
        paths.paths["posture"], paths.paths["parts"], paths.log_weights)
    return SmoothedPostures(best, probabilities, smoothed)


class _Dynamics(eqx.Module):
    """The dynamics' density p(x_t+1 | x_t), which backward simulation weighs by (the one
    method :func:`jaxtrack.smc.ffbsi` calls).

    With the posture's transition T, a particle that keeps its parts moves them by
    d = x_t+1 − x_t = v_t + σ_v ε + σ_x ε' (module docstring, step 4): Gaussian about its
    velocity, variance σ_v² + σ_x² per coordinate; one whose parts are re-drawn (on a switch,
    if ``redraw_on_switch``, and with probability ``redetect_probability``) has them about the
    new posture's hypotheses of frame t + 1, variance σ_init². The projection into the
    silhouette (step 5) moves a part onto the silhouette's edge, which no density expresses: it
    is left out, so this is the dynamics' density of an unprojected move."""

    model: MixedStateModel
    hypotheses: Float[Array, "time postures parts 2"]
    status: Int[Array, " time"]

    def log_transition_density(self, previous: dict, particle: dict, time) -> Float[Array, ""]:
        model = self.model
        dtype = particle["parts"].dtype
        posture = particle["posture"]
        log_t = model.postures.log_transition[previous["posture"], posture].astype(dtype)

        def gaussian(residual, variance):
            return (-0.5 * jnp.sum(residual ** 2) / variance
                    - 0.5 * residual.size * jnp.log(2 * jnp.pi * variance))

        kept = gaussian(particle["parts"] - previous["parts"] - previous["velocities"],
                        (model.velocity_std ** 2 + model.position_std ** 2).astype(dtype))
        fresh = gaussian(particle["parts"] - self.hypotheses[time, posture].astype(dtype),
                         (model.initial_std ** 2).astype(dtype))
        ok = self.status[time] == FRAME_OK
        chance = model.redetect_probability.astype(dtype)
        either = jnp.logaddexp(jnp.log1p(-chance) + kept, jnp.log(chance) + fresh)
        switched = posture != previous["posture"]
        redrawn = switched if model.redraw_on_switch else jnp.zeros_like(switched)
        return log_t + jnp.where(ok, jnp.where(redrawn, fresh, either), kept)


@eqx.filter_jit
def smooth_backward(key: PRNGKeyArray, result: MixedStateResult, model: MixedStateModel,
                    observations: MixedStateFrame, num_paths: int) -> SmoothedPostures:
    """The two-pass smoother (forward filtering, backward simulation: :func:`jaxtrack.smc.ffbsi`)
    for comparison with :func:`smooth`: ``num_paths`` paths drawn backward, each frame's
    particle of a path chosen among all that frame's particles by weight × the dynamics'
    density of the path's next state (:class:`_Dynamics`); per frame the MAP posture of the
    paths and the mean parts of the paths in it. Its cost is ``num_paths`` × particles density
    evaluations per frame, against ancestry tracing's one gather per particle.

    Args:
        key: PRNG key of the backward draws.
        result: :func:`filter_sequence`'s output for ``model`` and ``observations``.
        model, observations: what the filter ran on (the hypotheses and status of every frame).
        num_paths: M, the paths drawn.
    """
    if num_paths < 1:
        raise ValueError(f"num_paths must be at least 1, got {num_paths}")
    dynamics = _Dynamics(model, observations.hypotheses, observations.status)
    paths = smc.ffbsi(key, dynamics, _as_filter_result(result), num_paths)
    best, probabilities, parts = jax.vmap(_estimate, in_axes=(0, 0, None))(
        paths.paths["posture"], paths.paths["parts"], paths.log_weights)
    return SmoothedPostures(best, probabilities, parts)


def smooth_fixed_lag(result: MixedStateResult, lag: int) -> SmoothedPostures:
    """The fixed-lag smoother: frame t's estimate from the ancestry of frame ``t + lag``'s
    particles under that frame's weights (the last ``lag`` frames from the final ones). What a
    stream filtered chunk by chunk can report once ``lag`` more frames have arrived; ``lag = 0``
    is the filter, ``lag ≥ time − 1`` the whole-sequence smoother."""
    if lag < 0:
        raise ValueError(f"lag must be non-negative, got {lag}")
    # the lag is traced (one compilation serves every lag); the loop runs at most T − 1 steps
    return _fixed_lag(result, jnp.asarray(min(int(lag), result.postures.shape[0] - 1)))


@eqx.filter_jit
def _fixed_lag(result: MixedStateResult, lag: Int[Array, ""]) -> SmoothedPostures:
    num_frames, num = result.postures.shape

    def at(time):
        """Indices at ``time`` of the paths of frame min(time + lag, T−1)'s particles."""
        end = jnp.minimum(time + lag, num_frames - 1)

        def back(k, indices):
            t = end - k
            return jnp.where(t > time, result.ancestors[t][indices], indices)

        indices = lax.fori_loop(0, lag, back, jnp.arange(num))
        posture = result.postures[time][indices]
        parts = result.parts[time][indices]
        return _estimate(posture, parts, result.log_weights[end])

    best, probabilities, parts = jax.vmap(at)(jnp.arange(num_frames))
    return SmoothedPostures(best, probabilities, parts)


def instantaneous_estimates(model: MixedStateModel, observations: MixedStateFrame
                            ) -> tuple[Int[Array, " time"], Float[Array, "time parts 2"]]:
    """The extended Ghost baseline: per frame argmax_q p(h_t | q) and that posture's z_t^q."""
    log_h = jax.vmap(model.postures.log_likelihoods)(observations.features)
    posture = jnp.argmax(log_h, axis=-1)
    parts = jnp.take_along_axis(observations.hypotheses, posture[:, None, None, None],
                                axis=1)[:, 0]
    return posture, parts


def observations_from_silhouettes(masks: np.ndarray, *, num_bins: int = 16) -> MixedStateFrame:
    """A sequence's observations from its ``(time, height, width)`` bool silhouettes: features
    and status (:func:`jaxtrack.vision.histograms.silhouette_features`), every posture's
    hypotheses (:func:`jaxtrack.vision.parts.part_hypotheses`) and the nearest-point maps."""
    from jaxtrack.vision.histograms import silhouette_features
    from jaxtrack.vision.parts import nearest_silhouette_points, part_hypotheses

    masks = np.asarray(masks)
    features, status = silhouette_features(masks, num_bins)
    hypotheses = part_hypotheses(masks, status)
    nearest = np.stack([nearest_silhouette_points(mask) for mask in masks])
    return MixedStateFrame(jnp.asarray(features), jnp.asarray(hypotheses), jnp.asarray(nearest),
                           jnp.asarray(status, jnp.int32))


def with_detections(observations: MixedStateFrame, points: np.ndarray, confidence: np.ndarray,
                    markers, *, min_confidence: float = KEYPOINT_CONFIDENCE) -> MixedStateFrame:
    """A sequence's observations with a detector's keypoints as part hypotheses beside the
    silhouette's (:func:`jaxtrack.vision.parts.detection_hypotheses`: confident head, wrists
    and ankles replace every posture's silhouette hypotheses), and the projection of step 5
    (module docstring) onto the silhouette and those keypoints' pixels.

    The projection holds the parts on the person's body, which the paper takes to be the
    silhouette. A detector's parts need not lie on it: where background subtraction gives
    fragments of the person (a person who barely moves is in the median background), the
    detected hands and feet lie outside them, and particles projected onto the silhouette
    alone never reach them. The body is then the silhouette and the confident keypoints
    (``python -m papers.kwatra2002.detections_real_video --cameras cam01 --projections``,
    2026-11-29, 500 particles, silhouettes against the median background: smoothed MSE over
    all parts 10 976 px² projected onto the silhouette, 345 not projected, 257 onto the
    silhouette and the keypoints; MediaPipe's own keypoints 250).

    Args:
        observations: :func:`observations_from_silhouettes`' (a ``time`` axis).
        points: ``(time, markers, 2)`` keypoints in the same pixels (NaN where absent).
        confidence: ``(time, markers)``.
        markers: the markers' names (:data:`jaxtrack.vision.detections.DETECTION_MARKERS`).
        min_confidence: the least confidence of a keypoint that is taken.
    """
    from jaxtrack.vision.parts import (
        DETECTION_PART_MARKERS,
        detection_hypotheses,
        nearest_silhouette_points,
    )

    hypotheses = detection_hypotheses(np.asarray(observations.hypotheses), points, confidence,
                                      markers, min_confidence=min_confidence)
    nearest = np.array(observations.nearest)
    height, width = nearest.shape[1:3]
    ys, xs = np.mgrid[:height, :width]
    markers = tuple(markers)
    parts = [markers.index(name) for names in DETECTION_PART_MARKERS for name in names
             if name in markers]
    chosen = np.asarray(points, np.float64)[:, parts]
    usable = (np.nan_to_num(np.asarray(confidence, np.float64)[:, parts], nan=0.0)
              >= min_confidence) & np.isfinite(chosen).all(axis=-1)
    for t in range(len(nearest)):
        pixels = np.round(chosen[t][usable[t]]).astype(int)
        pixels = pixels[(pixels[:, 0] >= 0) & (pixels[:, 0] < width) & (pixels[:, 1] >= 0)
                        & (pixels[:, 1] < height)]
        if not len(pixels):
            continue
        # the silhouette: the pixels that are their own nearest silhouette pixel
        body = (nearest[t, ..., 0] == xs) & (nearest[t, ..., 1] == ys)
        body[pixels[:, 1], pixels[:, 0]] = True
        nearest[t] = nearest_silhouette_points(body)
    return dataclasses.replace(observations, hypotheses=jnp.asarray(hypotheses),
                               nearest=jnp.asarray(nearest))


class MixedStateHistory(eqx.Module):
    """One frame's particles as the smoother traces them (:func:`smooth`)."""

    postures: Int[Array, " particles"]
    parts: Float[Array, "particles parts 2"]
    log_weights: Float[Array, " particles"]
    ancestors: Int[Array, " particles"]  # each particle's parent in the previous frame


class MixedStateEstimate(FrameEstimate):
    """:class:`MixedStateTracker`'s report of a frame: the filtered parts as ``markers``, and

    Attributes:
        posture: the filtered posture (largest total weight) and ``posture_probability`` its
            weight.
        instant_posture, instant_parts: the extended Ghost's estimate from this frame alone
            (:func:`instantaneous_estimates`).
        silhouette: the frame's silhouette status (:data:`jaxtrack.vision.histograms.FRAME_OK`
            where a silhouette was found).
        history: with ``keep_history``, the frame's particles, for :meth:`MixedStateTracker.smooth`.
    """

    posture: Int[Array, ""]
    posture_probability: Float[Array, ""]
    instant_posture: Int[Array, ""]
    instant_parts: Float[Array, "parts 2"]
    silhouette: Int[Array, ""]
    history: MixedStateHistory | None


class MixedStateState(eqx.Module):
    """What :class:`MixedStateTracker` carries from frame to frame: the engine's filter state
    (particles ``{"posture", "parts", "velocities"}``), whether the last frame was degenerate,
    the particles' parents and the last frame's instantaneous estimate and silhouette status."""

    filter: smc.FilterState
    degenerate: Bool[Array, ""]
    ancestors: Int[Array, " particles"]
    instant_posture: Int[Array, ""]
    instant_parts: Float[Array, "parts 2"]
    silhouette: Int[Array, ""]

    @property
    def postures(self) -> Int[Array, " particles"]:
        return self.filter.particles["posture"]

    @property
    def parts(self) -> Float[Array, "particles parts 2"]:
        return self.filter.particles["parts"]

    @property
    def velocities(self) -> Float[Array, "particles parts 2"]:
        return self.filter.particles["velocities"]

    @property
    def log_weights(self) -> Float[Array, " particles"]:
        return self.filter.log_weights


def _instant(model: MixedStateModel, frame: MixedStateFrame):
    """This frame's extended Ghost estimate: argmax_q p(h | q) and that posture's z^q."""
    posture = jnp.argmax(model.postures.log_likelihoods(frame.features)).astype(jnp.int32)
    return posture, frame.hypotheses[posture]


class MixedStateTracker(Tracker):
    """The mixed-state filter under the tracker contract (frame by frame, causal): the engine's
    :func:`jaxtrack.smc.initialize` and :func:`jaxtrack.smc.step` on :class:`MixedStateModel`.

    Its frames are :class:`MixedStateFrame` observations (from the person's masks; the largest
    blob of each is the silhouette); it reports the five parts (head, hand, hand, foot, foot)
    as its markers, with the posture and the instantaneous estimate
    (:class:`MixedStateEstimate`). It starts from the first frame's silhouette (§3.2 step 1),
    so ``start``'s ``initial_pose`` is not used. With ``keep_history`` every frame's report
    carries its particles, and :meth:`smooth` gives the whole-sequence smoother's estimate
    (§3.3, :func:`smooth`) from them; its memory grows with the video by
    ``particles × (2 × parts + 3)`` numbers a frame.

    With ``keypoint_markers`` (the names of the keypoints' markers, in their order: e.g.
    :data:`jaxtrack.vision.detections.DETECTION_MARKERS`) it also reads a detector's keypoints
    (``VideoChunk.keypoints``, in tracking pixels), and each frame's part hypotheses are the
    silhouette's with the detector's confident head, wrists and ankles in their place, and the
    parts are projected onto the silhouette and those keypoints (:func:`with_detections`,
    keypoints of confidence at least ``keypoint_confidence``); the posture evidence and a
    frame's status stay the silhouette's.
    Without it (the default) the tracker is the paper's.
    """

    model: MixedStateModel
    particles: int = eqx.field(static=True)
    num_bins: int = eqx.field(static=True, default=16)
    keep_history: bool = eqx.field(static=True, default=False)
    keypoint_markers: tuple[str, ...] | None = eqx.field(static=True, default=None)
    keypoint_confidence: float = eqx.field(static=True, default=KEYPOINT_CONFIDENCE)

    @property
    def likelihood(self) -> PartDistances:
        return self.model.part_likelihood

    @property
    def reads(self) -> tuple[str, ...]:
        return ("masks",) if self.keypoint_markers is None else ("masks", "keypoints")

    def observe(self, chunk: VideoChunk, out=None) -> MixedStateFrame:
        """The chunk's :class:`MixedStateFrame` from the person's masks: each mask's largest
        blob (the person; speckle dropped, as :func:`jaxtrack.vision.histograms.silhouettes`
        keeps it), with ``num_bins`` projection-histogram bins (the posture model's)
        (:func:`observations_from_silhouettes`)."""
        from jaxtrack.vision.foreground import largest_component

        if chunk.masks is None:
            raise ValueError("the mixed-state tracker reads the person's silhouettes: give "
                             "masks=... (time, height, width) bool")
        masks = np.stack([largest_component(mask) for mask in np.asarray(chunk.masks, bool)])
        observations = observations_from_silhouettes(masks, num_bins=self.num_bins)
        if self.keypoint_markers is not None:
            if chunk.keypoints is None:
                raise ValueError("this mixed-state tracker reads a detector's keypoints "
                                 "(keypoint_markers is set): give keypoints=... (points (time, "
                                 "markers, 2), confidence (time, markers))")
            points, confidence = (np.asarray(value) for value in chunk.keypoints)
            if points.shape[1:2] != (len(self.keypoint_markers),):
                raise ValueError(f"keypoints hold {points.shape[1:2]} markers per frame, but "
                                 f"the tracker's keypoint_markers name "
                                 f"{len(self.keypoint_markers)}")
            observations = with_detections(observations, points, confidence,
                                           self.keypoint_markers,
                                           min_confidence=self.keypoint_confidence)
        return jax.tree.map(np.asarray, observations)

    def __check_init__(self):
        if self.particles < 1:
            raise ValueError(f"particles must be at least 1, got {self.particles}")
        if self.keypoint_markers is not None:
            from jaxtrack.vision.parts import DETECTION_PART_MARKERS

            wanted = [name for names in DETECTION_PART_MARKERS for name in names]
            if not isinstance(self.keypoint_markers, tuple) or not any(
                    name in self.keypoint_markers for name in wanted):
                raise ValueError(f"keypoint_markers must be a tuple of marker names holding "
                                 f"some of {', '.join(wanted)}, got {self.keypoint_markers!r}")
        if not 0.0 <= self.keypoint_confidence <= 1.0:
            raise ValueError(f"keypoint_confidence must be in [0, 1], got "
                             f"{self.keypoint_confidence}")

    @property
    def num_particles(self) -> int:
        return self.particles

    def options(self) -> dict:
        keypoints = {} if self.keypoint_markers is None else {
            "keypoint_markers": list(self.keypoint_markers),
            "keypoint_confidence": self.keypoint_confidence}
        return {"method": "mixed-state", "particles": self.particles, "num_bins": self.num_bins,
                **self.model.options(), **keypoints}

    def start(self, key, first_frame: MixedStateFrame, initial_pose=None) -> MixedStateState:
        first_frame = jax.tree.map(jnp.asarray, first_frame)  # NumPy from track()
        state, info = smc.initialize(key, self.model, first_frame, self.particles)
        posture, parts = _instant(self.model, first_frame)
        return MixedStateState(state, info.degenerate, jnp.arange(self.particles, dtype=jnp.int32),
                               posture, parts, first_frame.status.astype(jnp.int32))

    def _report(self, state: MixedStateState, increment) -> MixedStateEstimate:
        posture, probabilities, parts = _estimate(state.postures, state.parts,
                                                  state.log_weights)
        best = state.parts[jnp.argmax(state.log_weights)]
        ess = jnp.where(state.degenerate, 0.0, _ess(state.log_weights))
        history = None
        if self.keep_history:
            history = MixedStateHistory(state.postures, state.parts, state.log_weights,
                                        state.ancestors)
        return MixedStateEstimate(parts, best, ess, increment, state.degenerate,
                                  posture.astype(jnp.int32), probabilities[posture],
                                  state.instant_posture, state.instant_parts, state.silhouette,
                                  history)

    def first_estimate(self, state: MixedStateState) -> MixedStateEstimate:
        return self._report(state, state.filter.log_evidence)

    def update(self, key, state: MixedStateState, frame: MixedStateFrame | FrameInChunk
               ) -> tuple[MixedStateState, MixedStateEstimate]:
        if isinstance(frame, FrameInChunk):  # a pytree frame: index every leaf in place
            frame = jax.tree.map(lambda leaf: leaf[frame.index], frame.frames)
        filtered, info = smc.step(key, state.filter, frame, self.model)
        posture, parts = _instant(self.model, frame)
        state = MixedStateState(filtered, info.degenerate, info.ancestors.astype(jnp.int32),
                                posture, parts,
                                frame.status.astype(jnp.int32))
        return state, self._report(state, info.log_evidence_increment)

    def smooth(self, estimates: MixedStateEstimate) -> MixedStateEstimate:
        """The whole-sequence smoother's estimate (§3.3, :func:`smooth`) of every frame from
        the reports of a tracker with ``keep_history`` (``TrackResult.estimates``): ``markers``
        the smoothed parts, ``posture``/``posture_probability`` the smoothed posture; the
        other fields as filtered. The history is dropped from the result."""
        history = estimates.history
        if history is None:
            raise ValueError("smoothing needs every frame's particles: make the tracker with "
                             "keep_history=True")
        smoothed = _smooth_history(*(jnp.asarray(leaf) for leaf in (
            history.postures, history.parts, history.log_weights, history.ancestors)))
        chosen = jnp.take_along_axis(smoothed.posture_probabilities,
                                     smoothed.posture[:, None], axis=1)[:, 0]
        return jax.tree.map(np.asarray, dataclasses.replace(
            estimates, markers=smoothed.parts, posture=smoothed.posture.astype(jnp.int32),
            posture_probability=chosen, history=None))
