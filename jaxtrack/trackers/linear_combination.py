"""Ong & Gong's (2002) linear-combination tracker: CONDENSATION over cluster-constrained
coefficients of a hybrid vector, with cluster jumps.

A particle is ``{"cluster": int32, "coefficients": (components,)}``: the cluster a it lies in and
its global coefficients s (eq. 2). Each CONDENSATION cycle propagates it (eq. 4–6):

    b ~ U[a, :]                                    the next cluster, row a of the transition matrix
    s′ = s + P_b Λ_b Ω       if b = a              a step inside the cluster
    s′ = μ_b + P_b Λ_b Ω     if b ≠ a              a jump to the new cluster's mean
    r = clip(P_bᵀ(s′ − μ_b)/Λ_b, −1, 1);  s′ = μ_b + P_b Λ_b r     (eq. 5, 6)

with Ω ~ N(0, ω² I) (ω: ``step`` inside a cluster, ``jump_spread`` after a jump, fractions of
the cluster's ±1 box), and weights it by the fitness of its reconstruction (eq. 7) to the frame
(eq. 8–9, :mod:`jaxtrack.likelihoods.contour_normals`). ``iterations`` cycles run on every frame
(Ong & Gong: 5). The estimate is the best-fitness particle (the paper's) and the weighted mean;
the 3-D skeleton of each is read off its reconstruction.

``constrained=False`` gives the first baseline of ``docs/linear-combination.md``: the same filter
in the global coefficient space without clusters, a Brownian step of ``step`` training standard
deviations per coefficient and no clamp. The tracker follows the contract of
:mod:`jaxtrack.trackers._tracker`: it observes colour frames against the static scene
(:meth:`LinearCombinationTracker.observe`, :func:`observe_contours`) into
:class:`ContourObservation` pytrees, and :func:`jaxtrack.trackers.track` runs it like every other
tracker (:func:`track_observations` keeps every field of its estimate); its five cycles per frame
are the engine's (``Engine(iterations_per_frame=5)``).

With several calibrated views and a detector's keypoints, :class:`ViewsTracker`
(:func:`linear_combination_views_tracker`) places the same skeleton in the world and scores
every view's detections by the detection density (the comment above :func:`stack_views`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, Bool, Float, Int, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body.camera import Camera, project
from jaxtrack.body.hybrid import split_hybrid
from jaxtrack.likelihoods.contour_normals import ContourObservation, FitnessSettings, log_fitness
from jaxtrack.likelihoods.detections import DetectionModel, DetectionsFrame, log_density
from jaxtrack.priors.linear_combinations import LinearCombinationModel
from jaxtrack.trackers import _runner
from jaxtrack.trackers._options import RESAMPLERS, Engine, options_record
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk

__all__ = ["OBSERVATION_REASONS", "ContourFrames", "LinearCombinationEstimate",
           "LinearCombinationSSM", "LinearCombinationState", "LinearCombinationTrack",
           "LinearCombinationTracker", "ViewsEstimate", "ViewsSSM", "ViewsState",
           "ViewsTracker", "initial_particle", "linear_combination_tracker",
           "linear_combination_views_tracker", "nearest_neighbour", "propagate_particle",
           "propagate_shape", "reason_codes", "release_compiled", "stack_views",
           "track_observations", "world_skeleton"]

OBSERVATION_REASONS = (
    "",
    "no silhouette (nothing differs from the background)",
    "no silhouette (the mask is empty)",
    "no skin blobs: too few skin pixels for a head and two hands",
    "no skin blobs: the skin pixels form fewer than three blobs",
    "not observed",
)
"""Why a frame was not observed, by the code :class:`ContourFrames` carries (0: observed)."""


def propagate_particle(model: LinearCombinationModel, key: PRNGKeyArray,
                       cluster: Int[Array, ""], coefficients: Float[Array, " components"],
                       step: Float[Array, ""], jump_spread: Float[Array, ""]
                       ) -> tuple[Int[Array, ""], Float[Array, " components"]]:
    """One particle through Ong & Gong eq. 4–6 (module docstring); pure, vmap it.

    Returns:
        The new cluster b and the new coefficients, inside cluster b's ±1 box.
    """
    key_cluster, key_noise = jr.split(key)
    # Ong & Gong eq. (4): the next cluster from row a of U
    new_cluster = jr.categorical(key_cluster, jnp.log(model.transition[cluster]))
    omega = jr.normal(key_noise, model.local_extents.shape[1:], coefficients.dtype)
    same = new_cluster == cluster
    spread = jnp.where(same, step, jump_spread)
    offset = model.local_bases[new_cluster] @ (model.local_extents[new_cluster] * spread * omega)
    start = jnp.where(same, coefficients, model.cluster_means[new_cluster])
    # Ong & Gong eq. (5)-(6): clamp in cluster b's eigen-coordinates and reconstruct
    return new_cluster.astype(jnp.int32), model.constrain(start + offset, new_cluster)


def initial_particle(model: LinearCombinationModel, key: PRNGKeyArray, constrained: bool
                     ) -> dict:
    """A particle ``{"cluster", "coefficients"}`` drawn from the model: a cluster by its share
    of the training frames and a point of its ±1 box (constrained), or a random training
    vector's coefficients (the global-PCA baseline)."""
    key_cluster, key_box, key_example = jr.split(key, 3)
    if not constrained:
        example = jr.randint(key_example, (), 0, model.training_coefficients.shape[0])
        return {"cluster": jnp.asarray(0, jnp.int32),
                "coefficients": model.training_coefficients[example]}
    cluster = jr.categorical(key_cluster, jnp.log(model.cluster_prior)).astype(jnp.int32)
    box = jr.uniform(key_box, model.local_extents.shape[1:], model.mean.dtype, -1.0, 1.0)
    coefficients = model.cluster_means[cluster] + model.local_bases[cluster] @ (
        model.local_extents[cluster] * box)
    return {"cluster": cluster, "coefficients": coefficients}


