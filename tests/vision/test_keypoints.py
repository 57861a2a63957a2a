"""A detector's keypoints: checked, carried beside the image channels of an observation (never
inside one), read from and written to files."""

import numpy as np
import pytest

from jaxtrack.vision import edge_observations
from jaxtrack.vision.keypoints import (
    KeypointFileError,
    check_keypoints,
    read_keypoints,
    write_keypoints,
)
from jaxtrack.vision.observations import ImageObservation, image_observations


def _keypoints(frames=3, seed=0):
    rng = np.random.default_rng(seed)
    points = rng.uniform(0, 60, (frames, 12, 2))
    confidence = rng.uniform(0.1, 1.0, (frames, 12))
    return points, confidence


def test_keypoints_travel_beside_the_image_channels_and_leave_them_alone():
    rng = np.random.default_rng(1)
    frames = rng.random((3, 40, 50)).astype(np.float32)
    points, confidence = _keypoints()
    points[1, 4] = np.nan  # not found in frame 1
    masks = rng.random((3, 40, 50)) > 0.5
    plain = edge_observations(frames, masks=masks)
    keyed = image_observations(frames, masks=masks, keypoints=(points, confidence))
    assert isinstance(keyed, ImageObservation)
    np.testing.assert_array_equal(keyed.images, plain)  # the image channels are unchanged
    assert keyed.keypoints.points.shape == (3, 12, 2)
    found = np.isfinite(points).all(-1)
    np.testing.assert_allclose(keyed.keypoints.points[found], points[found], rtol=1e-6)
    np.testing.assert_allclose(keyed.keypoints.confidence[found], confidence[found], rtol=1e-6)
    assert np.all(keyed.keypoints.confidence[~found] == 0)
    assert np.all(keyed.keypoints.points[~found] == 0)
    # positions alone: confidence 1 where found
    alone = image_observations(frames, keypoints=points)
    assert alone.images.shape == (3, 3, 40, 50)
    np.testing.assert_array_equal(alone.keypoints.confidence[1], found[1].astype(np.float32))
    grey = image_observations(frames, edges=False)
    assert grey.keypoints is None and grey.images.shape == (3, 40, 50)
    with pytest.raises(ValueError, match=r"masks are read by the 'limbs\+edges' likelihood"):
        image_observations(frames, edges=False, masks=masks)


def test_bad_keypoints_are_refused_in_one_line(tmp_path):
    points, confidence = _keypoints()
    for arguments, message in (((points[:, :11], None), r"must be \(frames, 12, 2\)"),
                               ((points, confidence[:, :5]), r"confidence must be \(frames, 12\)"),
                               ((points, confidence + 1.0), r"must lie in \[0, 1\]"),
                               ((points * 1e7, None), "beyond 10\\^6 pixels")):
        with pytest.raises(ValueError, match=message):
            check_keypoints(*arguments)
    with pytest.raises(ValueError, match="hold 3 frames, the frames tracked are 4"):
        check_keypoints(points, num_frames=4)
    missing = tmp_path / "none.npz"
    with pytest.raises(KeypointFileError, match="none.npz: no such keypoints file"):
        read_keypoints(missing)
    other = tmp_path / "other.npz"
    np.savez(other, masks=np.zeros((2, 3, 3)))
    with pytest.raises(KeypointFileError, match="no array 'keypoints' \\(it has masks\\)"):
        read_keypoints(other)
    text = tmp_path / "text.npz"
    text.write_text("not an archive")
    with pytest.raises(KeypointFileError, match="text.npz: not a readable .npz"):
        read_keypoints(text)
    shaped = tmp_path / "shaped.npz"
    np.savez(shaped, keypoints=np.zeros((2, 17, 2)))
    with pytest.raises(KeypointFileError, match=r"shaped.npz: keypoints must be \(frames, 12"):
        read_keypoints(shaped)


def test_a_keypoints_file_round_trips(tmp_path):
    points, confidence = _keypoints()
    points[2, 7] = np.nan
    path = write_keypoints(tmp_path / "k.npz", points, confidence)
    read, sure = read_keypoints(path)
    found = np.isfinite(points).all(-1)
    np.testing.assert_allclose(read[found], points[found], rtol=1e-6)
    np.testing.assert_allclose(sure[found], confidence[found], rtol=1e-6)
    assert sure[2, 7] == 0
