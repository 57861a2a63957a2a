"""Tian, Li & Sclaroff's (2005) tracker: CONDENSATION in a learned GPLVM latent space.

Algorithm 2 of the paper: every particle is a 2-D latent point that random-walks with the
learned step ν; it is decoded by the GP mean μ(x) into the SPM pose and then into 12 image
markers, and weighted by the NCC of template patches at those markers (eq. 7). The estimate is
μ(weighted mean latent).

The paper's particles hold the latent point only: its subjects stay where they are. Here a
particle also carries the SPM placement (log scale and neck position), random-walking with small
steps, so a subject who shifts or leans is followed; ``placement_std = 0`` gives the paper's
fixed placement.

Three departures from the paper, each measured on a held-out real wave (README, "Tracking"), each
switchable back:

* **Likelihood.** The default is NCC of limb-aligned strips plus the distance of their borders
  to image edges (``likelihood="limbs+edges"``, :mod:`jaxtrack.likelihoods.edges`) instead of
  patches at the markers (``"markers"``, eq. 7): over the latent space, the marker patches'
  best-scoring pose is 20 % of the torso from the truth, the strips' 8.8 %; the edge term keeps
  scoring limbs whose texture has drifted from the frame-0 templates.
* **Jumps.** A GPLVM keeps dissimilar poses apart but not similar poses together, so a gesture
  can leave one region of the latent space for a distant one that decodes to nearly the same
  pose (μ⁻¹ of the held-out wave steps more than 4ν between frames in 10 % of frames), and a
  random walk that took the wrong branch cannot get back. With probability
  ``jump_probability`` a particle is instead redrawn at a random training latent (plus the
  usual step): the dynamics become the mixture ``(1 − ε) N(x, ν²) + ε p̂(x)`` of the random walk
  and the training latents' empirical distribution, still sampled from as CONDENSATION
  requires, like Ong & Gong's (2002) jumps between clusters. ``jump_probability = 0`` is the
  paper's random walk.
* **Full-state refinement of the estimate.** A 2-D latent space learned from a few takes holds
  poses near the subject's but not the subject's own (a body lean, a raised arm at an angle the
  takes never had), and a sharp likelihood ranks such near misses below poses that fit some
  limbs exactly: over the protocol's held-out take, the likelihood's best pose anywhere in the
  latent space at the true placement is within 15 % of the torso on 74 % of frames, while the
  latent space's nearest pose is on 95 %, and the tracker (73 %) reaches the former. The truth
  itself scores 10–20 nats above both. So each frame the reported pose leaves the latent
  space: the tracker carries one full 25-d SPM pose from frame to frame and refines two
  candidates on the new frame by the MHT baseline's damped Gauss–Newton
  (:func:`~jaxtrack.trackers.mht.refine_pose`, same likelihood, Gaussian prior about each
  start; ``solver="parts"``, its Jacobian built part by part, the same iterates in half the
  time): the pose carried from the previous frame, and μ of the particles' estimate. The
  better-scoring refined pose is reported and carried. The particles stay in the latent space
  (the refinement does not feed back into them), so the latent tracker's robustness is kept and
  a carried pose that drifts off the subject is replaced as soon as the latent estimate scores
  better. ``refine_steps = 0`` reports the paper's estimate (the default with eq. 7's marker
  patches, which give Gauss–Newton nothing to climb).
* **Arm search before the refinement.** Gauss–Newton is local: where the waving forearm moves
  more between frames than its strip is wide, both candidates keep the wrist where it was and
  the refinement cannot reach the truth, which scores 5–9 nats above them (the protocol's lost
  frames were 90 % in the raised-arm stretch). So each candidate's arms are first searched
  globally: for each arm, every combination of ``arm_grid`` offsets of
  the upper-arm and forearm image angles in ``[−arm_span, arm_span]`` is scored by the
  likelihood, and the best is kept if it scores at least ``arm_margin`` nats above the arm as
  it was (so the score never drops, and a right arm is not traded for a marginally better-
  scoring wrong one); then the refinement starts there. ``arm_grid = 0`` switches it off.
* **Constant-velocity arm centre.** A waving forearm turns up to ~0.5 rad per frame, at the
  edge of the search's span, and once the search lags a swing the arm is left where it was
  while the truth oscillates more than the span away (the protocol's failing frames, 50–95, were
  mostly this: right elbow and wrist 40–135 % of the torso off, the truth 2–8 nats above).
  So the same grid of offsets is searched a second time about the arm angles extrapolated from
  the last two reported poses (``arm_momentum`` × their change over the last frame), and the
  best of both grids is compared with the arm as it was. ``arm_momentum = 0`` searches about
  the carried arm alone.
"""