def propagate_shape(model: LinearCombinationModel, key: PRNGKeyArray, particle: dict,
                    step: Float[Array, ""], jump_spread: Float[Array, ""], constrained: bool
                    ) -> dict:
    """``particle``'s ``cluster`` and ``coefficients`` one cycle on: eq. 4–6
    (:func:`propagate_particle`), or (``constrained=False``) Brownian motion of ``step``
    training standard deviations per coefficient; its other entries are kept."""
    if not constrained:
        scale = jax.lax.rsqrt(model.eigenvalues)  # std of a_j over the training set
        noise = jr.normal(key, particle["coefficients"].shape, particle["coefficients"].dtype)
        return {**particle, "coefficients": particle["coefficients"] + step * scale * noise}
    cluster, coefficients = propagate_particle(model, key, particle["cluster"],
                                               particle["coefficients"], step, jump_spread)
    return {**particle, "cluster": cluster, "coefficients": coefficients}


class LinearCombinationSSM(smc.StateSpaceModel):
    """The state-space model the engine runs (one particle: ``{"cluster", "coefficients"}``).

    Attributes:
        model: the trained model in the tracker's float type.
        fitness: eq. 9's settings.
        step: ω inside a cluster (constrained) or in training standard deviations (global).
        jump_spread: ω after a cluster jump.
        constrained: clusters, jumps and clamps (the paper); False: the global-PCA baseline.
    """

    model: LinearCombinationModel
    fitness: FitnessSettings
    step: Float[Array, ""]
    jump_spread: Float[Array, ""]
    constrained: bool = eqx.field(static=True, default=True)

    def init(self, key: PRNGKeyArray) -> dict:
        return initial_particle(self.model, key, self.constrained)

    def propagate(self, key: PRNGKeyArray, particle: dict, time) -> dict:
        return propagate_shape(self.model, key, particle, self.step, self.jump_spread,
                               self.constrained)

    def log_likelihood(self, particle: dict, observation: ContourObservation
                       ) -> Float[Array, ""]:
        # Ong & Gong eq. (7): the hybrid vector of the particle, then its fitness (eq. 8-9)
        parts = split_hybrid(self.model.reconstruct(particle["coefficients"]), self.model.layout)
        return log_fitness(parts.contour, parts.hands, observation, self.fitness)


class ContourFrames(ContourObservation):
    """:class:`ContourObservation` with, per frame, why it was not observed: ``reason``, an
    index into :data:`OBSERVATION_REASONS` (0 where observed); what
    :meth:`LinearCombinationTracker.observe` gives, so that a pipeline reports it per frame."""

    reason: Int[Array, ""]


def reason_codes(status: list[str]) -> np.ndarray:
    """``(time,)`` int32 codes (:data:`OBSERVATION_REASONS`) of :func:`observe_contours`'
    per-frame status texts."""
    codes = np.zeros(len(status), np.int32)
    for t, text in enumerate(status):
        if not text:
            continue
        if text.startswith("no silhouette"):
            codes[t] = 2 if "mask" in text else 1
        else:
            codes[t] = 4 if "blobs" in text.split(":", 1)[-1] else 3
    return codes


class LinearCombinationEstimate(FrameEstimate):
    """:class:`FrameEstimate` with what this tracker recovers.

    ``markers`` / ``best_markers`` are the head and the two hands in the image, ``(3, 2)``.

    Attributes:
        skeleton_3d, best_skeleton_3d: ``(joints, 3)`` the skeleton of the weighted mean and of
            the best-fitness particle (the paper's estimate).
        contour: ``(contour, 2)`` the best particle's contour in the image.
        cluster: the best particle's cluster.
        log_fitness: log f (eq. 9) of the best particle (view selection weighs views by it).
        skeleton_spread: how far the particles' 3-D skeletons lie from their weighted mean:
            √(Σ_i w_i mean_k |s_ik − s̄_k|²) over particles i and skeleton vertices k, in the
            skeleton's units (metres). Small where the view leaves one skeleton; large where
            its silhouette keeps several apart (the filter's own ambiguity of the frame).
        found: the frame had a silhouette and three skin blobs (else it was scored flat and the
            filter only predicted).
        reason: why the frame was not observed, an index into :data:`OBSERVATION_REASONS` (0:
            observed).
    """

    skeleton_3d: Float[Array, "joints 3"]
    best_skeleton_3d: Float[Array, "joints 3"]
    contour: Float[Array, "contour 2"]
    cluster: Int[Array, ""]
    log_fitness: Float[Array, ""]
    skeleton_spread: Float[Array, ""]
    found: Bool[Array, ""]
    reason: Int[Array, ""]


class LinearCombinationState(eqx.Module):
    """What the tracker carries: the filter's state, the last frame's head, status and why it
    was not observed (which place its estimate in the image) and the best particle's
    log-fitness there."""

    filter: smc.FilterState
    info: smc.StepInfo
    head: Float[Array, " 2"]
    found: Bool[Array, ""]
    log_fitness: Float[Array, ""]
    reason: Int[Array, ""]


def _skeleton_spread(model: LinearCombinationModel, coefficients, log_weights, mean_skeleton):
    """:attr:`LinearCombinationEstimate.skeleton_spread` of the particles' ``coefficients``."""
    layout = model.layout
    skeletons = jax.vmap(model.reconstruct)(coefficients)[:, layout.skeleton_slice]
    skeletons = skeletons.reshape(len(coefficients), layout.num_skeleton, 3)
    squared = jnp.sum((skeletons - mean_skeleton) ** 2, axis=-1).mean(axis=-1)
    return jnp.sqrt(jnp.maximum(jax.nn.softmax(log_weights) @ squared, 0.0))


def _observation_at(frame) -> ContourObservation:
    if isinstance(frame, FrameInChunk):
        return jax.tree.map(lambda leaf: leaf[frame.index], frame.frames)
    return frame


