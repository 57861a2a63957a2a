"""Tian, Li & Sclaroff's (2005) tracker: CONDENSATION in a learned GPLVM latent space.

Algorithm 2 of the paper: every particle is a 2-D latent point that random-walks with the
learned step ν; it is decoded by the GP mean μ(x) into the SPM pose and then into 12 image
markers, and weighted by the NCC of template patches at those markers (eq. 7). The estimate is
μ(weighted mean latent).

The paper's particles hold the latent point only: its subjects stay where they are. Here a
particle also carries the SPM placement (log scale and neck position), random-walking with small
steps, so a subject who shifts or leans is followed; ``placement_std = 0`` gives the paper's
fixed placement.

Two departures from the paper, each measured on a held-out real wave (README, "Tracking"), each
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
from jaxtrack.body import SPMTemplate, spm_initial_state
from jaxtrack.likelihoods import (
    DEFAULT_LIKELIHOOD,
    AppearanceTemplates,
    default_sharpness,
    make_appearance_templates,
)
from jaxtrack.priors.gplvm import GPLVM
from jaxtrack.priors.poses import PLACEMENT_SIZE, markers_from_features, pose_features
from jaxtrack.trackers._runner import ParticleTracker

__all__ = ["DEFAULT_JUMP_PROBABILITY", "LatentModel", "LatentTracker", "latent_tracker"]

DEFAULT_JUMP_PROBABILITY = 0.2
"""ε of the jump proposal (module docstring). On the demo's held-out wave (limb strips, 200
particles, 3 seeds) the tracker lost the subject (above 25 % of the torso for 10 frames) in 2 of
3 runs with ε = 0 and in 1 with ε = 0.2; mean error 16.9 and 16.2 % of the torso, 44 and 48 % of
frames within 15 %."""


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


class LatentTracker(ParticleTracker):
    """Algorithm 2 of Tian et al. with ``num_particles`` particles (see :func:`latent_tracker`).

    Attributes:
        latent_model: the state-space model.
        particles: static N.
        mode_radius: the estimate is μ of the weighted mean latent of the particles within
            this many ν of the best particle (the local mode); ``inf`` gives the paper's
            weighted mean of all particles, which falls between the modes when jumps have put
            particles in two regions of the latent space that decode to similar poses.
    """

    latent_model: LatentModel
    particles: int = eqx.field(static=True)
    mode_radius: float = eqx.field(static=True, default=3.0)

    @property
    def model(self) -> LatentModel:
        return self.latent_model

    @property
    def num_particles(self) -> int:
        return self.particles

    def markers_of(self, particle) -> Array:
        return self.latent_model.markers_of(particle)

    def estimate_markers(self, particles, log_weights) -> Array:
        # the paper's estimate, μ of the weighted mean latent (placement: weighted mean too),
        # over the particles of the best particle's mode
        if np.isfinite(self.mode_radius):
            latents = particles["latent"]
            offset = (latents - latents[jnp.argmax(log_weights)]) / self.latent_model.latent_std
            near = jnp.sum(offset**2, axis=-1) <= self.mode_radius**2
            log_weights = jnp.where(near, log_weights, -jnp.inf)
        return self.markers_of(smc.weighted_mean(particles, log_weights))


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
    sharpness: float | None = None,
    jump_probability: float = DEFAULT_JUMP_PROBABILITY,
    mode_radius: float = 3.0,
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
        sharpness: λ of the likelihood; None for the likelihood's default.
        jump_probability: chance per particle and frame of a jump to a random training
            latent (0: the paper's pure random walk).
        mode_radius: the estimate averages the particles within this many ν of the best one
            (``float("inf")``: all particles, as the paper).
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
        templates=make_appearance_templates(likelihood, cast(first_frame), cast(first_markers)),
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
    return LatentTracker(latent_model=model, particles=int(num_particles),
                         mode_radius=float(mode_radius))
