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

With several calibrated views and a detector's keypoints,
:mod:`jaxtrack.trackers.linear_combination_views` places the same skeleton in the world and
scores every view's detections by the detection density.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, Bool, Float, Int, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body.hybrid import split_hybrid
from jaxtrack.likelihoods.contour_normals import ContourObservation, FitnessSettings, log_fitness
from jaxtrack.priors.linear_combinations import LinearCombinationModel
from jaxtrack.trackers import _runner
from jaxtrack.trackers._options import RESAMPLERS, Engine, options_record
from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk

__all__ = ["OBSERVATION_REASONS", "ContourFrames", "LinearCombinationEstimate",
           "LinearCombinationSSM", "LinearCombinationState", "LinearCombinationTrack",
           "LinearCombinationTracker", "initial_particle", "linear_combination_tracker",
           "nearest_neighbour", "propagate_particle", "propagate_shape", "reason_codes",
           "release_compiled", "track_observations"]

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