def observe_contours(images: np.ndarray, background: np.ndarray | None, *, skin_reference=None,
            threshold: int = 30, sigma: float = 1.0, masks: np.ndarray | None = None
            ) -> tuple[ContourObservation, list[str]]:
    """Frames as the linear-combination tracker observes them (Ong & Gong §5.2).

    Per frame: background subtraction and the largest connected component (the silhouette),
    skin blobs inside it (head = top), and the gradient-magnitude map.

    Args:
        images: ``(time, height, width, 3)`` uint8 RGB.
        background: ``(height, width, 3)`` uint8 RGB empty scene (unused with ``masks``).
        masks: ``(time, height, width)`` bool person masks (a segmenter's,
            :mod:`jaxtrack.vision.masks`) to take the silhouette from instead of background
            subtraction; their largest connected component is the silhouette.
        skin_reference: an RGB sample of the person's skin (None: the fixed chroma box).
        threshold: grey levels of the background subtraction.
        sigma: smoothing of the gradient map.

    Returns:
        ``(observations, status)``: a :class:`ContourObservation` of numpy arrays with a
        leading time axis, and per frame an empty string or why it was not observed (no
        silhouette, too little skin); such frames have ``found`` False.
    """
    from jaxtrack.vision.foreground import foreground_mask, largest_component
    from jaxtrack.vision.normals import gradient_magnitude
    from jaxtrack.vision.skin import skin_blobs, skin_mask

    images = np.asarray(images)
    if images.ndim != 4 or images.shape[-1] != 3 or images.dtype != np.uint8:
        raise ValueError(f"images must be (time, height, width, 3) uint8 RGB, got shape "
                         f"{images.shape} dtype {images.dtype}")
    count, height, width = images.shape[:3]
    if masks is None and background is None:
        raise ValueError("observe needs a background or masks")
    if masks is not None and np.shape(masks) != images.shape[:3]:
        raise ValueError(f"masks must be (time, height, width) = {images.shape[:3]}, got "
                         f"{np.shape(masks)}")
    gradient = np.empty((count, height, width), np.float32)
    head = np.zeros((count, 2))
    hands = np.zeros((count, 2, 2))
    found = np.zeros(count, bool)
    status = []
    for t, image in enumerate(images):
        gradient[t] = gradient_magnitude(image, sigma=sigma)
        person = (foreground_mask(image, background, threshold=threshold) if masks is None
                  else np.asarray(masks[t], bool))
        silhouette = largest_component(person)
        if not silhouette.any():
            status.append("no silhouette (nothing differs from the background)" if masks is None
                          else "no silhouette (the mask is empty)")
            continue
        blobs = skin_blobs(skin_mask(image, silhouette, reference=skin_reference))
        if not blobs.found:
            status.append(f"no skin blobs: {blobs.reason}")
            continue
        head[t], hands[t], found[t] = blobs.head, blobs.hands, True
        status.append("")
    return ContourObservation(gradient, head, hands, found), status


class LinearCombinationTracker(Tracker):
    """Ong & Gong's tracker (module docstring).

    Attributes:
        model: the trained :class:`LinearCombinationModel` (in the tracker's float type).
        likelihood: eq. 9's :class:`FitnessSettings`.
        engine: N, resampler, ESS threshold (Ong & Gong: resample every cycle) and the
            CONDENSATION cycles per frame, ``iterations_per_frame`` (Ong & Gong: 5).
        step, jump_spread: ω inside a cluster and after a jump.
        constrained: the paper's clusters; False: the global-PCA Brownian baseline.
        skin_reference: an RGB sample of the person's skin for observing frames (None: the
            fixed chroma box; :func:`observe_contours`).
        background_threshold: grey levels of the background subtraction (:meth:`observe`).
    """

    model: LinearCombinationModel
    likelihood: FitnessSettings
    engine: Engine
    step: Float[Array, ""]
    jump_spread: Float[Array, ""]
    constrained: bool = eqx.field(static=True, default=True)
    skin_reference: np.ndarray | None = None
    background_threshold: int = eqx.field(static=True, default=30)

    @property
    def iterations(self) -> int:
        """CONDENSATION cycles per frame: the engine's ``iterations_per_frame``."""
        return self.engine.iterations_per_frame

    @property
    def num_particles(self) -> int:
        return self.engine.num_particles

    @property
    def reads(self) -> tuple[str, ...]:
        return ("colour", "background")  # or the person's masks in the background's place

    def observe(self, chunk: VideoChunk, out=None) -> ContourFrames:
        """The chunk's observations (:func:`observe_contours`) from its colour frames and the
        static scene's background, or the person's masks in its place, in the model's float
        type, with each frame's reason code (:class:`ContourFrames`)."""
        if chunk.colour is None:
            raise ValueError("the linear-combination tracker reads colour frames: give "
                             "colour=... (time, height, width, 3) uint8 RGB")
        if chunk.background is None and chunk.masks is None:
            raise ValueError("the linear-combination tracker finds the silhouette against the "
                             "static scene: give background=... or the person's masks=...")
        observations, status = observe_contours(
            chunk.colour, chunk.background, skin_reference=self.skin_reference,
            threshold=self.background_threshold, masks=chunk.masks)
        dtype = self.model.mean.dtype
        return ContourFrames(np.asarray(observations.gradient, dtype),
                             np.asarray(observations.head, dtype),
                             np.asarray(observations.hands, dtype),
                             np.asarray(observations.found, bool), reason_codes(status))

    @property
    def observation_reasons(self) -> tuple[str, ...]:
        """What each reason code of :meth:`observe`'s frames means
        (:data:`OBSERVATION_REASONS`)."""
        return OBSERVATION_REASONS

    def options(self) -> dict:
        return {"method": "linear-combination" if self.constrained else "global-pca",
                "particles": self.num_particles, "engine": options_record(self.engine),
                "likelihood": self.likelihood.record(), "iterations": self.iterations,
                "step": float(self.step), "jump_spread": float(self.jump_spread),
                "clusters": self.model.num_clusters, "components": self.model.num_components}

    def _ssm(self) -> LinearCombinationSSM:
        return LinearCombinationSSM(self.model, self.likelihood, self.step, self.jump_spread,
                                    self.constrained)

    def _cycles(self, key, filtered, observation, iterations):
        """``iterations`` of the engine's cycles on one frame."""
        return smc.step(key, filtered, observation, self._ssm(),
                        resampler=RESAMPLERS[self.engine.resampler](),
                        ess_threshold=self.engine.ess_threshold,
                        iterations_per_frame=iterations)

    def start(self, key: PRNGKeyArray, first_frame: ContourObservation, initial_pose=None
              ) -> LinearCombinationState:
        """Particles drawn from the clusters (Ong & Gong start from the model, not from a
        given pose: ``initial_pose`` is not used), then ``iterations`` cycles on frame 0."""
        if not isinstance(first_frame, ContourObservation):
            raise TypeError(f"first_frame must be a ContourObservation (jaxtrack.experiments."
                            f"linear_combination.observe), got {type(first_frame).__name__}")
        return _start(self, key, first_frame)

    def _estimate(self, state: LinearCombinationState) -> LinearCombinationEstimate:
        model, filtered, info = self.model, state.filter, state.info
        particles, log_weights = filtered.particles, filtered.log_weights
        best = smc.best_particle(particles, log_weights)
        mean = smc.weighted_mean(particles, log_weights)
        # no head seen: the skeleton is still reported, its image positions are not known
        head = jnp.where(state.found, state.head.astype(log_weights.dtype), jnp.nan)
        best_parts = split_hybrid(model.reconstruct(best["coefficients"]), model.layout, head)
        mean_parts = split_hybrid(model.reconstruct(mean["coefficients"]), model.layout, head)
        return LinearCombinationEstimate(
            markers=jnp.concatenate([head[None], mean_parts.hands]),
            best_markers=jnp.concatenate([head[None], best_parts.hands]),
            ess=info.ess, log_likelihood=info.log_evidence_increment,
            degenerate=info.degenerate, skeleton_3d=mean_parts.skeleton_3d,
            best_skeleton_3d=best_parts.skeleton_3d, contour=best_parts.contour,
            cluster=best["cluster"], log_fitness=state.log_fitness,
            skeleton_spread=_skeleton_spread(model, particles["coefficients"], log_weights,
                                             mean_parts.skeleton_3d),
            found=state.found, reason=state.reason)

    def first_estimate(self, state: LinearCombinationState) -> LinearCombinationEstimate:
        return self._estimate(state)

    def update(self, key: PRNGKeyArray, state: LinearCombinationState, frame
               ) -> tuple[LinearCombinationState, LinearCombinationEstimate]:
        observation = _observation_at(frame)
        filtered, info = self.engine.step(key, state.filter, observation, self._ssm())
        state = self._state(filtered, info, observation)
        return state, self._estimate(state)

    def _state(self, filtered: smc.FilterState, info: smc.StepInfo,
               observation: ContourObservation) -> LinearCombinationState:
        best = smc.best_particle(filtered.particles, filtered.log_weights)
        # observations made without reasons (a plain ContourObservation): "not observed"
        reason = getattr(observation, "reason", None)
        if reason is None:
            reason = jnp.where(observation.found, 0, len(OBSERVATION_REASONS) - 1)
        return LinearCombinationState(filtered, info, observation.head, observation.found,
                                      self._ssm().log_likelihood(best, observation),
                                      jnp.asarray(reason, jnp.int32))


