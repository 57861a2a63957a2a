"""Pinhole cameras with OpenCV's lens distortion, projection, and the Qualisys ``.qca`` reader.

A :class:`Camera` maps world points to pixels exactly as ``cv2.projectPoints`` does
(``distCoeffs = (k1, k2, p1, p2, k3)``): world → camera frame (x right, y down, z forward),
perspective division, radial and tangential distortion, then the intrinsics.
Everything is JAX, so projection can be jitted, vmapped over points or over a stack of cameras
(see :func:`stack_cameras`) and differentiated with respect to points and camera parameters.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

__all__ = [
    "Camera",
    "look_at",
    "project",
    "project_with_depth",
    "read_qca",
    "rotation_from_rotation_vector",
    "stack_cameras",
    "to_camera_frame",
]


class Camera(eqx.Module):
    """A calibrated pinhole camera with OpenCV's 5-coefficient distortion model.

    Attributes:
        focal_length: ``(2,)`` — ``(fx, fy)`` in pixels.
        principal_point: ``(2,)`` — ``(cx, cy)`` in pixels (OpenCV: pixel centres at integers).
        rotation: ``(3, 3)`` — world → camera rotation (OpenCV axes: x right, y down, z forward).
        translation: ``(3,)`` — world → camera translation, ``X_cam = rotation @ X + translation``.
        distortion: ``(5,)`` — ``(k1, k2, p1, p2, k3)``, OpenCV's order.
        image_size: static ``(width, height)`` in pixels.
        name: static label (the serial in a calibration file).

    A stack of cameras (from :func:`stack_cameras`) has a leading ``views`` axis on every array.
    """

    focal_length: Float[Array, "*views 2"]
    principal_point: Float[Array, "*views 2"]
    rotation: Float[Array, "*views 3 3"]
    translation: Float[Array, "*views 3"]
    distortion: Float[Array, "*views 5"]
    image_size: tuple[int, int] = eqx.field(static=True)
    name: str = eqx.field(static=True, default="")

    @property
    def width(self) -> int:
        return self.image_size[0]

    @property
    def height(self) -> int:
        return self.image_size[1]

    @property
    def intrinsic_matrix(self) -> Float[Array, "*views 3 3"]:
        """The 3×3 matrix ``K`` (zero skew)."""
        fx, fy = self.focal_length[..., 0], self.focal_length[..., 1]
        cx, cy = self.principal_point[..., 0], self.principal_point[..., 1]
        zero, one = jnp.zeros_like(fx), jnp.ones_like(fx)
        rows = [
            jnp.stack([fx, zero, cx], -1),
            jnp.stack([zero, fy, cy], -1),
            jnp.stack([zero, zero, one], -1),
        ]
        return jnp.stack(rows, -2)

    @property
    def centre(self) -> Float[Array, "*views 3"]:
        """The camera centre in world coordinates, ``-Rᵀ t``."""
        return -jnp.einsum("...ji,...j->...i", self.rotation, self.translation)

    @classmethod
    def from_opencv(
        cls,
        intrinsic_matrix: ArrayLike,
        distortion: ArrayLike,
        rotation_vector: ArrayLike,
        translation: ArrayLike,
        image_size: tuple[int, int],
        name: str = "",
    ) -> Camera:
        """Build a camera from OpenCV's ``K``, ``distCoeffs``, ``rvec``, ``tvec``.

        Args:
            intrinsic_matrix: ``(3, 3)`` matrix ``K``; its skew must be zero.
            distortion: 0, 4 or 5 coefficients ``(k1, k2, p1, p2[, k3])``; the rational and
                thin-prism models (8+ coefficients) are not supported.
            rotation_vector: ``(3,)`` Rodrigues vector (world → camera), or a ``(3, 3)`` matrix.
            translation: ``(3,)`` world → camera translation.
            image_size: ``(width, height)``.
            name: a label.
        """
        matrix = jnp.asarray(intrinsic_matrix)
        if matrix.shape != (3, 3):
            raise ValueError(f"intrinsic_matrix must be 3x3, got shape {matrix.shape}")
        if float(np.abs(np.asarray(matrix)[0, 1])) > 0.0:
            raise ValueError("intrinsic_matrix has non-zero skew K[0, 1]; skew is not supported")
        coefficients = jnp.ravel(jnp.asarray(distortion, dtype=matrix.dtype))
        if coefficients.shape[0] not in (0, 4, 5):
            raise ValueError(
                f"distortion must have 0, 4 or 5 coefficients (k1, k2, p1, p2[, k3]), "
                f"got {coefficients.shape[0]}; the rational model is not supported"
            )
        coefficients = jnp.pad(coefficients, (0, 5 - coefficients.shape[0]))
        rotation = jnp.asarray(rotation_vector, dtype=matrix.dtype)
        if rotation.shape != (3, 3):
            rotation = rotation_from_rotation_vector(jnp.ravel(rotation))
        return cls(
            focal_length=jnp.stack([matrix[0, 0], matrix[1, 1]]),
            principal_point=jnp.stack([matrix[0, 2], matrix[1, 2]]),
            rotation=rotation,
            translation=jnp.ravel(jnp.asarray(translation, dtype=matrix.dtype)),
            distortion=coefficients,
            image_size=_image_size(image_size),
            name=name,
        )


def _image_size(image_size: Sequence[int]) -> tuple[int, int]:
    width, height = (int(round(float(size))) for size in image_size)
    if width <= 0 or height <= 0:
        raise ValueError(f"image_size must be positive (width, height), got {tuple(image_size)}")
    return width, height


@jax.jit
def rotation_from_rotation_vector(rotation_vector: Float[ArrayLike, "3"]) -> Float[Array, "3 3"]:
    """Rodrigues' formula ``R = I + sinθ/θ [r]× + (1 − cosθ)/θ² [r]×²``, smooth at ``θ = 0``."""
    r = jnp.asarray(rotation_vector)
    theta_squared = jnp.sum(r**2)
    small = theta_squared < 1e-12
    safe = jnp.where(small, 1.0, theta_squared)
    theta = jnp.sqrt(safe)
    # Taylor series near zero keeps the value and the gradient finite (the double-where trick).
    sin_term = jnp.where(small, 1.0 - theta_squared / 6.0, jnp.sin(theta) / theta)
    cos_term = jnp.where(small, 0.5 - theta_squared / 24.0, (1.0 - jnp.cos(theta)) / safe)
    zero = jnp.zeros_like(r[0])
    cross = jnp.array([[zero, -r[2], r[1]], [r[2], zero, -r[0]], [-r[1], r[0], zero]])
    return jnp.eye(3, dtype=r.dtype) + sin_term * cross + cos_term * (cross @ cross)


