"""Direct linear triangulation against points it must give back exactly, and Pose2Sim's TOML
calibration against the Qualisys file it was converted from."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.body import look_at
from jaxtrack.body._staging import project_numpy
from jaxtrack.vision.triangulation import (
    CalibrationFileError,
    read_pose2sim_calibration,
    reprojection_errors,
    triangulate,
)


def ring_of_cameras():
    eyes = [(3.0, 0.0, 1.5), (0.0, 3.5, 1.2), (-3.0, 0.5, 1.8), (0.5, -4.0, 1.0)]
    return [look_at(eye, (0.0, 0.0, 1.0), (0.0, 0.0, 1.0), 1200.0, (1080, 1920), name=f"c{i}")
            for i, eye in enumerate(eyes)]


def test_noiseless_views_give_the_points_back_and_a_missing_view_is_left_out():
    cameras = ring_of_cameras()
    world = np.random.default_rng(1).uniform([-0.5, -0.5, 0.2], [0.5, 0.5, 1.8], (5, 3, 3))
    points = np.stack([project_numpy(camera, world)[0] for camera in cameras])  # (4, 5, 3, 2)
    found, used = triangulate(points, cameras)
    np.testing.assert_allclose(found, world, atol=1e-9)
    assert (used == 4).all()
    np.testing.assert_allclose(reprojection_errors(found, points, cameras), 0.0, atol=1e-6)
    # a view's wrong detection: NaN, or confidence below the threshold, is left out
    corrupted = points.copy()
    corrupted[0, 0, 0] = np.nan
    corrupted[1, 1, 1] += 300.0
    confidence = np.ones(points.shape[:-1])
    confidence[1, 1, 1] = 0.1
    found, used = triangulate(corrupted, cameras, confidence=confidence, min_confidence=0.3)
    np.testing.assert_allclose(found, world, atol=1e-9)
    assert used[0, 0] == 3 and used[1, 1] == 3
    # kept, the wrong detection moves the point
    pulled, _ = triangulate(corrupted, cameras)
    assert np.linalg.norm(pulled[1, 1] - world[1, 1]) > 0.01
    # one view only: no point
    alone = np.full_like(points, np.nan)
    alone[2] = points[2]
    assert np.isnan(triangulate(alone, cameras)[0]).all()


def test_bad_shapes_are_refused():
    cameras = ring_of_cameras()
    with pytest.raises(ValueError, match="points must be"):
        triangulate(np.zeros((3, 5, 2)), cameras)
    with pytest.raises(ValueError, match="confidence must have shape"):
        triangulate(np.zeros((4, 5, 2)), cameras, confidence=np.ones((4, 4)))


def test_a_pose2sim_calibration_is_read_and_a_bad_one_refused(tmp_path):
    path = tmp_path / "Calib.toml"
    path.write_text('[cam_01]\nname = "cam_01"\nsize = [ 640.0, 480.0]\n'
                    'matrix = [ [ 500.0, 0.0, 320.0], [ 0.0, 510.0, 240.0], [ 0.0, 0.0, 1.0]]\n'
                    'distortions = [ 0.01, 0.0, 0.0, 0.0]\n'
                    'rotation = [ 0.0, 0.0, 1.5707963267948966]\n'
                    'translation = [ 0.1, 0.2, 3.0]\nfisheye = false\n\n'
                    '[metadata]\nadjusted = false\n')
    (camera,) = read_pose2sim_calibration(path)
    assert camera.name == "cam_01" and camera.image_size == (640, 480)
    np.testing.assert_allclose(camera.focal_length, [500, 510])
    np.testing.assert_allclose(camera.rotation, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-7)
    np.testing.assert_allclose(camera.translation, [0.1, 0.2, 3.0])
    path.write_text("[metadata]\nadjusted = false\n")
    with pytest.raises(CalibrationFileError, match="no camera table"):
        read_pose2sim_calibration(path)
    path.write_text('[c]\nmatrix = [1, 2]\n')
    with pytest.raises(CalibrationFileError, match=r"camera \[c\] is malformed"):
        read_pose2sim_calibration(path)
    with pytest.raises(CalibrationFileError, match="no such calibration file"):
        read_pose2sim_calibration(tmp_path / "none.toml")


def test_pose2sim_s_conversion_of_the_demo_calibration_is_read_qca_s_cameras():
    from jaxtrack.body import read_qca
    from jaxtrack.evaluation.reference import default_folder

    try:
        folder = default_folder()
    except FileNotFoundError as error:
        pytest.skip(str(error))
    toml = read_pose2sim_calibration(folder / "reference" / "Calib_qualisys.toml")
    qca = read_qca(folder / "Calib.qca.txt")
    assert len(toml) == len(qca) == 4
    for ours, theirs in zip(qca, toml, strict=True):
        np.testing.assert_allclose(theirs.focal_length, ours.focal_length, rtol=1e-6)
        np.testing.assert_allclose(theirs.principal_point, ours.principal_point, atol=1e-3)
        np.testing.assert_allclose(theirs.rotation, ours.rotation, atol=1e-6)
        np.testing.assert_allclose(theirs.translation, ours.translation, atol=1e-6)
