"""Cameras: projection against OpenCV, transformations, the Qualisys reader, viewpoints."""

from pathlib import Path

import cv2
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.body.camera import (
    Camera,
    look_at,
    project,
    project_with_depth,
    read_qca,
    rotation_from_rotation_vector,
    stack_cameras,
)
from jaxtrack.body.viewpoints import frame_subject, sample_viewpoints

QCA = Path("/work/shared/data/pose2sim_demo_singleperson/Calib.qca.txt")
needs_qca = pytest.mark.skipif(not QCA.is_file(), reason="real Qualisys calibration not present")


def random_opencv_camera(rng: np.random.Generator):
    """A random camera (OpenCV parameters) and random points in front of it."""
    matrix = np.array(
        [[rng.uniform(400, 1500), 0, rng.uniform(250, 400)],
         [0, rng.uniform(400, 1500), rng.uniform(200, 300)],
         [0, 0, 1]]
    )
    distortion = np.array([
        rng.uniform(-0.3, 0.3), rng.uniform(-0.2, 0.2), rng.uniform(-0.01, 0.01),
        rng.uniform(-0.01, 0.01), rng.uniform(-0.1, 0.1),
    ])
    rotation_vector = rng.normal(size=3)
    translation = rng.normal(size=3)
    return matrix, distortion, rotation_vector, translation


def points_in_front(rng, rotation_vector, translation, num=40):
    rotation = cv2.Rodrigues(rotation_vector)[0]
    camera_points = np.column_stack(
        [rng.uniform(-1.5, 1.5, num), rng.uniform(-1.2, 1.2, num), rng.uniform(2.0, 6.0, num)]
    )
    return (camera_points - translation) @ rotation  # Rᵀ (X_cam − t), row-wise


def test_project_matches_opencv_project_points():
    rng = np.random.default_rng(0)
    for _ in range(5):
        matrix, distortion, rvec, tvec = random_opencv_camera(rng)
        points = points_in_front(rng, rvec, tvec)
        expected = cv2.projectPoints(points, rvec, tvec, matrix, distortion)[0][:, 0]
        camera = Camera.from_opencv(matrix, distortion, rvec, tvec, (640, 480))
        pixels, depth = project_with_depth(camera, points)
        assert pixels.dtype == jnp.float64
        assert np.all(np.asarray(depth) > 0)
        np.testing.assert_allclose(pixels, expected, rtol=0, atol=1e-8)


def test_project_jit_and_vmap_over_cameras_equal_loop():
    rng = np.random.default_rng(1)
    cameras, expected = [], []
    points = rng.normal(size=(7, 3)) * 0.3
    for _ in range(3):
        matrix, distortion, rvec, _ = random_opencv_camera(rng)
        tvec = np.array([0.1, -0.2, 4.0])
        cameras.append(Camera.from_opencv(matrix, distortion, rvec, tvec, (640, 480)))
        expected.append(cv2.projectPoints(points, rvec, tvec, matrix, distortion)[0][:, 0])
    stacked = stack_cameras(cameras)
    assert stacked.rotation.shape == (3, 3, 3)
    batched = jax.jit(jax.vmap(project, in_axes=(0, None)))(stacked, points)
    np.testing.assert_allclose(batched, np.stack(expected), atol=1e-8)
    looped = np.stack([jax.jit(project)(camera, points) for camera in cameras])
    np.testing.assert_allclose(batched, looped, atol=1e-10)


def test_float32_points_give_float32_pixels():
    rng = np.random.default_rng(2)
    matrix, distortion, rvec, tvec = random_opencv_camera(rng)
    points = points_in_front(rng, rvec, tvec, num=10)
    camera = Camera.from_opencv(matrix, distortion, rvec, tvec, (640, 480))
    pixels32 = project(camera, points.astype(np.float32))
    assert pixels32.dtype == jnp.float32
    np.testing.assert_allclose(pixels32, project(camera, points), atol=5e-2)


def test_from_opencv_distortion_lengths():
    rng = np.random.default_rng(3)
    matrix, distortion, rvec, tvec = random_opencv_camera(rng)
    four = Camera.from_opencv(matrix, distortion[:4], rvec, tvec, (640, 480))
    assert four.distortion.shape == (5,) and float(four.distortion[4]) == 0.0
    with pytest.raises(ValueError, match="rational"):
        Camera.from_opencv(matrix, np.zeros(8), rvec, tvec, (640, 480))
    with pytest.raises(ValueError, match="skew"):
        Camera.from_opencv(matrix + np.array([[0, 1.0, 0], [0, 0, 0], [0, 0, 0]]),
                           distortion, rvec, tvec, (640, 480))


