"""Several calibrated views' 2-D detections → 3-D points: direct linear triangulation, and
Pose2Sim's TOML calibration.

:func:`triangulate` is the DLT (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., §12.2,
the homogeneous method): each view ``v`` whose point ``(x, y)`` is present gives two rows
``w_v (x̂ p₃ᵀ − p₁ᵀ)``, ``w_v (ŷ p₃ᵀ − p₂ᵀ)`` of ``A``, with ``p_i`` the rows of the view's
``[R | t]`` and ``(x̂, ŷ) = ((x − c_x)/f_x, (y − c_y)/f_y)`` the point in normalised
coordinates (which conditions ``A`` as Hartley's normalisation would); the point is the right
singular vector of ``A``'s least singular value, dehomogenised. The weights ``w_v`` are the
detections' confidences, as Pose2Sim weights its DLT by the detector's likelihoods. Lens
distortion is left out, as Pose2Sim left it out (SOURCE.txt of the demo's reference).

:func:`read_pose2sim_calibration` reads Pose2Sim's ``Calib*.toml`` (one table per camera:
``size`` (width, height), ``matrix`` K, ``distortions`` (k1, k2, p1, p2), ``rotation`` (a
Rodrigues vector, world → camera), ``translation`` (metres), ``fisheye``) into
:class:`jaxtrack.body.Camera` (``jaxtrack.body.read_qca`` reads Qualisys's ``.qca``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["CalibrationFileError", "read_pose2sim_calibration", "reprojection_errors",
           "triangulate"]


class CalibrationFileError(ValueError):
    """A calibration file is missing or not what it should be; one line naming it."""


def read_pose2sim_calibration(path: str | os.PathLike) -> list:
    """The cameras of a Pose2Sim ``Calib*.toml``, in the file's order, named by their tables.

    Raises:
        CalibrationFileError: no such file, not TOML, no camera table, a malformed or fisheye
            camera.
    """
    import tomllib

    from jaxtrack.body import Camera

    path = Path(path)
    if not path.is_file():
        raise CalibrationFileError(f"{path}: no such calibration file")
    try:
        tables = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise CalibrationFileError(f"{path} is not a TOML file: {error}") from None
    cameras = []
    for name, table in tables.items():
        if not isinstance(table, dict) or "matrix" not in table:
            continue  # [metadata] and the like
        try:
            if table.get("fisheye", False):
                raise ValueError("fisheye cameras are not supported")
            matrix = np.asarray(table["matrix"], np.float64)
            distortion = np.asarray(table.get("distortions", []), np.float64)
            rotation = np.asarray(table["rotation"], np.float64)
            translation = np.asarray(table["translation"], np.float64)
            width, height = (int(round(float(v))) for v in table["size"])
            if not all(np.isfinite(a).all() for a in (matrix, distortion, rotation, translation)):
                raise ValueError("non-finite values")
            cameras.append(Camera.from_opencv(matrix, distortion, rotation, translation,
                                              (width, height), name=str(name)))
        except (KeyError, TypeError, ValueError) as error:
            raise CalibrationFileError(f"{path}: camera [{name}] is malformed: "
                                       f"{' '.join(str(error).split())}") from None
    if not cameras:
        raise CalibrationFileError(f"{path} has no camera table (one with a 'matrix'); is it a "
                                   f"Pose2Sim calibration?")
    return cameras


def _extrinsics(cameras) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    focal = np.stack([np.asarray(c.focal_length, np.float64) for c in cameras])
    principal = np.stack([np.asarray(c.principal_point, np.float64) for c in cameras])
    rotation = np.stack([np.asarray(c.rotation, np.float64) for c in cameras])
    translation = np.stack([np.asarray(c.translation, np.float64) for c in cameras])
    return focal, principal, rotation, translation


def triangulate(points, cameras, *, confidence=None, min_confidence: float = 0.0,
                min_views: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Weighted DLT of each point seen in several views (module docstring).

    Args:
        points: ``(views, ..., 2)`` pixels, NaN where a view has no detection.
        cameras: ``views`` :class:`jaxtrack.body.Camera` (their distortion is ignored).
        confidence: optional ``(views, ...)`` weights; views below ``min_confidence`` are left
            out. Default 1 wherever a point is present.
        min_views: fewer present views give NaN.

    Returns:
        ``(world (..., 3), views_used (...))``.
    """
    points = np.asarray(points, np.float64)
    cameras = list(cameras)
    if points.ndim < 2 or points.shape[-1] != 2 or points.shape[0] != len(cameras):
        raise ValueError(f"points must be (views = {len(cameras)}, ..., 2), got {points.shape}")
    if int(min_views) < 2:
        raise ValueError(f"min_views must be at least 2, got {min_views}")
    weights = (np.ones(points.shape[:-1]) if confidence is None
               else np.nan_to_num(np.asarray(confidence, np.float64)))
    if weights.shape != points.shape[:-1]:
        raise ValueError(f"confidence must have shape {points.shape[:-1]}, got {weights.shape}")
    present = np.isfinite(points).all(-1) & (weights >= min_confidence) & (weights > 0)
    weights = np.where(present, weights, 0.0)
    focal, principal, rotation, translation = _extrinsics(cameras)
    views, rest = points.shape[0], points.shape[1:-1]
    flat = points.reshape(views, -1, 2)
    normalised = (np.nan_to_num(flat) - principal[:, None]) / focal[:, None]  # (views, N, 2)
    projection = np.concatenate([rotation, translation[..., None]], axis=-1)  # (views, 3, 4)
    # rows x̂ p₃ − p₁ and ŷ p₃ − p₂ per view: (N, views, 2, 4)
    rows = (normalised[..., None] * projection[:, None, 2:3, :]
            - projection[:, None, :2, :])
    rows = rows * weights.reshape(views, -1)[..., None, None]
    matrix = np.moveaxis(rows, 0, 1).reshape(flat.shape[1], 2 * views, 4)
    _, _, vh = np.linalg.svd(matrix)
    homogeneous = vh[:, -1]
    used = present.reshape(views, -1).sum(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        world = homogeneous[:, :3] / homogeneous[:, 3:]
    world = np.where((used >= int(min_views))[:, None] & np.isfinite(world), world, np.nan)
    return world.reshape(*rest, 3), used.reshape(rest)


def reprojection_errors(world, points, cameras) -> np.ndarray:
    """Pixel distance ``(views, ...)`` between each view's ``points`` ``(views, ..., 2)`` and
    the projection (no distortion) of ``world`` ``(..., 3)``; NaN where either is missing."""
    focal, principal, rotation, translation = _extrinsics(list(cameras))
    world = np.asarray(world, np.float64)
    camera = np.einsum("vij,...j->v...i", rotation, world)
    camera = camera + translation.reshape(len(focal), *([1] * (world.ndim - 1)), 3)
    shape = (len(focal), *([1] * (world.ndim - 1)), 2)
    pixels = camera[..., :2] / camera[..., 2:] * focal.reshape(shape) + principal.reshape(shape)
    return np.linalg.norm(pixels - np.asarray(points, np.float64), axis=-1)