from __future__ import annotations

from statistics import NormalDist

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import jax.scipy.special as jsp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import (
    SPM_MARKERS,
    SPM_STATE_NAMES,
    SPM_STATE_SIZE,
    SPMTemplate,
    spm_forward,
    spm_initial_state,
)
from jaxtrack.likelihoods import (
    DEFAULT_LIKELIHOOD,
    AppearanceTemplates,
    default_sharpness,
    make_appearance_templates,
)
from jaxtrack.priors.gplvm import GPLVM
from jaxtrack.priors.poses import (
    PLACEMENT_SIZE,
    markers_from_features,
    pose_features,
    states_from_features,
)
from jaxtrack.trackers._runner import FrameEstimate, ParticleTracker
from jaxtrack.trackers.condensation import default_noise_floor
from jaxtrack.trackers.mht import refine_pose

__all__ = ["DEFAULT_ARM_GRID", "DEFAULT_ARM_MARGIN", "DEFAULT_ARM_SPAN",
           "DEFAULT_JUMP_PROBABILITY", "DEFAULT_REFINE_STEPS", "LatentModel", "LatentState",
           "LatentTracker", "default_refine_steps", "latent_tracker"]

DEFAULT_JUMP_PROBABILITY = 0.2
"""ε of the jump proposal (module docstring). On the demo's held-out wave (limb strips, 200
particles, 3 seeds) the tracker lost the subject (above 25 % of the torso for 10 frames) in 2 of
3 runs with ε = 0 and in 1 with ε = 0.2; mean error 16.9 and 16.2 % of the torso, 44 and 48 % of
frames within 15 %."""

DEFAULT_REFINE_STEPS = 10
"""Gauss–Newton trial steps per candidate and frame of the full-state refinement (module
docstring), the MHT baseline's default; the default of the strip likelihoods. On the protocol's
held-out take (4 sequences × 3 seeds, 200 particles) it took the tracker from 9.9 % of the torso
and 73 % of frames within 15 % to 7.9 % and 90 % with strips + oriented edges (20 steps: 7.8 %
and 89 %; on another CPU, stop 14: 11.0 % and 70.5 % to 8.7 % and 83 %, and with the arm search
that now starts each refinement 6.4 % and 98.7 %), and from 14.5 % and 57 % to 12.3 % and 67 %
with the strips alone. With eq. 7's
marker patches, whose NCC has nothing for Gauss–Newton to climb (see the MHT baseline), it lost
the subject in 8 of the 12 runs instead of 2, so ``likelihood="markers"`` defaults to the
paper's estimate (``refine_steps = 0``)."""


DEFAULT_ARM_GRID = 7
"""Offsets per arm angle of the arm search before the refinement (module docstring): 7 × 7
upper-arm × forearm angles per arm and candidate, 0.2 rad apart with :data:`DEFAULT_ARM_SPAN`
(196 evaluations of the arm's two strips per frame for the two candidates' two arms). Stop 19
chose it over stop 14's 5 × 5 (0.3 rad apart) on the Bandai validation splits (48 runs: 6.83
→ 6.63 % of the torso, 91.1 → 91.8 % of frames within 15 %, 5 → 4 runs lost), once the search
had become cheap (only the arm's strips scored); on the protocol (60 runs) 6.46 → 5.72 % and
93.8 → 94.1 %, 0 → 1 run lost; ~0.3 ms more per frame."""