@eqx.filter_jit
def _start(tracker: LinearCombinationTracker, key: PRNGKeyArray,
           observation: ContourObservation) -> LinearCombinationState:
    key_init, key_cycles = jr.split(key)
    filtered, info = smc.initialize(key_init, tracker._ssm(), observation,
                                    tracker.num_particles)
    if tracker.iterations > 1:
        filtered, info = tracker._cycles(key_cycles, filtered, observation,
                                         tracker.iterations - 1)
        filtered = eqx.tree_at(lambda f: f.time, filtered, jnp.zeros_like(filtered.time))
    return tracker._state(filtered, info, observation)


def release_compiled() -> None:
    """Forget the executables :func:`jaxtrack.trackers.track` compiled ahead of time
    (:func:`jaxtrack.trackers._runner.release_compiled`)."""
    _runner.release_compiled()


class LinearCombinationTrack(eqx.Module):
    """A tracked sequence: every field of :class:`LinearCombinationEstimate` with a leading
    ``time`` axis (``estimates``), and timings.

    Attributes:
        estimates: per-frame estimates, frame 0 included.
        seconds_per_frame: run time per frame after frame 0, compilation excluded.
        compile_seconds: time to compile everything the run executes: frame 0's start and
            estimate and the scan over the other frames (0 for what a compiled one was reused).
        options: the tracker's ``options()``.
    """

    estimates: LinearCombinationEstimate
    seconds_per_frame: float = eqx.field(static=True)
    compile_seconds: float = eqx.field(static=True)
    options: dict = eqx.field(static=True)


def track_observations(tracker: LinearCombinationTracker, key: PRNGKeyArray,
                       observations: ContourObservation) -> LinearCombinationTrack:
    """Track a sequence of observations (every leaf with a leading ``time`` axis) with
    :func:`jaxtrack.trackers.track` (start on frame 0, then compiled chunks of ``update``),
    keeping every field of the tracker's estimate. Compilation is timed apart from the run
    (``compile_seconds``, ``seconds_per_frame``)."""
    if not isinstance(observations, ContourObservation):
        raise TypeError(f"observations must be a ContourObservation with a time axis, got "
                        f"{type(observations).__name__}")
    num_frames = observations.found.shape[0] if np.ndim(observations.found) == 1 else 0
    if num_frames < 1:
        raise ValueError("observations hold no frame (found must have a leading time axis)")
    dtype = tracker.model.mean.dtype
    leaves = (observations.gradient, observations.head, observations.hands, observations.found)
    dtypes = (dtype, dtype, dtype, bool)
    observations = ContourObservation(*(np.asarray(leaf, kind)
                                        for leaf, kind in zip(leaves, dtypes, strict=True)))
    result = _runner.track(tracker, key, observations, None, progress=False)
    return LinearCombinationTrack(result.estimates, result.seconds_per_frame,
                                  result.compile_seconds, result.options)


