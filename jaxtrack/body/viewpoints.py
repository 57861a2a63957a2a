"""Viewpoints on the view sphere and cameras that frame a moving subject.

Tian, Li & Sclaroff (2005) render their training poses "from different viewpoints on the
view-sphere"; :func:`sample_viewpoints` draws such viewpoints and :func:`frame_subject` turns one
into a camera whose image holds a whole motion with a margin, so projected training poses and
rendered test video share one convention.

The world is Y-up (as ``body.motion``): azimuth turns about +y (azimuth 0 puts the camera on +z,
azimuth π/2 on +x), elevation lifts the camera above the x–z plane.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
from jaxtyping import Array, ArrayLike, Float, Key

from jaxtrack.body.camera import Camera, look_at, to_camera_frame

__all__ = ["Viewpoint", "frame_subject", "sample_viewpoints", "viewpoint_direction"]


class Viewpoint(eqx.Module):
    """A point on the view sphere around the subject (angles in radians, distance in metres).

    Every field may carry a leading batch axis (``sample_viewpoints`` returns ``(num,)`` fields).
    """

    azimuth: Float[Array, "*batch"]
    elevation: Float[Array, "*batch"]
    distance: Float[Array, "*batch"]


def viewpoint_direction(viewpoint: Viewpoint) -> Float[Array, "*batch 3"]:
    """Unit vector from the subject to the camera (Y-up world)."""
    cos_elevation = jnp.cos(viewpoint.elevation)
    return jnp.stack(
        [
            cos_elevation * jnp.sin(viewpoint.azimuth),
            jnp.sin(viewpoint.elevation),
            cos_elevation * jnp.cos(viewpoint.azimuth),
        ],
        axis=-1,
    )


@eqx.filter_jit
def sample_viewpoints(
    key: Key[Array, ""],
    num: int,
    *,
    azimuth_range: tuple[float, float] = (-jnp.pi, jnp.pi),
    elevation_range: tuple[float, float] = (-0.2, 0.5),
    distance: float | tuple[float, float] = 4.0,
    dtype=None,
) -> Viewpoint:
    """Draw ``num`` viewpoints uniformly by area on a band of the view sphere.

    Azimuth is uniform in ``azimuth_range``; elevation is drawn with ``sin(elevation)`` uniform in
    ``sin(elevation_range)``, which is uniform over the sphere's surface (uniform elevation would
    crowd the poles). ``distance`` is fixed or uniform in a ``(low, high)`` range, in metres.

    Returns:
        A :class:`Viewpoint` whose fields have shape ``(num,)``.
    """
    low_elevation, high_elevation = elevation_range
    if not -jnp.pi / 2 <= low_elevation <= high_elevation <= jnp.pi / 2:
        raise ValueError(f"elevation_range must lie in [-π/2, π/2], got {elevation_range}")
    if azimuth_range[0] > azimuth_range[1]:
        raise ValueError(f"azimuth_range must be (low, high), got {azimuth_range}")
    dtype = dtype or jnp.result_type(float)
    key_azimuth, key_elevation, key_distance = jr.split(key, 3)
    azimuth = jr.uniform(
        key_azimuth, (num,), dtype, minval=azimuth_range[0], maxval=azimuth_range[1]
    )
    sine = jr.uniform(
        key_elevation, (num,), dtype,
        minval=jnp.sin(low_elevation), maxval=jnp.sin(high_elevation),
    )
    if isinstance(distance, tuple):
        distances = jr.uniform(key_distance, (num,), dtype, minval=distance[0], maxval=distance[1])
    else:
        distances = jnp.full((num,), distance, dtype)
    return Viewpoint(azimuth=azimuth, elevation=jnp.arcsin(sine), distance=distances)


@eqx.filter_jit
def frame_subject(
    points_world: Float[ArrayLike, "time joints 3"],
    view: Viewpoint | Camera,
    image_size: tuple[int, int],
    margin: float = 0.1,
) -> Camera:
    """A camera that shows every point of a motion inside the image, with a margin on each side.

    With a :class:`Viewpoint` the camera sits at ``viewpoint.distance`` from the centre of the
    motion's bounding box, in the viewpoint's direction, looking at that centre with +y up. With a
    :class:`Camera` its pose is kept. Either way the focal length (equal in x and y) and the
    principal point are then chosen so that the points' projections span the image minus
    ``margin`` (a fraction of the image's width and height, on each side) in the tighter direction,
    centred. Distortion is zero. Traceable: ``jax.vmap`` over a batch of viewpoints works.

    Args:
        points_world: ``(time, joints, 3)`` (any leading shape) world points, metres.
        view: where to look from.
        image_size: ``(width, height)`` in pixels.
        margin: empty border as a fraction of the image size, in ``[0, 0.5)``.

    Returns:
        The camera. Every point must lie in front of it (for a viewpoint: ``distance`` larger than
        the motion's radius); points at or behind the camera are clamped to a small depth, which
        frames nothing sensible.
    """
    if not 0.0 <= margin < 0.5:
        raise ValueError(f"margin must be in [0, 0.5), got {margin}")
    points = jnp.asarray(points_world)
    dtype = jnp.result_type(points, float)
    points = points.reshape(-1, 3).astype(dtype)
    width, height = image_size
    if isinstance(view, Viewpoint):
        low, high = jnp.min(points, axis=0), jnp.max(points, axis=0)
        centre = 0.5 * (low + high)
        view = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), view)
        eye = centre + view.distance * viewpoint_direction(view)
        up = jnp.array([0.0, 1.0, 0.0], dtype)
        camera = look_at(eye, centre, up, 1.0, image_size)
    else:
        camera = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), view)
    camera_points = to_camera_frame(camera, points)
    depth = jnp.maximum(camera_points[:, 2], 1e-6)
    normalised = camera_points[:, :2] / depth[:, None]
    low, high = jnp.min(normalised, axis=0), jnp.max(normalised, axis=0)
    usable = jnp.array([width * (1 - 2 * margin), height * (1 - 2 * margin)], dtype)
    extent = jnp.maximum(high - low, 1e-9)
    focal = jnp.min(usable / extent)
    image_centre = jnp.array([(width - 1) / 2.0, (height - 1) / 2.0], dtype)
    principal_point = image_centre - focal * 0.5 * (low + high)
    return Camera(
        focal_length=jnp.stack([focal, focal]),
        principal_point=principal_point,
        rotation=camera.rotation,
        translation=camera.translation,
        distortion=jnp.zeros(5, dtype),
        image_size=(int(width), int(height)),
        name=camera.name,
    )