DEFAULT_ARM_SPAN = 0.6
"""Largest angle offset (radians) of the arm search. Chosen on a validation split that shares
nothing with the protocol's take (another subject: the prior trained on three Bandai waves,
take 002; both-hands and left-hand waves of take 001 tracked, 8 runs): frames within 15 % of
the torso 92.8 % with no search; 98.0 % with 5 × 5 offsets over ±0.6 rad, 95.6 % over ±0.9 rad
(7 × 7), 96.2 % over ±1.2 rad (9 × 9). The mean error rose there, 4.7 → 6.0 % of the torso
(6.7 and 6.9 % with the wider spans): in the both-hands wave the search finds arm poses that
the likelihood scores ~6 nats above the truth (README)."""

DEFAULT_ARM_MOMENTUM = 1.0
"""Factor on the arm angles' change over the last frame that gives the arm search's second
centre (module docstring): 1, constant velocity; 0, no second centre. Chosen at stop 20 on the
Bandai validation splits (48 runs, prior seeds 0–2): 6.63 → 6.11 % of the torso, 91.7 →
91.6 % of frames within 15 %, 4 → 3 runs lost (0.5: 6.22 %, 91.6 %, 4 lost); then on the
protocol (60 runs) 5.72 → 5.35 %, 94.1 → 95.6 %, 1 → 0 lost. Twice the arm search's
evaluations (~0.3 ms more per candidate and frame)."""

DEFAULT_ARM_MARGIN = 2.0
"""Nats by which the arm search's best offset must beat the arm as it was before it moves it.
Chosen on the same validation splits: against no margin, Bandai 6.0 → 5.0 % of the torso and
98.0 → 98.9 % of frames within 15 % (no search: 4.7 %, 92.8 %); the easy split (the protocol's
other take) 5.2 → 5.0 % and 99.9 → 100 % (no search: 4.8 %, 99.9 %). Only 2 was tried."""

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


def default_refine_steps(likelihood: str) -> int:
    """``refine_steps`` when none is given: :data:`DEFAULT_REFINE_STEPS`, or 0 (the paper's
    estimate) with the marker patches."""
    return 0 if likelihood == "markers" else DEFAULT_REFINE_STEPS