def linear_combination_tracker(
    model: LinearCombinationModel,
    *,
    engine: Engine = Engine(300),
    fitness: FitnessSettings = FitnessSettings(contour_tolerance=64.0, hands_tolerance=16.0),
    iterations: int = 5,
    step: float = 0.03,
    jump_spread: float = 0.3,
    constrained: bool = True,
    skin_reference=None,
    dtype=jnp.float32,
) -> LinearCombinationTracker:
    """Ong & Gong's tracker with a trained model (module docstring).

    Args:
        model: a trained :class:`LinearCombinationModel`.
        engine: N, resampler, ESS threshold (Ong & Gong: up to 300 samples).
        fitness: eq. 9's weights and tolerances (default P = 64, Q = 16 px², chosen on the
            validation subject, ``python -m papers.ong2002.evaluation``, docs/defaults.md).
        iterations: CONDENSATION cycles per frame (Ong & Gong: 5), the engine's
            ``iterations_per_frame`` (``engine``'s own is replaced).
        step: ω inside a cluster, a fraction of its ±1 box (with ``constrained=False``: the
            Brownian step in training standard deviations); default 0.03, chosen on the
            validation subject for both filters (the same run).
        jump_spread: ω after a jump to a new cluster's mean.
        constrained: False for the global-PCA Brownian baseline.
        skin_reference: an RGB sample of the person's skin for :meth:`observe` (None: the
            fixed chroma box).
        dtype: the filter's float type.
    """
    for name, value in (("step", step), ("jump_spread", jump_spread)):
        if np.shape(value) != () or not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    if not isinstance(iterations, int) or isinstance(iterations, bool) or iterations < 1:
        raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
    engine = Engine(engine.num_particles, engine.resampler, engine.ess_threshold,
                    iterations_per_frame=iterations)
    return LinearCombinationTracker(
        model=model.astype(dtype), likelihood=fitness, engine=engine,
        step=jnp.asarray(step, dtype), jump_spread=jnp.asarray(jump_spread, dtype),
        constrained=constrained, skin_reference=skin_reference)


@eqx.filter_jit
def _nearest(vectors, layout, observations, fitness):
    parts = split_hybrid(vectors, layout)

    def frame(observation):
        scores = jax.vmap(log_fitness, in_axes=(0, 0, None, None))(
            parts.contour, parts.hands, observation, fitness)
        return jnp.argmax(scores)

    return jax.lax.map(frame, observations)


def nearest_neighbour(vectors: Float[Array, "examples vector"], layout,
                      observations: ContourObservation,
                      fitness: FitnessSettings = FitnessSettings(contour_tolerance=64.0,
                                                                 hands_tolerance=16.0)
                      ) -> Int[Array, " time"]:
    """The second baseline: per frame, the training hybrid vector of greatest fitness (eq. 9),
    with no dynamics. Returns the index of the chosen vector per frame (its skeleton is the
    estimate; on a frame without observations every vector scores alike and the first wins)."""
    vectors = jnp.asarray(vectors)
    if vectors.ndim != 2 or vectors.shape[1] != layout.size:
        raise ValueError(f"vectors must be (examples, {layout.size}), got {vectors.shape}")
    observations = ContourObservation(
        jnp.asarray(observations.gradient, vectors.dtype),
        jnp.asarray(observations.head, vectors.dtype),
        jnp.asarray(observations.hands, vectors.dtype), jnp.asarray(observations.found, bool))
    return _nearest(vectors, layout, observations, fitness)


# ---- several calibrated views scored by a detector's keypoints -------------------------------
#
# Ong & Gong's skeleton is the 3-D part of the hybrid vector, neck-relative in the frame of the
# camera it was seen by. With calibrated views the particle also carries where that skeleton
# stands in the world: x = T + c·R_up(θ)·Rᵀ s(a), s(a) the skeleton of the coefficients a
# (eq. 7), R the reference camera's world → camera rotation, R_up(θ) a turn by θ about the
# world's up axis, c the person's size against the model's, T the neck in the world. Each view
# v projects x (OpenCV's model) and its detections are scored by the normalised detection
# density (jaxtrack.likelihoods.detections); the views are independent given x, so the frame's
# log-likelihood is the sum of the views' (papers/ong2002/README.md, section 4).


def stack_views(cameras) -> Camera:
    """Cameras of any image sizes as one :class:`Camera` with a leading ``views`` axis (the
    image sizes stay with each view's detections)."""
    cameras = list(cameras)
    if not cameras:
        raise ValueError("cameras: give at least one calibrated camera")
    fields = ("focal_length", "principal_point", "rotation", "translation", "distortion")
    return Camera(**{name: jnp.stack([jnp.asarray(getattr(camera, name), jnp.float32)
                                      for camera in cameras]) for name in fields},
                  image_size=cameras[0].image_size,
                  name=",".join(camera.name for camera in cameras))


def _turn(points: Float[Array, "joints 3"], up: Float[Array, " 3"], angle: Float[Array, ""]
          ) -> Float[Array, "joints 3"]:
    """``points`` turned by ``angle`` about the unit axis ``up`` (Rodrigues)."""
    cos, sin = jnp.cos(angle), jnp.sin(angle)
    return (points * cos + jnp.cross(up, points) * sin
            + (points @ up)[:, None] * up * (1 - cos))


def world_skeleton(model: LinearCombinationModel, reference_rotation: Float[Array, "3 3"],
                   up: Float[Array, " 3"], particle: dict) -> Float[Array, "joints 3"]:
    """The world skeleton of one particle: x = T + c·R_up(θ)·Rᵀ s(a) (comment above), from
    its ``coefficients`` a, ``yaw`` θ, ``scale`` c and ``translation`` T."""
    layout = model.layout
    skeleton = model.reconstruct(particle["coefficients"])[layout.skeleton_slice]
    # a camera-frame vector s is s @ R in the world's axes (R: world → camera)
    world = skeleton.reshape(layout.num_skeleton, 3) @ reference_rotation
    return particle["translation"] + particle["scale"] * _turn(world, up, particle["yaw"])


class ViewsAnchor(eqx.Module):
    """Where the first frame's detections place the person: ``skeleton`` ``(joints, 3)``
    world points (triangulated), neck-relative, ``weights`` ``(joints,)`` (0 where not
    triangulated) and ``neck`` ``(3,)``; particles start turned and sized to fit it."""

    skeleton: Float[Array, "joints 3"]
    weights: Float[Array, " joints"]
    neck: Float[Array, " 3"]


