"""Tian, Li & Sclaroff's (2005) tracker: CONDENSATION in a learned GPLVM latent space.

Algorithm 2 of the paper: every particle is a 2-D latent point that random-walks with the
learned step ν (eq. 6); it is decoded by the GP mean μ(x) (eq. 3) into the SPM pose and then
into 12 image markers, and weighted by the appearance likelihood at those markers (eq. 7's
form). The estimate is μ(weighted mean latent); the initial latent point is μ⁻¹ of frame 0's
pose (eq. 5).

Departures from the paper, each switchable back (reasons and measurements: ``docs/trackers.md``):

* **Placement.** A particle also carries the SPM placement (log scale and neck position),
  random-walking with small steps, so a subject who shifts or leans is followed
  (``placement_std = (0, 0, 0)`` gives the paper's fixed placement).
* **Likelihood.** Limb strips and their oriented edges (``Likelihood("limbs+edges")``) by
  default instead of eq. 7's patches at the markers (``Likelihood("markers")``).
* **Jumps** (:class:`~jaxtrack.priors.dynamics.LatentWalk`): with probability
  ``jump_probability`` a particle is redrawn at a random training latent, so a gesture that
  leaves one region of the latent space for a distant one that decodes to a similar pose is
  followed (0: the paper's random walk).
* **Local mode.** The estimate averages the particles within ``mode_radius`` ν of the best one
  (``inf``: all, as the paper).
* **The subject's proportions** (``subject_lengths=True``, the default): μ(x) is drawn with
  the tracked person's link lengths, read off frame 0's pose, rather than the training
  subjects' (False: the paper's decoder).
* **Partitioned sampling** (``partitioned=True``, with a ``PartsGPLVM`` prior; off by
  default): each frame moves the torso, then each arm, resampling by that part's strips before
  the next part moves (:mod:`jaxtrack.trackers._partitioned`), so that one arm's sharp evidence
  does not decide where the other arm goes.
* **Refinement** (``refinement=Refinement()``, the stage every tracker can take,
  :mod:`jaxtrack.trackers._refinement`): the reported pose refined in the full SPM state; None
  reports the paper's estimate.
"""

from __future__ import annotations

from statistics import NormalDist

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPM_LINKS, SPMTemplate, spm_forward
from jaxtrack.likelihoods import PartTemplates
from jaxtrack.priors.dynamics import LatentVelocity, LatentWalk
from jaxtrack.priors.gplvm import GPLVM
from jaxtrack.priors.poses import (
    PLACEMENT_SIZE,
    markers_from_features,
    pose_features,
    states_from_features,
)
from jaxtrack.trackers._options import RESAMPLERS, Engine, Likelihood, Refinement, options_record
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
from jaxtrack.trackers._partitioned import partitioned_step, stages_of
from jaxtrack.trackers._refinement import RefinementState, refine, start_refinement
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk

__all__ = ["DEFAULT_JUMP_PROBABILITY", "LatentModel", "LatentState", "LatentTracker",
           "default_refinement", "latent_tracker"]

DEFAULT_JUMP_PROBABILITY = 0.05
"""ε of the jump proposal (module docstring); chosen on the validation subject over {0.05, 0.2,
0.5}, which tied within their paired 95 % interval, the tie going to the fewest jumps
(``python -m papers.tian2005.defaults_sweep``; ``docs/trackers.md``, "Why the defaults are what
they are"). It was 0.2, first tuned on a test subject's clip."""


def default_refinement(likelihood: Likelihood) -> Refinement | None:
    """The latent tracker's refinement when none is chosen: :class:`Refinement` with the strip
    likelihoods, none (the paper's estimate) with eq. 7's marker patches, which give
    Gauss–Newton nothing to climb (``docs/trackers.md``, "Refinement")."""
    return None if likelihood.kind == "markers" else Refinement()