def look_at(
    eye: Float[ArrayLike, "3"],
    target: Float[ArrayLike, "3"],
    up: Float[ArrayLike, "3"],
    focal_length: float | Float[ArrayLike, ""],
    image_size: tuple[int, int],
    name: str = "",
) -> Camera:
    """A distortion-free camera at ``eye`` looking at ``target``, ``up`` pointing up in the image.

    The principal point is the image centre ``((W − 1)/2, (H − 1)/2)``; ``focal_length`` in pixels.
    ``up`` must not be parallel to ``target − eye``. Traceable (vmap over eyes or targets).
    """
    eye, target, up = (jnp.asarray(v) for v in (eye, target, up))
    dtype = jnp.result_type(eye, target, up, float)
    eye, target, up = (v.astype(dtype) for v in (eye, target, up))
    forward = _normalise(target - eye)
    right = _normalise(jnp.cross(forward, up))
    down = jnp.cross(forward, right)  # OpenCV's y axis points down the image
    rotation = jnp.stack([right, down, forward])
    width, height = _image_size(image_size)
    focal = jnp.asarray(focal_length, dtype=dtype)
    return Camera(
        focal_length=jnp.stack([focal, focal]),
        principal_point=jnp.array([(width - 1) / 2.0, (height - 1) / 2.0], dtype=dtype),
        rotation=rotation,
        translation=-rotation @ eye,
        distortion=jnp.zeros(5, dtype=dtype),
        image_size=(width, height),
        name=name,
    )


def _normalise(vector: Array) -> Array:
    return vector / jnp.linalg.norm(vector, axis=-1, keepdims=True)


def _cast(camera: Camera, dtype) -> Camera:
    """The camera's arrays in ``dtype``, so float32 points give float32 pixels."""
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype=dtype), camera)


def to_camera_frame(camera: Camera, points_world: Float[ArrayLike, "*points 3"]) -> Array:
    """World points ``(..., 3)`` → camera-frame points ``(..., 3)`` (``z`` is the depth)."""
    points = jnp.asarray(points_world)
    dtype = jnp.result_type(points, float)
    camera = _cast(camera, dtype)
    return jnp.einsum("ij,...j->...i", camera.rotation, points.astype(dtype)) + camera.translation