class ViewsSSM(smc.StateSpaceModel):
    """The state-space model of :class:`ViewsTracker` (one particle: ``{"cluster",
    "coefficients", "yaw", "scale", "translation"}``).

    Attributes:
        model: the trained model in the tracker's float type.
        detection: the detection density's parameters.
        cameras: the views' cameras, stacked (:func:`stack_views`).
        reference_rotation: ``(3, 3)`` the world → camera rotation of the frame the model's
            skeletons are expressed in.
        up: ``(3,)`` the world's unit up axis, about which the skeleton turns.
        step, jump_spread: ω inside a cluster and after a jump (eq. 4–6).
        translation_step: the neck's random walk per cycle, metres.
        yaw_step: the turn's random walk per cycle, radians.
        scale_step: the size's log random walk per cycle.
        anchor: the first frame's triangulated skeleton (used by :meth:`init` only).
        constrained: clusters, jumps and clamps; False: the global-PCA Brownian baseline.
    """

    model: LinearCombinationModel
    detection: DetectionModel
    cameras: Camera
    reference_rotation: Float[Array, "3 3"]
    up: Float[Array, " 3"]
    step: Float[Array, ""]
    jump_spread: Float[Array, ""]
    translation_step: Float[Array, ""]
    yaw_step: Float[Array, ""]
    scale_step: Float[Array, ""]
    anchor: ViewsAnchor
    constrained: bool = eqx.field(static=True, default=True)

    def init(self, key: PRNGKeyArray) -> dict:
        """A shape from the model (:func:`initial_particle`), turned about the up axis to fit
        the anchor or, for half the particles, its mirror, and sized to fit its midline
        (weighted least squares), then spread by 0.3 rad, 10 % and 5 cm so that the first
        frame's cycles can correct the fit."""
        key_shape, key_yaw, key_scale, key_translation, key_side = jr.split(key, 5)
        particle = initial_particle(self.model, key_shape, self.constrained)
        dtype = particle["coefficients"].dtype
        shape = world_skeleton(self.model, self.reference_rotation, self.up,
                               {**particle, "yaw": jnp.zeros((), dtype),
                                "scale": jnp.ones((), dtype),
                                "translation": jnp.zeros(3, dtype)})
        # half the particles fit the anchor with its left and right exchanged: a view whose
        # detector swapped them pulls the triangulation, and the density may explain either
        mirrored = jr.bernoulli(key_side)
        order = jnp.where(mirrored, jnp.asarray(self.detection.swap),
                          jnp.arange(len(self.detection.swap)))
        target, weights = self.anchor.skeleton[order], self.anchor.weights[order]
        flat = lambda points: points - (points @ self.up)[:, None] * self.up  # noqa: E731
        source, aim = flat(shape), flat(target)
        # the turn about up that best lays the shape's horizontal part on the anchor's
        sine = jnp.sum(weights * (jnp.cross(source, aim) @ self.up))
        cosine = jnp.sum(weights * jnp.sum(source * aim, -1))
        yaw = jnp.arctan2(sine, cosine)
        turned = _turn(shape, self.up, yaw)
        # the size from the midline (its own mirror), which a left/right swap leaves in place
        swap = jnp.asarray(self.detection.swap)
        weights = weights * (swap == jnp.arange(len(swap)))
        size = (jnp.sum(weights * jnp.sum(turned * target, -1))
                / jnp.maximum(jnp.sum(weights * jnp.sum(turned ** 2, -1)), 1e-12))
        size = jnp.where(jnp.sum(weights) > 0, jnp.clip(size, 0.5, 2.0), 1.0)
        return {**particle,
                "yaw": yaw + 0.3 * jr.normal(key_yaw, (), dtype),
                "scale": size * jnp.exp(0.1 * jr.normal(key_scale, (), dtype)),
                "translation": self.anchor.neck + 0.05 * jr.normal(key_translation, (3,),
                                                                   dtype)}

    def propagate(self, key: PRNGKeyArray, particle: dict, time) -> dict:
        key_shape, key_yaw, key_scale, key_translation = jr.split(key, 4)
        particle = propagate_shape(self.model, key_shape, particle, self.step,
                                   self.jump_spread, self.constrained)
        dtype = particle["coefficients"].dtype
        return {**particle,
                "yaw": particle["yaw"] + self.yaw_step * jr.normal(key_yaw, (), dtype),
                "scale": particle["scale"] * jnp.exp(
                    self.scale_step * jr.normal(key_scale, (), dtype)),
                "translation": particle["translation"] + self.translation_step * jr.normal(
                    key_translation, (3,), dtype)}

    def markers(self, particle: dict) -> Float[Array, "views joints 2"]:
        """The particle's skeleton projected into every view, pixels."""
        skeleton = world_skeleton(self.model, self.reference_rotation, self.up, particle)
        return jax.vmap(project, in_axes=(0, None))(self.cameras, skeleton)

    def log_likelihood(self, particle: dict, observation: DetectionsFrame) -> Float[Array, ""]:
        # the views' detections are independent given the 3-D skeleton: a product of densities
        densities = jax.vmap(self._view_log_density)(self.markers(particle), observation)
        return jnp.sum(densities)

    def _view_log_density(self, markers: Float[Array, "joints 2"], frame: DetectionsFrame
                          ) -> Float[Array, ""]:
        """One view's detection density, its spread sized by the detected person's torso
        (first person, where its neck and pelvis were found) instead of the hypothesis's: with
        the size free, σ ∝ the hypothesis's size would favour small skeletons (−2 log σ per
        keypoint), pulling a 3-D size away from what the views show."""
        neck, pelvis = self.detection.spine
        present = (frame.confidence[0, neck] > 0) & (frame.confidence[0, pelvis] > 0)
        detected = jnp.linalg.norm(frame.points[0, neck] - frame.points[0, pelvis])
        hypothesis = jnp.linalg.norm(markers[neck] - markers[pelvis])
        ratio = jnp.where(present & (detected > 0) & (hypothesis > 0),
                          detected / jnp.where(hypothesis > 0, hypothesis, 1.0), 1.0)
        params = eqx.tree_at(lambda model: model.joint_scales, self.detection,
                             self.detection.joint_scales * ratio)
        return log_density(markers, frame, params)