class LatentModel(smc.StateSpaceModel):
    """The state-space model of the latent tracker (one particle: ``{"latent", "placement"}``).

    Attributes:
        prior: the GPLVM (float32 for speed).
        template: SPM template the GPLVM's poses are expressed in.
        templates: appearance templates from the first frame.
        walk: the latent random walk with jumps, and the placement's walk.
        initial_latent, initial_placement: where frame 0's pose lies.
        initial_spread: std of the initial cloud around the initial latent, in units of ν.
        sharpness: λ of the likelihood.
        nearest: read pixels at the nearest sample point (10–40× faster) instead of bilinearly.
        link_scale: ``(11,)`` the tracked subject's link lengths over the prior's, fixed at
            frame 0 (:attr:`LatentTracker.subject_lengths`); ones: the prior's proportions.
    """

    prior: GPLVM
    template: SPMTemplate
    templates: PartTemplates
    walk: LatentWalk
    initial_latent: Float[Array, " latent"]
    initial_placement: Float[Array, " 3"]
    initial_spread: Float[Array, ""]
    sharpness: Float[Array, ""]
    link_scale: Float[Array, " 11"]
    nearest: bool = eqx.field(static=True, default=True)

    def init(self, key: PRNGKeyArray) -> dict:
        key_latent, key_placement = jr.split(key)
        latent = self.initial_latent + self.initial_spread * self.walk.latent_std * jr.normal(
            key_latent, self.initial_latent.shape, self.initial_latent.dtype)
        placement = self.initial_placement + self.walk.placement_std * jr.normal(
            key_placement, (PLACEMENT_SIZE,), self.initial_placement.dtype)
        if self.walk.velocity is None:
            return {"latent": latent, "placement": placement}
        return {"latent": latent, "placement": placement, "previous": latent}  # at rest

    def propagate(self, key: PRNGKeyArray, particle: dict, time) -> dict:
        return self.walk.move(key, particle)

    def features_of(self, latent: Float[Array, " latent"]) -> Float[Array, " 22"]:
        """μ(x) with every link stretched to the tracked subject's proportions."""
        vectors = self.prior.mean(latent).reshape(-1, 2) * self.link_scale[:, None]
        return vectors.reshape(-1)

    def markers_of(self, particle: dict) -> Float[Array, "markers 2"]:
        # spm_forward(states_from_features(μ(x), placement)) without the angles in between
        return markers_from_features(self.features_of(particle["latent"]),
                                     particle["placement"])

    def log_likelihood(self, particle: dict, observation) -> Float[Array, ""]:
        # Tian et al. eq. 7's form on the markers of μ(x)
        return self.templates.log_likelihood(self.markers_of(particle), observation,
                                             self.sharpness, self.nearest)


class LatentState(eqx.Module):
    """What the latent tracker carries between frames.

    Attributes:
        model: the state-space model assembled at frame 0 (templates cut from the first frame,
            the initial latent point from μ⁻¹); constant over the sequence.
        filter: the particle filter's state (latent points and placements).
        refined: the refinement stage's carried poses (None without a refinement).
        refine_std: ``(25,)`` σ of the refinement's prior (None without a refinement).
    """

    model: LatentModel
    filter: smc.FilterState
    refined: RefinementState | None
    refine_std: Float[Array, " 25"] | None


class _HostPrior:
    """The prior as trained (float64), for μ⁻¹ at ``start`` on the host: a static field of the
    tracker that never enters compiled code.

    Compared and hashed by the prior's contents (a digest of its arrays and structure), not by
    identity: compiled programs are cached by their static arguments, so with identity every
    new tracker of the same prior compiled anew and its programs stayed cached, about 1 000
    memory mappings each, until a process that built ~50 trackers ran out of them (the
    kernel's vm.max_map_count, 65 530 here; measured with /proc/self/maps).
    """

    def __init__(self, prior: GPLVM):
        import hashlib

        self.prior = prior
        leaves, structure = jax.tree.flatten(prior)
        digest = hashlib.sha256(str(structure).encode())
        for leaf in leaves:
            array = np.asarray(leaf)
            digest.update(f"{array.dtype}{array.shape}".encode())
            digest.update(np.ascontiguousarray(array).tobytes())
        self._digest = digest.hexdigest()

    def __eq__(self, other) -> bool:
        return isinstance(other, _HostPrior) and other._digest == self._digest

    def __hash__(self) -> int:
        return hash(self._digest)


@eqx.filter_jit
def _inverse_latent(prior, features: Array) -> Array:
    """μ⁻¹ of one pose's features, compiled once per prior's shapes: solved eagerly, the
    optimiser compiles its loop on every call and keeps it (about 190 memory mappings per
    tracker started)."""
    return prior.inverse(features[None]).latents[0]


