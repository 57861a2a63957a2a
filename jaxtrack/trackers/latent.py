"""Tian, Li & Sclaroff's (2005) tracker: CONDENSATION in a learned GPLVM latent space.

Algorithm 2 of the paper: every particle is a 2-D latent point that random-walks with the
learned step ν; it is decoded by the GP mean μ(x) into the SPM pose and then into 12 image
markers, and weighted by the NCC of template patches at those markers (eq. 7). The estimate is
μ(weighted mean latent).

The paper's particles hold the latent point only: its subjects stay where they are. Here a
particle also carries the SPM placement (log scale and neck position), random-walking with small
steps, so a subject who shifts or leans is followed; ``placement_std = 0`` gives the paper's
fixed placement.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body import SPMTemplate, spm_initial_state
from jaxtrack.likelihoods import (
    DEFAULT_NCC_SHARPNESS,
    NCCTemplates,
    make_templates,
    ncc_log_likelihood,
    ncc_log_likelihood_nearest,
)
from jaxtrack.priors.gplvm import GPLVM
from jaxtrack.priors.poses import PLACEMENT_SIZE, markers_from_features, pose_features
from jaxtrack.trackers._runner import ParticleTracker

__all__ = ["LatentModel", "LatentTracker", "latent_tracker"]


class LatentModel(smc.StateSpaceModel):
    """The state-space model of the latent tracker (one particle: ``{"latent", "placement"}``).

    Attributes:
        prior: the GPLVM (float32 for speed).
        template: SPM template the GPLVM's poses are expressed in.
        templates: NCC template patches from the first frame.
        initial_latent, initial_placement: where frame 0's pose lies.
        latent_std: ``(latent,)`` random-walk step per frame (ν, rescaled to the video's rate).
        placement_std: ``(3,)`` random-walk step of (log scale, x, y) per frame.
        initial_spread: std of the initial cloud around the initial latent, in units of ν.
        sharpness: λ of the NCC likelihood.
        nearest: read patches at the nearest pixel (10–40× faster) instead of bilinearly.
    """

    prior: GPLVM
    template: SPMTemplate
    templates: NCCTemplates
    initial_latent: Float[Array, " latent"]
    initial_placement: Float[Array, " 3"]
    latent_std: Float[Array, " latent"]
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
        # Tian et al. §4: random walk x_{t+1} = x_t + ω, ω ~ N(0, diag ν²)
        noise = smc.fast_normal(key, (particle["latent"].shape[0] + PLACEMENT_SIZE,),
                                particle["latent"].dtype)
        latent_dim = particle["latent"].shape[0]
        return {"latent": particle["latent"] + self.latent_std * noise[:latent_dim],
                "placement": particle["placement"] + self.placement_std * noise[latent_dim:]}

    def markers_of(self, particle: dict) -> Float[Array, "markers 2"]:
        # spm_forward(states_from_features(μ(x), placement)) without the angles in between
        return markers_from_features(self.prior.mean(particle["latent"]), particle["placement"])

    def log_likelihood(self, particle: dict, observation) -> Float[Array, ""]:
        # Tian et al. eq. 7 on the markers of μ(x)
        score = ncc_log_likelihood_nearest if self.nearest else ncc_log_likelihood
        return score(self.markers_of(particle), observation, self.templates, self.sharpness)


class LatentTracker(ParticleTracker):
    """Algorithm 2 of Tian et al. with ``num_particles`` particles (see :func:`latent_tracker`)."""

    latent_model: LatentModel
    particles: int = eqx.field(static=True)

    @property
    def model(self) -> LatentModel:
        return self.latent_model

    @property
    def num_particles(self) -> int:
        return self.particles

    def markers_of(self, particle) -> Array:
        return self.latent_model.markers_of(particle)

    def estimate_markers(self, particles, log_weights) -> Array:
        # the paper's estimate: μ of the weighted mean latent (placement: weighted mean too)
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
    sharpness: float = DEFAULT_NCC_SHARPNESS,
    nearest: bool = True,
    dtype=jnp.float32,
) -> LatentTracker:
    """Initialise the latent tracker on a frame whose markers are known (ground truth, or an
    automatic initialisation).

    Args:
        prior: a trained GPLVM with its dynamics ν (``fit_gplvm(..., sequence_ids=...)``).
        template: the SPM template its training poses were expressed in.
        first_frame: ``(height, width)`` grey frame 0.
        first_markers: ``(12, 2)`` its markers (``SPM_MARKERS`` order): they give the NCC
            templates, the placement and, through μ⁻¹, the initial latent point.
        fps: the video's frame rate; ν (learned at ``prior.dynamics_fps``) is rescaled by
            ``sqrt(prior fps / fps)``, a random walk's step over a longer or shorter frame.
        placement_std: per-frame random-walk std of (log scale, x px, y px); default
            (0.01, 1 % of the torso, 1 % of the torso).
        sharpness: λ of the NCC likelihood.
        nearest: nearest-pixel patches (fast) rather than bilinear ones.
    """
    first_markers = np.asarray(first_markers, np.float64)
    if first_markers.shape != (12, 2) or not np.all(np.isfinite(first_markers)):
        raise ValueError(f"first_markers must be 12 finite (x, y) markers, got shape "
                         f"{first_markers.shape}")
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
        templates=make_templates(cast(first_frame), cast(first_markers)),
        initial_latent=cast(latent), initial_placement=cast(state[:PLACEMENT_SIZE]),
        latent_std=cast(std), placement_std=cast(placement_std),
        initial_spread=cast(initial_spread), sharpness=cast(sharpness), nearest=bool(nearest),
    )
    return LatentTracker(latent_model=model, particles=int(num_particles))