class ViewsEstimate(FrameEstimate):
    """:class:`FrameEstimate` of :class:`ViewsTracker`; ``markers`` / ``best_markers`` are
    ``(views, joints, 2)``, the skeletons below projected into each view.

    Attributes:
        skeleton_3d, best_skeleton_3d: ``(joints, 3)`` world points: the particles' weighted
            mean of their world skeletons, and the best particle's.
        cluster: the best particle's cluster.
        scale: the particles' weighted mean size against the model's.
        skeleton_spread: √(Σ_i w_i mean_k |x_ik − x̄_k|²), metres.
    """

    skeleton_3d: Float[Array, "joints 3"]
    best_skeleton_3d: Float[Array, "joints 3"]
    cluster: Int[Array, ""]
    scale: Float[Array, ""]
    skeleton_spread: Float[Array, ""]


class ViewsState(eqx.Module):
    """What :class:`ViewsTracker` carries: the filter's state, its last step's info and the
    anchor its particles were drawn about."""

    filter: smc.FilterState
    info: smc.StepInfo
    anchor: ViewsAnchor


class ViewsTracker(Tracker):
    """Ong & Gong's linear-combination tracker over several calibrated views, scored by each
    view's detections (the comment above :func:`stack_views`).

    Observations are :class:`DetectionsFrame` leaves with leading ``(time, views)`` axes, made
    beforehand (:func:`jaxtrack.experiments.linear_combination.views_detections`); the first
    pose is the first frame's triangulated ``(joints, 3)`` skeleton (NaN where a joint was not
    triangulated), which places, turns and sizes the particles drawn from the model.

    Attributes:
        model, likelihood: the trained model and the detection density's parameters.
        engine: N, resampler, ESS threshold and cycles per frame (Ong & Gong: 5).
        cameras: the views' cameras (:func:`stack_views`).
        reference_rotation, up: :class:`ViewsSSM`'s.
        step, jump_spread, translation_step, yaw_step, scale_step: the random walks.
        constrained: the paper's clusters; False: the global-PCA Brownian baseline.
    """

    model: LinearCombinationModel
    likelihood: DetectionModel
    engine: Engine
    cameras: Camera
    reference_rotation: Float[Array, "3 3"]
    up: Float[Array, " 3"]
    step: Float[Array, ""]
    jump_spread: Float[Array, ""]
    translation_step: Float[Array, ""]
    yaw_step: Float[Array, ""]
    scale_step: Float[Array, ""]
    constrained: bool = eqx.field(static=True, default=True)

    @property
    def num_particles(self) -> int:
        return self.engine.num_particles

    @property
    def num_views(self) -> int:
        return self.cameras.rotation.shape[0]

    @property
    def reads(self) -> tuple[str, ...]:
        return ()

    def observe(self, chunk: VideoChunk, out=None):
        raise ValueError("the linear-combination tracker over calibrated views reads every "
                         "view's detections, made beforehand: give a DetectionsFrame with "
                         "(time, views) axes (jaxtrack.experiments.linear_combination."
                         "views_detections)")

    def options(self) -> dict:
        scales = np.asarray(self.likelihood.joint_scales).round(4).tolist()
        return {"method": "linear-combination" if self.constrained else "global-pca",
                "evidence": "detections", "views": self.cameras.name.split(","),
                "particles": self.num_particles, "engine": options_record(self.engine),
                "iterations": self.engine.iterations_per_frame, "step": float(self.step),
                "jump_spread": float(self.jump_spread),
                "translation_step": float(self.translation_step),
                "yaw_step": float(self.yaw_step), "scale_step": float(self.scale_step),
                "up": np.asarray(self.up).tolist(),
                "detection": {"joint_scales": scales,
                              "pixel_noise": float(self.likelihood.pixel_noise),
                              "outlier_rate": float(self.likelihood.outlier_rate),
                              "swap_probability": float(self.likelihood.swap_probability),
                              "absent_probability": float(self.likelihood.absent_probability)},
                "clusters": self.model.num_clusters, "components": self.model.num_components}

    def _ssm(self, anchor: ViewsAnchor) -> ViewsSSM:
        return ViewsSSM(self.model, self.likelihood, self.cameras, self.reference_rotation,
                        self.up, self.step, self.jump_spread, self.translation_step,
                        self.yaw_step, self.scale_step, anchor, self.constrained)

    def _check_frame(self, frame) -> None:
        if not isinstance(frame, DetectionsFrame):
            raise TypeError(f"observations must be a DetectionsFrame with (time, views) axes "
                            f"(jaxtrack.experiments.linear_combination.views_detections), got "
                            f"{type(frame).__name__}")
        joints = self.model.layout.num_skeleton
        if np.shape(frame.points)[:1] != (self.num_views,) or \
                np.shape(frame.points)[2:] != (joints, 2):
            raise ValueError(f"a frame's detections must be (views = {self.num_views}, people, "
                             f"{joints}, 2), got {np.shape(frame.points)}")

    def start(self, key: PRNGKeyArray, first_frame: DetectionsFrame, initial_pose
              ) -> ViewsState:
        """Particles from the model placed on ``initial_pose``, the first frame's
        ``(joints, 3)`` triangulated world skeleton (NaN where missing; its neck must be
        there), then the engine's cycles on frame 0."""
        self._check_frame(first_frame)
        joints = self.model.layout.num_skeleton
        pose = np.asarray(initial_pose, np.float64) if initial_pose is not None else None
        if pose is None or pose.shape != (joints, 3):
            raise ValueError(f"initial_pose must be the first frame's ({joints}, 3) world "
                             f"skeleton (triangulated), got "
                             f"{None if pose is None else pose.shape}")
        found = np.all(np.isfinite(pose), -1)
        if not found[_NECK]:
            raise ValueError("initial_pose: the first frame's neck is not triangulated (seen "
                             "in fewer than two views); start on a frame where it is")
        dtype = self.model.mean.dtype
        relative = np.where(found[:, None], pose - pose[_NECK], 0.0)
        anchor = ViewsAnchor(jnp.asarray(relative, dtype), jnp.asarray(found, dtype),
                             jnp.asarray(pose[_NECK], dtype))
        return _start_views(self, key, first_frame, anchor)

    def _estimate(self, state: ViewsState) -> ViewsEstimate:
        filtered, info = state.filter, state.info
        ssm = self._ssm(state.anchor)
        skeletons = jax.vmap(lambda particle: world_skeleton(
            self.model, self.reference_rotation, self.up, particle))(filtered.particles)
        weights = jax.nn.softmax(filtered.log_weights)
        mean = jnp.einsum("p,pjc->jc", weights, skeletons)
        best = jnp.argmax(filtered.log_weights)
        spread = jnp.sqrt(jnp.maximum(
            weights @ jnp.sum((skeletons - mean) ** 2, -1).mean(-1), 0.0))
        view_points = lambda skeleton: jax.vmap(project, in_axes=(0, None))(  # noqa: E731
            ssm.cameras, skeleton)
        return ViewsEstimate(
            markers=view_points(mean), best_markers=view_points(skeletons[best]),
            ess=info.ess, log_likelihood=info.log_evidence_increment,
            degenerate=info.degenerate, skeleton_3d=mean, best_skeleton_3d=skeletons[best],
            cluster=filtered.particles["cluster"][best],
            scale=weights @ filtered.particles["scale"], skeleton_spread=spread)

    def first_estimate(self, state: ViewsState) -> ViewsEstimate:
        return self._estimate(state)

    def update(self, key: PRNGKeyArray, state: ViewsState, frame
               ) -> tuple[ViewsState, ViewsEstimate]:
        observation = _observation_at(frame)
        filtered, info = self.engine.step(key, state.filter, observation,
                                          self._ssm(state.anchor))
        state = ViewsState(filtered, info, state.anchor)
        return state, self._estimate(state)