class LatentTracker(ImageTracker):
    """Algorithm 2 of Tian et al. (module docstring; build one with :func:`latent_tracker`).

    Attributes:
        prior: the GPLVM in the tracker's float type.
        template: SPM template the prior's poses are expressed in.
        likelihood: how frames are scored.
        latent_std: ``(latent,)`` ν per frame, rescaled to the video's frame rate.
        engine: the particle filter's settings (N, resampler, ESS threshold).
        refinement: the full-state refinement of the reported pose; None: the paper's estimate.
        background: grey background of a static camera for the foreground term; None: none.
        placement_std: per-frame std of (log scale, x px, y px); None: (0.01, 1 % of the
            torso, 1 % of the torso).
        initial_spread: std of the initial cloud about μ⁻¹ of frame 0's pose, in units of ν.
        jump_probability: chance per particle and frame of a jump to a training latent.
        mode_radius: the estimate averages the particles within this many ν of the best one
            (of σ, the walk's own step, with a ``velocity``).
        subject_lengths: decode every particle with the tracked subject's link lengths: each
            link of μ(x) is stretched by (its length in frame 0's pose) / (its length in μ of
            μ⁻¹(frame 0's pose)), clipped to [1/2, 2], so a person whose proportions differ
            from the training subjects' is not drawn with theirs. False: the paper's decoder.
            On by default, chosen on the validation subject's nine gesture clips
            (``docs/trackers.md``, "Why the defaults are what they are").
        partitioned: partitioned sampling over the prior's parts (module docstring; needs a
            ``PartsGPLVM`` of ``UPPER_BODY_PARTS`` and a strip likelihood); False: one
            CONDENSATION step on the whole latent point, as the paper.
        velocity: ``(latent,)`` the carried share a of the last latent step
            (:class:`~jaxtrack.priors.dynamics.LatentVelocity`, ``latent_std`` then its σ);
            None: the paper's random walk.
    """

    prior: GPLVM
    template: SPMTemplate
    likelihood: Likelihood
    latent_std: Float[Array, " latent"]
    engine: Engine
    host_prior: _HostPrior = eqx.field(static=True)
    refinement: Refinement | None = None
    background: Float[Array, "height width"] | None = None
    placement_std: tuple[float, float, float] | None = eqx.field(static=True, default=None)
    initial_spread: float = eqx.field(static=True, default=1.0)
    jump_probability: float = eqx.field(static=True, default=DEFAULT_JUMP_PROBABILITY)
    mode_radius: float = eqx.field(static=True, default=3.0)
    subject_lengths: bool = eqx.field(static=True, default=True)
    partitioned: bool = eqx.field(static=True, default=False)
    velocity: Float[Array, " latent"] | None = None

    def __check_init__(self):
        if not 0 <= self.jump_probability < 1:
            raise ValueError(f"jump_probability must be in [0, 1), got {self.jump_probability}")
        if not self.mode_radius > 0:
            raise ValueError(f"mode_radius must be positive (inf for all particles), got "
                             f"{self.mode_radius}")
        if not self.initial_spread >= 0:
            raise ValueError(f"initial_spread must be >= 0, got {self.initial_spread!r}")

    @property
    def num_particles(self) -> int:
        return self.engine.num_particles

    def options(self) -> dict:
        return {"method": "latent", "particles": self.num_particles,
                "engine": options_record(self.engine),
                "likelihood": options_record(self.likelihood),
                "refinement": options_record(self.refinement),
                "foreground": self.background is not None,
                "placement_std": self.placement_std, "initial_spread": self.initial_spread,
                "jump_probability": self.jump_probability, "mode_radius": self.mode_radius,
                "subject_lengths": self.subject_lengths, "partitioned": self.partitioned,
                "latent_velocity": self.velocity is not None}

    def start(self, key: PRNGKeyArray, first_frame, initial_pose) -> LatentState:
        markers = check_initial_pose(initial_pose)
        dtype = self.latent_std.dtype
        state = np.asarray(frame0_state(markers, self.template, dtype), np.float64)
        prior = self.host_prior.prior
        with jax.enable_x64(True):  # μ⁻¹ (eq. 5) in the prior's float64
            features = pose_features(jnp.asarray(state), jax.tree.map(
                lambda leaf: jnp.asarray(np.asarray(leaf), jnp.float64), self.template))
            latent = np.asarray(_inverse_latent(prior, features))
            link_scale = np.ones(len(SPM_LINKS))
            if self.subject_lengths:
                decoded = np.asarray(prior.mean(jnp.asarray(latent))).reshape(-1, 2)
                observed = np.asarray(features).reshape(-1, 2)
                ratio = (np.linalg.norm(observed, axis=-1)
                         / np.maximum(np.linalg.norm(decoded, axis=-1), 1e-9))
                link_scale = np.clip(ratio, 0.5, 2.0)
        torso = float(np.exp(state[0]))
        placement_std = self.placement_std
        if placement_std is None:
            placement_std = (0.01, 0.01 * torso, 0.01 * torso)
        cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
        threshold = (NormalDist().inv_cdf(self.jump_probability) if self.jump_probability > 0
                     else -np.inf)
        model = LatentModel(
            prior=self.prior, template=self.template,
            templates=frame0_templates(self.likelihood, first_frame, markers, self.background,
                                       dtype),
            walk=LatentWalk(latent_std=self.latent_std, jump_threshold=cast(threshold),
                            pool=self.prior.latents, placement_std=cast(placement_std),
                            velocity=self.velocity),
            initial_latent=cast(latent), initial_placement=cast(state[:PLACEMENT_SIZE]),
            initial_spread=cast(self.initial_spread), sharpness=cast(self.likelihood.lam),
            link_scale=cast(link_scale), nearest=self.likelihood.nearest)
        refined, refine_std = start_refinement(self.refinement, cast(state))
        filtered = initialize_filter(key, model, device_observation(first_frame),
                                    self.num_particles)
        return LatentState(model, filtered, refined, refine_std)

    def estimate_particle(self, model: LatentModel, particles, log_weights) -> dict:
        """The paper's estimate, the weighted mean latent (placement: weighted mean too), over
        the particles of the best particle's mode."""
        if np.isfinite(self.mode_radius):
            latents = particles["latent"]
            offset = (latents - latents[jnp.argmax(log_weights)]) / model.walk.latent_std
            near = jnp.sum(offset**2, axis=-1) <= self.mode_radius**2
            log_weights = jnp.where(near, log_weights, -jnp.inf)
        return smc.weighted_mean(particles, log_weights)

    def _cloud(self, model: LatentModel, filtered: smc.FilterState, info: smc.StepInfo
               ) -> FrameEstimate:
        particle = self.estimate_particle(model, filtered.particles, filtered.log_weights)
        return cloud_estimate(filtered, info, model.markers_of(particle), model.markers_of)

    def first_estimate(self, state: LatentState) -> FrameEstimate:
        return self._cloud(state.model, state.filter, first_info(state.filter))

    def update(self, key: PRNGKeyArray, state: LatentState, frame: Array | FrameInChunk
               ) -> tuple[LatentState, FrameEstimate]:
        with jax.named_scope("filter"):
            if self.partitioned:
                filtered, info = partitioned_step(
                    key, state.filter, frame, state.model, stages_of(self.prior),
                    RESAMPLERS[self.engine.resampler]())
            else:
                filtered, info = filter_step(self.engine, key, state.filter, frame,
                                             state.model)
            estimate = self._cloud(state.model, filtered, info)
        return self._report(state, filtered, estimate, frame)

    def _report(self, state: LatentState, filtered: smc.FilterState, estimate: FrameEstimate,
                frame: Array | FrameInChunk) -> tuple[LatentState, FrameEstimate]:
        """The new state and the frame's report, the refinement stage run on ``frame``."""
        model = state.model
        if self.refinement is None:
            return LatentState(model, filtered, None, None), estimate
        with jax.named_scope("candidates"):
            particle = self.estimate_particle(model, filtered.particles, filtered.log_weights)
            decoded = states_from_features(model.features_of(particle["latent"]),
                                           particle["placement"], model.template)
        # the carried pose and μ of the particles' estimate refined side by side; the particles
        # stay in the latent space (the refinement does not feed back into them)
        refined, pose = refine(self.refinement, state.refined, decoded, frame, model.templates,
                               model.template, model.sharpness, state.refine_std)
        estimate = eqx.tree_at(lambda e: e.markers, estimate, spm_forward(pose, model.template))
        return LatentState(model, filtered, refined, state.refine_std), estimate



