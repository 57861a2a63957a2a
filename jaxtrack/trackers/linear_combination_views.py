"""Ong & Gong's (2002) linear-combination model tracked over several calibrated views, each
view's detections scored by the normalised detection density.

Ong & Gong's skeleton is the 3-D part of the hybrid vector, neck-relative in the frame of the
camera it was seen by. With calibrated views the particle also carries where that skeleton
stands in the world: x = T + c·R_up(θ)·Rᵀ s(a), s(a) the skeleton of the coefficients a
(eq. 7), R the reference camera's world → camera rotation, R_up(θ) a turn by θ about the
world's up axis, c the person's size against the model's, T the neck in the world. Each view
v projects x (OpenCV's model) and its detections are scored by the normalised detection
density (jaxtrack.likelihoods.detections); the views are independent given x, so the frame's
log-likelihood is the sum of the views' (papers/ong2002/README.md, section 4).

:class:`ViewsTracker` (:func:`linear_combination_views_tracker`) keeps the tracker contract of
:mod:`jaxtrack.trackers._tracker`; its particles propagate as the single-view tracker's
(:func:`jaxtrack.trackers.linear_combination.propagate_shape`, eq. 4–6).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, Float, Int, PRNGKeyArray

from jaxtrack import smc
from jaxtrack.body.camera import Camera, project
from jaxtrack.likelihoods.detections import DetectionModel, DetectionsFrame, log_density
from jaxtrack.priors.linear_combinations import LinearCombinationModel
from jaxtrack.trackers._options import RESAMPLERS, Engine, options_record
from jaxtrack.trackers._tracker import FrameEstimate, Tracker, VideoChunk, frame_at
from jaxtrack.trackers.linear_combination import initial_particle, propagate_shape

__all__ = ["ViewsAnchor", "ViewsEstimate", "ViewsSSM", "ViewsState", "ViewsTracker",
           "linear_combination_views_tracker", "stack_views", "world_skeleton"]


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
    """The world skeleton of one particle: x = T + c·R_up(θ)·Rᵀ s(a) (module docstring), from
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
    view's detections (module docstring).

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
        observation = frame_at(frame)
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
