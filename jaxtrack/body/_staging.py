"""Putting a camera and a motion together for rendering: frontal, random and calibrated views.

Re-exported by `jaxtrack.body.render`.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from jaxtrack.body.camera import Camera, look_at
from jaxtrack.body.markers import HUMANEVA_15, marker_positions
from jaxtrack.body.motion import Motion
from jaxtrack.body.viewpoints import Viewpoint, frame_subject, sample_viewpoints

__all__ = ["fit_camera", "frontal_camera", "project_numpy", "random_camera", "scale_camera",
           "stage_for_cameras"]

_UP = np.array([0.0, 1.0, 0.0])


def project_numpy(camera: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`camera.project_with_depth` in NumPy float64: `(..., 3)` world points to pixels `(..., 2)`
    and depths `(...)`. The renderer projects once per render; NumPy avoids compiling for every
    new clip length."""
    rotation, translation = (np.asarray(a, np.float64) for a in (camera.rotation,
                                                                  camera.translation))
    k1, k2, p1, p2, k3 = np.asarray(camera.distortion, np.float64)
    camera_points = np.asarray(points, np.float64) @ rotation.T + translation
    depth = camera_points[..., 2]
    inverse = np.where(depth != 0, 1.0 / np.where(depth != 0, depth, 1.0), 1.0)
    x, y = camera_points[..., 0] * inverse, camera_points[..., 1] * inverse
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    x_distorted = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    y_distorted = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    focal, principal = (np.asarray(a, np.float64) for a in (camera.focal_length,
                                                             camera.principal_point))
    pixels = np.stack([focal[0] * x_distorted + principal[0],
                       focal[1] * y_distorted + principal[1]], axis=-1)
    return pixels, depth


def scale_camera(camera: Camera, factor: float) -> Camera:
    """The same camera with its image resampled by `factor` (intrinsics and size scaled; pixel
    centres stay at integers, so `c' = (c + 0.5) factor - 0.5`)."""
    if not factor > 0:
        raise ValueError(f"factor must be positive, got {factor}")
    width, height = camera.image_size
    return Camera(
        focal_length=jnp.asarray(camera.focal_length) * factor,
        principal_point=(jnp.asarray(camera.principal_point) + 0.5) * factor - 0.5,
        rotation=camera.rotation, translation=camera.translation, distortion=camera.distortion,
        image_size=(max(1, round(width * factor)), max(1, round(height * factor))),
        name=camera.name,
    )


def fit_camera(camera: Camera, image_size: tuple[int, int]) -> Camera:
    """`scale_camera` by the largest factor that fits the camera's image inside `image_size`
    (`(width, height)`); the aspect ratio is kept, e.g. a portrait 1088x1920 camera fitted into
    640x480 gives 272x480 frames."""
    width, height = camera.image_size
    return scale_camera(camera, min(image_size[0] / width, image_size[1] / height))


def _facing(joints: np.ndarray) -> np.ndarray:
    """The subject's mean facing direction, a horizontal unit vector, from `(time, 15, 3)`."""
    index = {name: i for i, name in enumerate(HUMANEVA_15)}
    across = sum(joints[:, index[f"left_{j}"]] - joints[:, index[f"right_{j}"]]
                 for j in ("hip", "shoulder"))
    # forward = left x up in a right-handed Y-up world (facing +z puts the left on +x)
    forward = np.cross(across, _UP).mean(axis=0)
    forward[1] = 0.0
    norm = np.linalg.norm(forward)
    if norm < 1e-9:
        raise ValueError("cannot tell which way the subject faces (hips and shoulders coincide)")
    return forward / norm


def _distance(joints: np.ndarray, distance: float) -> float:
    centre = 0.5 * (joints.min(axis=(0, 1)) + joints.max(axis=(0, 1)))
    radius = float(np.max(np.linalg.norm(joints - centre, axis=-1)))
    return max(float(distance), radius + 1.0)  # the camera must stay outside the motion