@eqx.filter_jit
def project_with_depth(
    camera: Camera, points_world: Float[ArrayLike, "*points 3"]
) -> tuple[Float[Array, "*points 2"], Float[Array, "*points"]]:
    """Project world points to pixels, returning ``(pixels (..., 2), depth (...))``.

    Same model as ``cv2.projectPoints``:
    ``x' = X/Z, y' = Y/Z, r² = x'² + y'²``,
    ``x'' = x'(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x'y' + p2 (r² + 2x'²)``,
    ``y'' = y'(1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y'²) + 2 p2 x'y'``,
    ``u = fx x'' + cx, v = fy y'' + cy``.
    Points with ``depth <= 0`` are behind the camera: their pixels are meaningless (OpenCV projects
    them anyway); mask them with ``depth > 0``. For one camera; vmap for a stack of cameras.
    """
    points = jnp.asarray(points_world)
    dtype = jnp.result_type(points, float)
    camera = _cast(camera, dtype)
    camera_points = to_camera_frame(camera, points)
    depth = camera_points[..., 2]
    # OpenCV uses 1/z = 1 when z == 0; the double where keeps gradients finite there.
    nonzero = depth != 0
    inverse_depth = jnp.where(nonzero, 1.0 / jnp.where(nonzero, depth, 1.0), 1.0)
    x = camera_points[..., 0] * inverse_depth
    y = camera_points[..., 1] * inverse_depth
    k1, k2, p1, p2, k3 = (camera.distortion[i] for i in range(5))
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    x_distorted = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    y_distorted = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    u = camera.focal_length[0] * x_distorted + camera.principal_point[0]
    v = camera.focal_length[1] * y_distorted + camera.principal_point[1]
    return jnp.stack([u, v], axis=-1), depth


def project(
    camera: Camera, points_world: Float[ArrayLike, "*points 3"]
) -> Float[Array, "*points 2"]:
    """Project world points ``(..., 3)`` to pixels ``(..., 2)``; see :func:`project_with_depth`."""
    return project_with_depth(camera, points_world)[0]


def stack_cameras(cameras: Sequence[Camera]) -> Camera:
    """Stack cameras of one image size into one :class:`Camera` with a leading ``views`` axis.

    Use with ``jax.vmap(project, in_axes=(0, None))``. The stack's name joins the names with commas.
    """
    if not cameras:
        raise ValueError("stack_cameras needs at least one camera")
    sizes = {camera.image_size for camera in cameras}
    if len(sizes) != 1:
        raise ValueError(f"cameras must share one image size to be stacked, got {sorted(sizes)}")
    fields = ("focal_length", "principal_point", "rotation", "translation", "distortion")
    stacked = {f: jnp.stack([jnp.asarray(getattr(c, f)) for c in cameras]) for f in fields}
    return Camera(
        **stacked,
        image_size=cameras[0].image_size,
        name=",".join(camera.name for camera in cameras),
    )


# --------------------------------------------------------------------------------------------
# Qualisys .qca calibration files
# --------------------------------------------------------------------------------------------