def test_rotation_vector_matches_rodrigues_and_is_smooth_at_zero():
    rng = np.random.default_rng(4)
    for rvec in rng.normal(size=(3, 3)):
        np.testing.assert_allclose(rotation_from_rotation_vector(rvec), cv2.Rodrigues(rvec)[0],
                                   atol=1e-12)
    gradient = jax.jacfwd(rotation_from_rotation_vector)(jnp.zeros(3))
    assert np.all(np.isfinite(gradient))
    np.testing.assert_allclose(gradient[:, :, 2], [[0, -1, 0], [1, 0, 0], [0, 0, 0]], atol=1e-12)


def test_look_at_centres_target_and_keeps_up_up():
    eye, target = jnp.array([1.0, 1.5, 4.0]), jnp.array([0.0, 1.0, 0.0])
    camera = look_at(eye, target, jnp.array([0.0, 1.0, 0.0]), 500.0, (640, 480))
    centre, above = project(camera, jnp.stack([target, target + jnp.array([0.0, 0.5, 0.0])]))
    np.testing.assert_allclose(centre, [319.5, 239.5], atol=1e-9)
    assert above[1] < centre[1] - 10  # up in the world is up (smaller v) in the image
    np.testing.assert_allclose(camera.centre, eye, atol=1e-12)
    np.testing.assert_allclose(camera.rotation @ camera.rotation.T, np.eye(3), atol=1e-12)


def test_project_gradient_matches_finite_differences():
    rng = np.random.default_rng(5)
    matrix, distortion, rvec, tvec = random_opencv_camera(rng)
    camera = Camera.from_opencv(matrix, distortion, rvec, tvec, (640, 480))
    point = jnp.asarray(points_in_front(rng, rvec, tvec, num=1)[0])
    jacobian = jax.jacfwd(lambda p: project(camera, p))(point)
    step = 1e-6
    for axis in range(3):
        offset = jnp.zeros(3).at[axis].set(step)
        central = (project(camera, point + offset) - project(camera, point - offset)) / (2 * step)
        np.testing.assert_allclose(jacobian[:, axis], central, rtol=1e-6, atol=1e-4)


@needs_qca
def test_read_qca_values_match_the_file():
    cameras = read_qca(QCA)
    assert [camera.name for camera in cameras] == ["cam01", "cam02", "cam03", "cam04"]
    first = cameras[0]
    assert first.image_size == (1088, 1920)
    # Numbers copied from the <camera serial="cam01"> element of Calib.qca.txt.
    np.testing.assert_allclose(first.focal_length, [107599.671875 / 64, 107588.828125 / 64])
    np.testing.assert_allclose(first.principal_point, [34110.316406 / 64, 60680.792969 / 64])
    np.testing.assert_allclose(first.distortion, [-0.046183, 0.139983, 0.000608, 0.00069, 0.0])
    np.testing.assert_allclose(
        first.centre, [1.4602323709212087, -1.9091590482454608, 1.8965058524092062], atol=1e-12
    )
    # Pose2Sim's own conversion of this calibration (Calib_qualisys.toml, cam_01) gives the
    # same extrinsics: rvec (1.68827548, 1.04832205, −0.41955852), t (0.32110489, 0.95633206,
    # 2.89071305).
    rotation_vector = cv2.Rodrigues(np.asarray(first.rotation))[0][:, 0]
    np.testing.assert_allclose(rotation_vector, [1.68827548, 1.04832205, -0.41955852], atol=1e-7)
    np.testing.assert_allclose(first.translation, [0.32110489, 0.95633206, 2.89071305], atol=1e-7)


@needs_qca
def test_read_qca_cameras_all_see_the_capture_volume():
    cameras = read_qca(QCA)
    points = jnp.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.3, -0.3, 1.7]])  # Z-up, metres
    for camera in cameras:
        pixels, depth = project_with_depth(camera, points)
        assert np.all(np.asarray(depth) > 1.0), camera.name
        assert np.all((pixels >= 0) & (pixels < jnp.array(camera.image_size))), camera.name
        assert pixels[1, 1] < pixels[0, 1]  # the point 1 m up is higher in the portrait image
    y_up = read_qca(QCA, world_up="y")
    swapped = points[:, jnp.array([0, 2, 1])] * jnp.array([1.0, 1.0, -1.0])
    np.testing.assert_allclose(project(y_up[2], swapped), project(cameras[2], points), atol=1e-9)