class LatentModel(smc.StateSpaceModel):
    """The state-space model of the latent tracker (one particle: ``{"latent", "placement"}``).

    Attributes:
        prior: the GPLVM (float32 for speed).
        template: SPM template the GPLVM's poses are expressed in.
        templates: appearance templates from the first frame (limb strips or marker patches).
        initial_latent, initial_placement: where frame 0's pose lies.
        latent_std: ``(latent,)`` random-walk step per frame (ν, rescaled to the video's rate).
        jump_threshold: Φ⁻¹(jump probability): a particle jumps when its normal draw falls
            below it (−inf: never, the paper's random walk).
        placement_std: ``(3,)`` random-walk step of (log scale, x, y) per frame.
        initial_spread: std of the initial cloud around the initial latent, in units of ν.
        sharpness: λ of the likelihood.
        nearest: read pixels at the nearest sample point (10–40× faster) instead of bilinearly.
    """

    prior: GPLVM
    template: SPMTemplate
    templates: AppearanceTemplates
    initial_latent: Float[Array, " latent"]
    initial_placement: Float[Array, " 3"]
    latent_std: Float[Array, " latent"]
    jump_threshold: Float[Array, ""]
    placement_std: Float[Array, " 3"]
    initial_spread: Float[Array, ""]
    sharpness: Float[Array, ""]
    nearest: bool = eqx.field(static=True, default=True)

    def init(self, key: PRNGKeyArray) -> dict:
        key_latent, key_placement = jr.split(key)
        latent = self.initial_latent + self.initial_spread * self.latent_std * jr.normal(
            key_latent, self.initial_latent.shape, self.initial_latent.dtype)
        placement = self.initial_placement + self.placement_std * jr.normal(
            key_placement, (PLACEMENT_SIZE,), self.initial_placement.dtype)
        return {"latent": latent, "placement": placement}

    def propagate(self, key: PRNGKeyArray, particle: dict, time) -> dict:
        latent_dim = particle["latent"].shape[0]
        noise = smc.fast_normal(key, (latent_dim + PLACEMENT_SIZE + 2,), particle["latent"].dtype)
        step, jump_draw, pick_draw = (noise[:latent_dim + PLACEMENT_SIZE], noise[-2], noise[-1])
        # Tian et al. §4: random walk x_{t+1} = x_t + ω, ω ~ N(0, diag ν²) ...
        start = particle["latent"]
        # ... or, with probability ε, from a random training latent of the prior (module
        # docstring)
        pool = self.prior.latents
        pick = jnp.minimum((jsp.ndtr(pick_draw) * pool.shape[0]).astype(jnp.int32),
                           pool.shape[0] - 1)
        start = jnp.where(jump_draw < self.jump_threshold, pool[pick], start)
        return {"latent": start + self.latent_std * step[:latent_dim],
                "placement": particle["placement"] + self.placement_std * step[latent_dim:]}

    def markers_of(self, particle: dict) -> Float[Array, "markers 2"]:
        # spm_forward(states_from_features(μ(x), placement)) without the angles in between
        return markers_from_features(self.prior.mean(particle["latent"]), particle["placement"])

    def log_likelihood(self, particle: dict, observation) -> Float[Array, ""]:
        # Tian et al. eq. 7's form on the markers of μ(x)
        return self.templates.log_likelihood(self.markers_of(particle), observation,
                                             self.sharpness, self.nearest)


class LatentState(eqx.Module):
    """What the latent tracker carries between frames.

    Attributes:
        filter: the particle filter's state (latent points and placements).
        pose: ``(25,)`` the SPM pose reported at the last frame (the refined one; frame 0's
            given pose at the start and, with ``refine_steps = 0``, ever after).
        previous: ``(25,)`` the pose reported the frame before (``pose`` at the start): the
            arm search's constant-velocity centre is extrapolated from the two.
    """

    filter: smc.FilterState
    pose: Float[Array, " 25"]
    previous: Float[Array, " 25"]