def frontal_camera(motion: Motion, image_size: tuple[int, int] = (640, 480), *,
                   distance: float = 4.0, elevation: float = 0.0, azimuth: float = 0.0,
                   margin: float = 0.1) -> Camera:
    """A camera in front of the subject (its mean facing direction from hips and shoulders),
    framing the whole motion; the subject's left appears on the image's right.

    Args:
        azimuth: radians turned about the vertical from straight in front (positive moves the
            camera toward the subject's left).
        distance: metres from the motion's centre (raised to clear the motion's extent).
        elevation: radians above the horizontal.
        margin: empty border as a fraction of the image, see `frame_subject`.
    """
    joints = marker_positions(motion, HUMANEVA_15)
    forward = _facing(joints)
    # turn about +y: the subject's left is up × forward
    forward = np.cos(azimuth) * forward + np.sin(azimuth) * np.cross(_UP, forward)
    centre = 0.5 * (joints.min(axis=(0, 1)) + joints.max(axis=(0, 1)))
    direction = np.cos(elevation) * forward + np.sin(elevation) * _UP
    eye = centre + _distance(joints, distance) * direction
    camera = look_at(eye, centre, _UP, 1.0, image_size, name="frontal")
    return frame_subject(joints, camera, tuple(image_size), margin)


def random_camera(seed: int, motion: Motion, image_size: tuple[int, int] = (640, 480), *,
                  distance: float | tuple[float, float] = (3.5, 6.0),
                  elevation_range: tuple[float, float] = (-0.1, 0.4),
                  margin: float = 0.1) -> Camera:
    """A viewpoint drawn from the view sphere (`sample_viewpoints`) framing the whole motion."""
    joints = marker_positions(motion, HUMANEVA_15)
    viewpoint = sample_viewpoints(jr.PRNGKey(seed), 1, elevation_range=elevation_range,
                                  distance=distance)
    viewpoint = jax.tree.map(lambda leaf: leaf[0], viewpoint)
    viewpoint = Viewpoint(viewpoint.azimuth, viewpoint.elevation,
                          jnp.asarray(_distance(joints, float(viewpoint.distance))))
    camera = frame_subject(joints, viewpoint, tuple(image_size), margin)
    return Camera(camera.focal_length, camera.principal_point, camera.rotation,
                  camera.translation, camera.distortion, camera.image_size, name=f"random{seed}")


def stage_for_cameras(motion: Motion, cameras: Sequence[Camera]) -> Motion:
    """Move a motion horizontally so its pelvis's mean position sits where the cameras look.

    The target is the point nearest (least squares) to every camera's optical axis, e.g. the
    middle of a mocap lab's capture volume for the four Pose2Sim cameras (`read_qca(path,
    world_up="y")`); only its horizontal (x, z) position is used, so the subject keeps its height
    above the floor. With one camera, the point on its axis at the pelvis's mean height is used.
    """
    if not cameras:
        raise ValueError("stage_for_cameras needs at least one camera")
    pelvis = marker_positions(motion, ("pelvis",))[:, 0]
    centres = [np.asarray(c.centre, np.float64) for c in cameras]
    axes = [np.asarray(c.rotation, np.float64)[2] for c in cameras]
    if len(cameras) == 1:
        height = pelvis[:, 1].mean()
        step = (height - centres[0][1]) / axes[0][1] if abs(axes[0][1]) > 1e-3 else 3.0
        target = centres[0] + max(step, 1.0) * axes[0]
    else:
        normal_matrix = sum(np.eye(3) - np.outer(a, a) for a in axes)
        right_side = sum((np.eye(3) - np.outer(a, a)) @ c for a, c in zip(axes, centres,
                                                                          strict=True))
        target = np.linalg.lstsq(normal_matrix, right_side, rcond=None)[0]
    shift = target - pelvis.mean(axis=0)
    shift[1] = 0.0
    return Motion(motion.positions + shift, motion.joint_names, motion.parents, motion.fps,
                  motion.source, motion.rig)