def test_read_qca_errors_name_the_file(tmp_path):
    missing = tmp_path / "nothing.qca.txt"
    with pytest.raises(FileNotFoundError, match="nothing.qca.txt"):
        read_qca(missing)
    garbage = tmp_path / "garbage.qca.txt"
    garbage.write_text("<calibration><cameras>")
    with pytest.raises(ValueError, match="garbage.qca.txt"):
        read_qca(garbage)
    empty = tmp_path / "empty.qca.txt"
    empty.write_text("<calibration/>")
    with pytest.raises(ValueError, match="empty.qca.txt"):
        read_qca(empty)
    broken = tmp_path / "broken.qca.txt"
    broken.write_text(
        '<calibration><cameras><camera serial="c1"><fov_video left="0" top="0" right="9" '
        'bottom="9"/></camera></cameras></calibration>'
    )
    with pytest.raises(ValueError, match="broken.qca.txt.*c1"):
        read_qca(broken)


def test_sample_viewpoints_ranges():
    viewpoints = sample_viewpoints(
        jr.key(0), 500, azimuth_range=(-1.0, 2.0), elevation_range=(0.0, 1.0), distance=(3.0, 5.0)
    )
    assert viewpoints.azimuth.shape == (500,)
    assert float(viewpoints.azimuth.min()) >= -1.0 and float(viewpoints.azimuth.max()) <= 2.0
    assert float(viewpoints.elevation.min()) >= 0.0 and float(viewpoints.elevation.max()) <= 1.0
    assert float(viewpoints.distance.min()) >= 3.0 and float(viewpoints.distance.max()) <= 5.0
    # area-uniform: sin(elevation) is uniform on [0, sin 1], so its mean is sin(1)/2
    assert abs(float(jnp.mean(jnp.sin(viewpoints.elevation))) - np.sin(1.0) / 2) < 0.04
    with pytest.raises(ValueError, match="elevation_range"):
        sample_viewpoints(jr.key(0), 3, elevation_range=(0.0, 2.0))


def test_frame_subject_fits_a_point_cloud_with_margin():
    rng = np.random.default_rng(6)
    points = rng.normal(size=(5, 12, 3)) * np.array([0.3, 0.8, 0.3]) + np.array([0, 1.0, 0])
    viewpoints = sample_viewpoints(jr.key(1), 4, distance=4.0)
    cameras = jax.vmap(lambda view: frame_subject(points, view, (640, 480), 0.1))(viewpoints)
    pixels = jax.vmap(project, in_axes=(0, None))(cameras, points)
    low = pixels.reshape(4, -1, 2).min(axis=1)
    high = pixels.reshape(4, -1, 2).max(axis=1)
    # pixel centres are integers, so the image spans [−0.5, W − 0.5]; margins are 64 and 48 px
    assert np.all(low >= np.array([63.5, 47.5]) - 1e-6)
    assert np.all(high <= np.array([575.5, 431.5]) + 1e-6)
    # the tighter direction spans the image minus the margins exactly
    span = (high - low) / np.array([512.0, 384.0])
    np.testing.assert_allclose(span.max(axis=1), 1.0, atol=1e-9)


def test_frame_subject_keeps_a_real_motion_inside_sampled_views():
    from jaxtrack.data import load_clip

    positions = load_clip("animateddrawings/fair1_wave_hello").positions[::20]  # (42, 27, 3)
    viewpoints = sample_viewpoints(jr.key(2), 6, elevation_range=(-0.3, 0.8), distance=(2.5, 5.0))
    cameras = jax.vmap(lambda view: frame_subject(positions, view, (640, 480), 0.05))(viewpoints)
    pixels, depth = jax.vmap(project_with_depth, in_axes=(0, None))(cameras, positions)
    assert np.all(np.asarray(depth) > 0.5)
    low, high = np.array([31.5, 23.5]) - 1e-6, np.array([607.5, 455.5]) + 1e-6  # 5% margins
    assert np.all((pixels >= low) & (pixels <= high))
    # the views differ: the same joint lands in different places
    assert float(jnp.std(pixels[:, 0, 0, 0])) > 1.0
    # keeping a calibrated camera's pose works as well (a Camera instead of a viewpoint)
    camera = look_at(jnp.array([0.5, 1.2, 3.0]), jnp.array([0.0, 0.5, 0.0]),
                     jnp.array([0.0, 1.0, 0.0]), 300.0, (640, 480))
    framed = frame_subject(positions, camera, (640, 480), 0.05)
    np.testing.assert_allclose(framed.rotation, camera.rotation)
    inside = project(framed, positions)
    assert np.all((inside >= low) & (inside <= high))