class LatentTracker(ParticleTracker):
    """Algorithm 2 of Tian et al. with ``num_particles`` particles (see :func:`latent_tracker`).

    Attributes:
        latent_model: the state-space model.
        initial_pose: ``(25,)`` SPM pose of frame 0.
        refine_std: ``(25,)`` σ of the Gaussian prior about each refinement's start.
        particles: static N.
        mode_radius: the estimate is μ of the weighted mean latent of the particles within
            this many ν of the best particle (the local mode); ``inf`` gives the paper's
            weighted mean of all particles, which falls between the modes when jumps have put
            particles in two regions of the latent space that decode to similar poses.
        refine_steps: static Gauss–Newton steps of the full-state refinement per candidate
            (module docstring); 0 reports the paper's estimate.
        arm_grid: static offsets per arm angle of the arm search before each refinement
            (odd; 0: no search); ``arm_span``: the largest offset in radians; ``arm_margin``:
            the nats by which the best offset must beat offset 0 to be taken;
            ``arm_momentum``: the factor on the arm angles' last change that gives the search's
            second centre (0: none).
    """

    latent_model: LatentModel
    initial_pose: Float[Array, " 25"]
    refine_std: Float[Array, " 25"]
    particles: int = eqx.field(static=True)
    mode_radius: float = eqx.field(static=True, default=3.0)
    refine_steps: int = eqx.field(static=True, default=DEFAULT_REFINE_STEPS)
    arm_grid: int = eqx.field(static=True, default=DEFAULT_ARM_GRID)
    arm_span: float = eqx.field(static=True, default=DEFAULT_ARM_SPAN)
    arm_margin: float = eqx.field(static=True, default=DEFAULT_ARM_MARGIN)
    arm_momentum: float = eqx.field(static=True, default=DEFAULT_ARM_MOMENTUM)

    @property
    def model(self) -> LatentModel:
        return self.latent_model

    @property
    def num_particles(self) -> int:
        return self.particles

    def markers_of(self, particle) -> Array:
        return self.latent_model.markers_of(particle)

    def estimate_particle(self, particles, log_weights) -> dict:
        """The paper's estimate, the weighted mean latent (placement: weighted mean too), over
        the particles of the best particle's mode."""
        if np.isfinite(self.mode_radius):
            latents = particles["latent"]
            offset = (latents - latents[jnp.argmax(log_weights)]) / self.latent_model.latent_std
            near = jnp.sum(offset**2, axis=-1) <= self.mode_radius**2
            log_weights = jnp.where(near, log_weights, -jnp.inf)
        return smc.weighted_mean(particles, log_weights)

    def estimate_markers(self, particles, log_weights) -> Array:
        return self.markers_of(self.estimate_particle(particles, log_weights))

    def start(self, key: PRNGKeyArray, frame) -> LatentState:
        return LatentState(ParticleTracker.start(self, key, frame), self.initial_pose,
                           self.initial_pose)

    def first_estimate(self, state: LatentState) -> FrameEstimate:
        return ParticleTracker.first_estimate(self, state.filter)

    def update(self, key: PRNGKeyArray, state: LatentState, frame
               ) -> tuple[LatentState, FrameEstimate]:
        with jax.named_scope("filter"):
            filtered, estimate = ParticleTracker.update(self, key, state.filter, frame)
        return self._refined(state, filtered, estimate, frame)

    def update_in_chunk(self, key: PRNGKeyArray, state: LatentState, frames, index
                        ) -> tuple[LatentState, FrameEstimate]:
        with jax.named_scope("filter"):
            filtered, estimate = ParticleTracker.update_in_chunk(self, key, state.filter, frames,
                                                                 index)
        # the refinement reads the frame from the chunk in place (refine_pose)
        return self._refined(state, filtered, estimate, (frames, index))

    def _score(self, pose: Array, frame, parts: tuple[int, ...] | None = None) -> Array:
        """Log-likelihood of one SPM pose (bilinear reads), or the sum of its ``parts`` terms
        alone (``part_log_likelihoods``); −inf where it is NaN."""
        model = self.latent_model
        markers = spm_forward(pose, model.template)
        if parts is None:
            value = model.templates.log_likelihood(markers, frame, model.sharpness, False)
        else:
            value = jnp.sum(model.templates.part_log_likelihoods(markers, frame, model.sharpness,
                                                                 False, parts))
        return jnp.where(jnp.isnan(value), -jnp.inf, value)

    def search_arms(self, pose: Float[Array, " 25"], frame,
                    predicted: Float[Array, " 25"] | None = None) -> Float[Array, " 25"]:
        """The arm search (module docstring): for each arm, the best of ``arm_grid²`` offsets
        of its upper-arm and forearm angles if it beats offset 0 (the middle of the grid) by
        ``arm_margin`` nats, the rest of ``pose`` kept. With ``predicted`` (a pose whose arm
        angles are the constant-velocity prediction), the same grid of offsets about the
        predicted arm angles is searched too.

        The offsets move only the elbow and the wrist, so only the likelihood's terms that
        depend on them (``part_markers``: the arm's two strips) are computed: the others are
        the same for every offset and cancel from the comparison (a quarter of the work of
        whole-pose scores with the limb strips, the same choice to rounding). For the same
        reason one arm's search does not see the other arm's angles, so both arms are searched
        from ``pose`` as given, independently (XLA may run the two side by side): the same
        result as searching the right arm and then the left from the right's outcome."""
        half = self.arm_grid // 2  # offset 0 exactly in the middle
        offsets = (self.arm_span / max(half, 1)) * jnp.arange(-half, half + 1, dtype=pose.dtype)
        upper, fore = (grid.ravel() for grid in jnp.meshgrid(offsets, offsets))
        part_markers = self.latent_model.templates.part_markers
        searched = pose
        for (upper_index, fore_index), moved in zip(_ARM_ANGLES, _ARM_MARKERS, strict=True):
            parts = tuple(part for part, markers in enumerate(part_markers)
                          if moved.intersection(markers))
            centres = [pose]
            if predicted is not None:
                centres.append(pose.at[upper_index].set(predicted[upper_index])
                               .at[fore_index].set(predicted[fore_index]))
            trials = jnp.concatenate([
                jnp.broadcast_to(centre, (upper.size, pose.shape[0]))
                .at[:, upper_index].add(upper).at[:, fore_index].add(fore)
                for centre in centres])
            values = jax.vmap(lambda trial, parts=parts: self._score(trial, frame, parts))(trials)
            best = jnp.argmax(values)
            better = values[best] - values[upper.size // 2] >= self.arm_margin
            searched = (searched.at[upper_index].set(jnp.where(better, trials[best, upper_index],
                                                               pose[upper_index]))
                        .at[fore_index].set(jnp.where(better, trials[best, fore_index],
                                                      pose[fore_index])))
        return searched

    def _refine(self, start: Array, observed, predicted: Array | None = None
                ) -> tuple[Array, Array]:
        """One candidate searched (arms) and refined on the frame ``observed`` (or ``(frames,
        index)`` standing for it: ``refine_pose``), with its log-likelihood."""
        # the named scopes label the compiled ops by stage (benchmarks/profile_step.py)
        model = self.latent_model
        frame = observed[0][observed[1]] if isinstance(observed, tuple) else observed
        if self.arm_grid:
            with jax.named_scope("arm_search"):
                start = self.search_arms(start, frame, predicted)
        with jax.named_scope("gauss_newton"):
            refined, _ = refine_pose(start, observed, model.templates, model.template, start,
                                     self.refine_std, model.sharpness,
                                     max_steps=self.refine_steps, solver="parts")
        with jax.named_scope("choice"):
            refined = jnp.where(jnp.all(jnp.isfinite(refined)), refined, start)
            return refined, self._score(refined, frame)

    def _predicted(self, state: LatentState) -> Array | None:
        """The carried pose with its arm angles moved on by ``arm_momentum`` × their change
        over the last frame (wrapped to ±π), or None where ``arm_momentum`` is 0."""
        if not self.arm_momentum:
            return None
        change = state.pose - state.previous
        change = jnp.arctan2(jnp.sin(change), jnp.cos(change))
        return state.pose + jnp.where(_ARM_ANGLE_MASK, self.arm_momentum * change, 0)

    def _refined(self, state: LatentState, filtered: smc.FilterState, estimate: FrameEstimate,
                 observed) -> tuple[LatentState, FrameEstimate]:
        """The refined estimate on the frame ``observed`` (or ``(frames, index)``: _refine)."""
        carried = state.pose
        if self.refine_steps == 0:
            return LatentState(filtered, carried, carried), estimate
        model = self.latent_model
        with jax.named_scope("candidates"):
            particle = self.estimate_particle(filtered.particles, filtered.log_weights)
            decoded = states_from_features(model.prior.mean(particle["latent"]),
                                           particle["placement"], model.template)
        # the pose carried from the last frame and μ of the particles' estimate, refined side
        # by side (module docstring); the better-scoring one is reported and carried
        predicted = self._predicted(state)
        poses, values = jax.vmap(self._refine, in_axes=(0, None, None))(
            jnp.stack([carried, decoded.astype(carried.dtype)]), observed, predicted)
        pose = jnp.where(values[0] >= values[1], poses[0], poses[1])
        estimate = eqx.tree_at(lambda e: e.markers, estimate, spm_forward(pose, model.template))
        return LatentState(filtered, pose, carried), estimate


def latent_tracker(
    prior: GPLVM,
    template: SPMTemplate,
    first_frame: Float[ArrayLike, "height width"],
    first_markers: Float[ArrayLike, "markers 2"],
    *,
    num_particles: int = 200,
    fps: float | None = None,
    placement_std: tuple[float, float, float] | None = None,
    initial_spread: float = 1.0,
    likelihood: str = DEFAULT_LIKELIHOOD,
    background: Float[ArrayLike, "height width"] | None = None,
    sharpness: float | None = None,
    jump_probability: float = DEFAULT_JUMP_PROBABILITY,
    mode_radius: float = 3.0,
    refine_steps: int | None = None,
    refine_std: Float[ArrayLike, " 25"] | None = None,
    arm_grid: int | None = None,
    arm_span: float = DEFAULT_ARM_SPAN,
    arm_margin: float = DEFAULT_ARM_MARGIN,
    arm_momentum: float | None = None,
    nearest: bool = True,
    dtype=jnp.float32,
) -> LatentTracker:
    """Initialise the latent tracker on a frame whose markers are known (ground truth, or an
    automatic initialisation).

    Args:
        prior: a trained GPLVM with its dynamics ν (``fit_gplvm(..., sequence_ids=...)``).
        template: the SPM template its training poses were expressed in.
        first_frame: ``(height, width)`` grey frame 0 (or its ``(3, height, width)``
            observation with the edge maps).
        first_markers: ``(12, 2)`` its markers (``SPM_MARKERS`` order): they give the NCC
            templates, the placement and, through μ⁻¹, the initial latent point.
        fps: the video's frame rate; ν (learned at ``prior.dynamics_fps``) is rescaled by
            ``sqrt(prior fps / fps)``, a random walk's step over a longer or shorter frame.
        placement_std: per-frame random-walk std of (log scale, x px, y px); default
            (0.01, 1 % of the torso, 1 % of the torso).
        likelihood: ``"limbs+edges"`` (strips along the segments and their edges),
            ``"limbs"`` (the strips alone) or ``"markers"`` (the paper's patches at the
            markers); see :mod:`jaxtrack.likelihoods.appearance`.
        background: ``(height, width)`` grey background of a static camera (the video's
            median, ``jaxtrack.vision.median_grey_background``) for the ``"limbs+edges"``
            likelihood's foreground term, which scores the arm strips' centre lines against
            it; None: no foreground term.
        sharpness: λ of the likelihood; None for the likelihood's default.
        jump_probability: chance per particle and frame of a jump to a random training
            latent (0: the paper's pure random walk).
        mode_radius: the estimate averages the particles within this many ν of the best one
            (``float("inf")``: all particles, as the paper).
        refine_steps: Gauss–Newton steps per candidate of the full-state refinement of the
            reported pose (module docstring); 0 reports the paper's estimate, μ of the
            particles' estimate, and costs nothing. None: :data:`DEFAULT_REFINE_STEPS` with
            the strip likelihoods, 0 with ``"markers"`` (measured there, see the constant).
        refine_std: ``(25,)`` σ of the Gaussian prior about each refinement's start; default
            the MHT baseline's without training frames: 4 × 10 × ``default_noise_floor`` (0.08
            in log scale, angles and log lengths, 8 % of the torso in the neck position).
        arm_grid: offsets per arm angle of the arm search that starts each refinement (module
            docstring); odd, so that offset 0 is among them; 0 switches the search off (it
            runs only where ``refine_steps`` > 0); None: :data:`DEFAULT_ARM_GRID`.
        arm_span: the search's largest angle offset in radians.
        arm_margin: nats by which the search's best offset must beat the arm as it was.
        arm_momentum: the search also runs about the arm angles moved on by this factor (in
            [0, 1]) times their change over the last frame; 0: about the carried arm alone;
            None: :data:`DEFAULT_ARM_MOMENTUM`.
        nearest: nearest-pixel sampling (fast) rather than bilinear.
    """
    first_markers = np.asarray(first_markers, np.float64)
    if first_markers.shape != (12, 2) or not np.all(np.isfinite(first_markers)):
        raise ValueError(f"first_markers must be 12 finite (x, y) markers, got shape "
                         f"{first_markers.shape}")
    if not 0 <= jump_probability < 1:
        raise ValueError(f"jump_probability must be in [0, 1), got {jump_probability}")
    if sharpness is None:
        sharpness = default_sharpness(likelihood)
    std = np.asarray(prior.dynamics_std, np.float64)
    if not np.all(np.isfinite(std)):
        raise ValueError("the GPLVM has no latent dynamics (ν is NaN); train it with "
                         "sequence_ids so that ν is estimated")
    if fps is not None and np.isfinite(float(prior.dynamics_fps)):
        std = std * np.sqrt(float(prior.dynamics_fps) / fps)
    state = np.asarray(spm_initial_state(jnp.asarray(first_markers), template), np.float64)
    with jax.enable_x64(True):  # μ⁻¹ in the prior's float64
        features = pose_features(jnp.asarray(state), jax.tree.map(
            lambda leaf: jnp.asarray(np.asarray(leaf), jnp.float64), template))
        latent = np.asarray(prior.inverse(features[None]).latents[0])
    torso = float(np.exp(state[0]))
    if placement_std is None:
        placement_std = (0.01, 0.01 * torso, 0.01 * torso)
    cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
    model = LatentModel(
        prior=prior.astype(dtype),
        template=jax.tree.map(cast, template),
        templates=make_appearance_templates(likelihood, cast(first_frame), cast(first_markers),
                                            background),
        initial_latent=cast(latent), initial_placement=cast(state[:PLACEMENT_SIZE]),
        latent_std=cast(std),
        jump_threshold=cast(NormalDist().inv_cdf(jump_probability) if jump_probability > 0
                            else -np.inf),
        placement_std=cast(placement_std),
        initial_spread=cast(initial_spread), sharpness=cast(sharpness), nearest=bool(nearest),
    )
    if not mode_radius > 0:
        raise ValueError(f"mode_radius must be positive (inf for all particles), got "
                         f"{mode_radius}")
    if refine_steps is None:
        refine_steps = default_refine_steps(likelihood)
    if int(refine_steps) != refine_steps or refine_steps < 0:
        raise ValueError(f"refine_steps must be a non-negative integer, got {refine_steps}")
    if refine_std is None:
        refine_std = 4 * 10 * default_noise_floor(torso)
    refine_std = np.broadcast_to(np.asarray(refine_std, np.float64), (SPM_STATE_SIZE,))
    if not np.all(np.isfinite(refine_std) & (refine_std > 0)):
        raise ValueError(f"refine_std must be positive and finite, got {refine_std}")
    if arm_grid is None:
        arm_grid = DEFAULT_ARM_GRID
    if int(arm_grid) != arm_grid or arm_grid < 0 or (arm_grid > 0 and arm_grid % 2 == 0):
        raise ValueError(f"arm_grid must be 0 or an odd positive integer (offset 0 on the "
                         f"grid), got {arm_grid}")
    if not (np.isfinite(arm_span) and arm_span > 0):
        raise ValueError(f"arm_span must be a positive number of radians, got {arm_span}")
    if not (np.isfinite(arm_margin) and arm_margin >= 0):
        raise ValueError(f"arm_margin must be a non-negative number of nats, got {arm_margin}")
    if arm_momentum is None:
        arm_momentum = DEFAULT_ARM_MOMENTUM
    if not (np.isfinite(arm_momentum) and 0 <= arm_momentum <= 1):
        raise ValueError(f"arm_momentum must be in [0, 1], got {arm_momentum}")
    return LatentTracker(latent_model=model, initial_pose=cast(state), refine_std=cast(refine_std),
                         particles=int(num_particles), mode_radius=float(mode_radius),
                         refine_steps=int(refine_steps), arm_grid=int(arm_grid),
                         arm_span=float(arm_span), arm_margin=float(arm_margin),
                         arm_momentum=float(arm_momentum))