_NECK = 1  # UPPER_BODY_12's neck, the skeleton's origin


@eqx.filter_jit
def _start_views(tracker: ViewsTracker, key: PRNGKeyArray, observation: DetectionsFrame,
                 anchor: ViewsAnchor) -> ViewsState:
    key_init, key_cycles = jr.split(key)
    ssm = tracker._ssm(anchor)
    filtered, info = smc.initialize(key_init, ssm, observation, tracker.num_particles)
    iterations = tracker.engine.iterations_per_frame
    if iterations > 1:
        filtered, info = smc.step(key_cycles, filtered, observation, ssm,
                                  resampler=RESAMPLERS[tracker.engine.resampler](),
                                  ess_threshold=tracker.engine.ess_threshold,
                                  iterations_per_frame=iterations - 1)
        filtered = eqx.tree_at(lambda f: f.time, filtered, jnp.zeros_like(filtered.time))
    return ViewsState(filtered, info, anchor)


def linear_combination_views_tracker(
    model: LinearCombinationModel,
    cameras,
    *,
    detection: DetectionModel | None = None,
    engine: Engine = Engine(300),
    iterations: int = 5,
    step: float = 0.03,
    jump_spread: float = 0.3,
    translation_step: float = 0.01,
    yaw_step: float = 0.03,
    scale_step: float = 0.005,
    up=(0.0, 0.0, 1.0),
    reference_view: int = 0,
    constrained: bool = True,
    dtype=jnp.float32,
) -> ViewsTracker:
    """Ong & Gong's tracker over calibrated ``cameras``, scored by their detections.

    Args:
        model: a trained :class:`LinearCombinationModel` (its skeleton ``UPPER_BODY_12``,
            neck-relative, in the frame of the cameras it was trained through).
        cameras: one :class:`jaxtrack.body.Camera` per view, in the detections' order.
        detection: the detection density (default :func:`jaxtrack.likelihoods.detections.
            detection_model`'s hand-set one for the 12 markers).
        engine: N, resampler and ESS threshold; ``iterations`` replaces its cycles per frame.
        step, jump_spread: ω inside a cluster and after a jump (the contour tracker's
            defaults).
        translation_step, yaw_step, scale_step: the random walks per cycle of the neck
            (metres), the turn about ``up`` (radians) and the log size; hand-set for a person
            filmed at 30-60 fps, not tuned on any test clip.
        up: the world's up axis (Qualisys and Pose2Sim calibrations: Z).
        reference_view: the camera whose frame the model's skeletons are taken in.
        constrained: False for the global-PCA Brownian baseline.
        dtype: the filter's float type.
    """
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.likelihoods.detections import detection_model

    cameras = list(cameras)
    if model.layout.num_skeleton != len(UPPER_BODY_12):
        raise ValueError(f"the model's skeleton has {model.layout.num_skeleton} vertices; the "
                         f"detections score the {len(UPPER_BODY_12)} of UPPER_BODY_12")
    if not isinstance(reference_view, int) or not 0 <= reference_view < len(cameras):
        raise ValueError(f"reference_view must index one of the {len(cameras)} cameras, got "
                         f"{reference_view!r}")
    for name, value in (("step", step), ("jump_spread", jump_spread),
                        ("translation_step", translation_step), ("yaw_step", yaw_step),
                        ("scale_step", scale_step)):
        if np.shape(value) != () or not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    if not isinstance(iterations, int) or isinstance(iterations, bool) or iterations < 1:
        raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
    up = np.asarray(up, np.float64)
    if up.shape != (3,) or not np.all(np.isfinite(up)) or np.linalg.norm(up) == 0:
        raise ValueError(f"up must be a non-zero 3-vector, got {up}")
    detection = detection_model(UPPER_BODY_12, dtype=dtype) if detection is None else detection
    engine = Engine(engine.num_particles, engine.resampler, engine.ess_threshold,
                    iterations_per_frame=iterations)
    array = lambda value: jnp.asarray(value, dtype)  # noqa: E731
    return ViewsTracker(
        model=model.astype(dtype), likelihood=detection, engine=engine,
        cameras=jax.tree.map(lambda leaf: leaf.astype(dtype), stack_views(cameras)),
        reference_rotation=array(cameras[reference_view].rotation),
        up=array(up / np.linalg.norm(up)), step=array(step), jump_spread=array(jump_spread),
        translation_step=array(translation_step), yaw_step=array(yaw_step),
        scale_step=array(scale_step), constrained=constrained)