# Qualisys stores focal lengths and the principal point in sub-pixel units of 1/64 pixel.
_QUALISYS_SUBPIXELS = 64.0
# The Qualisys camera frame has y up and looks along −z; OpenCV's has y down and looks along +z:
# a rotation by π about x (Pose2Sim's ``rotate_cam(ang_x=π)``).
_QUALISYS_TO_OPENCV = np.diag([1.0, -1.0, -1.0])
# A Y-up world point (x, y, z) is the Z-up point (x, −z, y): rotation by +π/2 about x.
_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def read_qca(path: str | Path, *, world_up: str = "z") -> list[Camera]:
    """Read a Qualisys ``.qca.txt`` calibration (XML) into OpenCV-convention cameras, in metres.

    Conventions (checked against Pose2Sim's ``calib_qca_fun`` and against an independent
    checkerboard calibration of the same four cameras, Pose2Sim's ``Calib_scene.toml``):

    - ``<transform>``: ``x, y, z`` is the camera centre in the world, in millimetres; the matrix
      ``M = [[r11, r12, r13], [r21, r22, r23], [r31, r32, r33]]`` maps world to the Qualisys camera
      frame (y up, looking along −z). OpenCV's world → camera rotation is therefore
      ``R = diag(1, −1, −1) M`` and ``t = −R C`` with ``C`` in metres.
    - ``<intrinsic>``: ``focalLengthU/V`` and ``centerPointU/V`` are in 1/64 pixel; the principal
      point is then shifted by the ``fov_video`` window's ``left``/``top``.
    - distortion ``(radialDistortion1, radialDistortion2, tangentalDistortion1,
      tangentalDistortion2, radialDistortion3)`` is used as OpenCV's ``(k1, k2, p1, p2, k3)`` as
      written. (Pose2Sim also divides these by 64, but the checkerboard calibration of the same
      lenses gives k1 ≈ −0.05, k2 ≈ 0.15, matching the raw values, not the values ÷ 64.)
    - image size: ``fov_video`` ``right − left + 1`` by ``bottom − top + 1``.

    Args:
        path: the ``.qca.txt`` file.
        world_up: ``"z"`` keeps Qualisys's Z-up world; ``"y"`` makes the cameras take Y-up world
            points (the Z-up point ``(X, Y, Z)`` is the Y-up point ``(X, Z, −Y)``), the convention
            of ``body.motion``.

    Returns:
        The active cameras, sorted by serial, each named by its serial (e.g. ``"cam01"``).
    """
    path = Path(path)
    if world_up not in ("y", "z"):
        raise ValueError(f"world_up must be 'y' or 'z', got {world_up!r}")
    if not path.is_file():
        raise FileNotFoundError(f"Qualisys calibration file not found: {path}")
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as error:
        raise ValueError(f"{path} is not a valid Qualisys .qca XML file: {error}") from error
    elements = root.findall("cameras/camera")
    if not elements:
        raise ValueError(f"{path} has no <cameras><camera> elements; is it a Qualisys .qca file?")
    cameras = []
    for element in elements:
        if element.get("active", "1") == "0":
            continue
        try:
            cameras.append(_qca_camera(element, world_up))
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            serial = element.get("serial", "?")
            raise ValueError(f"{path}: camera {serial!r} is malformed: {error!r}") from error
    return sorted(cameras, key=lambda camera: _natural_key(camera.name))


def _natural_key(text: str) -> list:
    import re

    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", text)]


def _qca_camera(element: ElementTree.Element, world_up: str) -> Camera:
    def attributes(tag: str) -> dict[str, str]:
        child = element.find(tag)
        if child is None:
            raise KeyError(f"missing <{tag}>")
        return child.attrib

    def number(values: dict[str, str], key: str) -> float:
        if key not in values:
            raise KeyError(f"missing attribute {key!r}")
        value = float(values[key])
        if not math.isfinite(value):
            raise ValueError(f"attribute {key!r} is not finite")
        return value

    window = attributes("fov_video")
    left, top = number(window, "left"), number(window, "top")
    width = number(window, "right") - left + 1
    height = number(window, "bottom") - top + 1
    intrinsic = attributes("intrinsic")
    focal = [number(intrinsic, k) / _QUALISYS_SUBPIXELS for k in ("focalLengthU", "focalLengthV")]
    centre = [
        number(intrinsic, "centerPointU") / _QUALISYS_SUBPIXELS - left,
        number(intrinsic, "centerPointV") / _QUALISYS_SUBPIXELS - top,
    ]
    distortion = [
        number(intrinsic, key)
        for key in ("radialDistortion1", "radialDistortion2", "tangentalDistortion1",
                    "tangentalDistortion2", "radialDistortion3")
    ]
    transform = attributes("transform")
    matrix = np.array([[number(transform, f"r{i}{j}") for j in (1, 2, 3)] for i in (1, 2, 3)])
    if not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-5):
        raise ValueError("<transform> r11..r33 is not a rotation matrix")
    position = np.array([number(transform, key) for key in ("x", "y", "z")]) / 1000.0
    rotation = _QUALISYS_TO_OPENCV @ matrix
    if world_up == "y":
        rotation = rotation @ _Y_UP_TO_Z_UP
        position = _Y_UP_TO_Z_UP.T @ position
    return Camera(
        focal_length=jnp.asarray(focal),
        principal_point=jnp.asarray(centre),
        rotation=jnp.asarray(rotation),
        translation=jnp.asarray(-rotation @ position),
        distortion=jnp.asarray(distortion),
        image_size=_image_size((width, height)),
        name=element.get("serial", ""),
    )