def latent_tracker(
    prior: GPLVM,
    template: SPMTemplate,
    *,
    engine: Engine = Engine(200),
    likelihood: Likelihood = Likelihood(),
    refinement: Refinement | None | str = "default",
    background: Float[ArrayLike, "height width"] | None = None,
    fps: float | None = None,
    placement_std: tuple[float, float, float] | None = None,
    initial_spread: float = 1.0,
    jump_probability: float = DEFAULT_JUMP_PROBABILITY,
    mode_radius: float = 3.0,
    subject_lengths: bool = True,
    partitioned: bool = False,
    velocity: LatentVelocity | None = None,
    dtype=jnp.float32,
) -> LatentTracker:
    """The latent tracker with a trained prior.

    Args:
        prior: a trained GPLVM with its dynamics ν (``fit_gplvm(..., sequence_ids=...)``).
        template: the SPM template its training poses were expressed in.
        engine: the particle filter's settings (:class:`~jaxtrack.trackers.Engine`: N,
            resampler, ESS threshold).
        likelihood: how frames are scored (:class:`~jaxtrack.trackers.Likelihood`).
        refinement: the full-state refinement of the reported pose; None: the paper's
            estimate; ``"default"``: :func:`default_refinement` of the likelihood.
        background: ``(height, width)`` grey background of a static camera (the video's
            median, ``jaxtrack.vision.median_grey_background``) for the ``"limbs+edges"``
            likelihood's foreground term; None: none.
        fps: the video's frame rate; ν (learned at ``prior.dynamics_fps``) is rescaled by
            ``sqrt(prior fps / fps)``, a random walk's step over a longer or shorter frame.
        placement_std: see :class:`LatentTracker`.
        initial_spread: see :class:`LatentTracker`.
        jump_probability: see :class:`LatentTracker`.
        mode_radius: see :class:`LatentTracker`.
        subject_lengths: see :class:`LatentTracker`.
        partitioned: see :class:`LatentTracker`.
        velocity: a second-order latent walk learned from the prior's training latents
            (:func:`~jaxtrack.priors.dynamics.fit_latent_velocity` of ``prior.latents`` and the
            training sequence ids), in place of the random walk ν; its frame rate must be the
            video's. None: the paper's random walk.
        dtype: the filter's float type (μ⁻¹ at the start always runs in float64).
    """
    std = np.asarray(prior.dynamics_std, np.float64)
    if not np.all(np.isfinite(std)):
        raise ValueError("the GPLVM has no latent dynamics (ν is NaN); train it with "
                         "sequence_ids so that ν is estimated")
    if fps is not None:
        if not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        if np.isfinite(float(prior.dynamics_fps)):
            std = std * np.sqrt(float(prior.dynamics_fps) / fps)
    carried = None
    if velocity is not None:
        carried = np.asarray(velocity.coefficient, np.float64)
        if carried.shape != std.shape or np.asarray(velocity.noise_std).shape != std.shape:
            raise ValueError(f"velocity is for a {carried.shape[-1]}-D latent space, the prior's "
                             f"is {std.shape[0]}-D")
        if (fps is not None and np.isfinite(velocity.fps)
                and abs(velocity.fps - fps) > 1e-6 * fps):
            raise ValueError(f"velocity was learned at {velocity.fps:g} fps and the video is "
                             f"{fps:g} fps; learn it at the video's frame rate")
        std = np.asarray(velocity.noise_std, np.float64)
    if isinstance(refinement, str):
        if refinement != "default":
            raise ValueError(f"refinement must be a Refinement, None or 'default', got "
                             f"{refinement!r}")
        refinement = default_refinement(likelihood)
    if placement_std is not None:
        placement_std = tuple(float(value) for value in placement_std)
        if len(placement_std) != PLACEMENT_SIZE or not all(
                np.isfinite(value) and value >= 0 for value in placement_std):
            raise ValueError(f"placement_std must be {PLACEMENT_SIZE} numbers >= 0 (log scale, "
                             f"x px, y px), got {placement_std}")
    if partitioned:
        stages_of(prior)  # a PartsGPLVM of the three upper-body parts, or a clear error
        if engine.iterations_per_frame != 1:
            raise ValueError(f"partitioned sampling runs one cycle per frame; got an engine "
                             f"with iterations_per_frame={engine.iterations_per_frame}")
        if likelihood.kind not in ("limbs+edges", "limbs"):
            raise ValueError(f"partitioned sampling weighs each part by its limb strips; the "
                             f"{likelihood.kind!r} likelihood has none (use 'limbs+edges')")
        for on, term, option in ((likelihood.has_coverage, "coverage", "coverage_weight"),
                                 (likelihood.has_keypoints, "keypoint", "keypoint_weight")):
            if on:
                raise ValueError(f"partitioned sampling weighs each part by its own terms; the "
                                 f"{term} term belongs to no part (leave {option} off)")
    cast = lambda value: jnp.asarray(np.asarray(value, np.float64), dtype)  # noqa: E731
    return LatentTracker(
        prior=prior.astype(dtype), template=jax.tree.map(cast, template), likelihood=likelihood,
        latent_std=cast(std), engine=engine, host_prior=_HostPrior(prior),
        refinement=refinement, background=background, placement_std=placement_std,
        initial_spread=float(initial_spread), jump_probability=float(jump_probability),
        mode_radius=float(mode_radius), subject_lengths=bool(subject_lengths),
        partitioned=bool(partitioned), velocity=None if carried is None else cast(carried))
