"""A detector's keypoints: checked, carried in the observations' last channel, read from and
written to files."""

import numpy as np
import pytest

from jaxtrack.vision import edge_observations
from jaxtrack.vision.keypoints import (
    KEYPOINT_VALUES,
    KeypointFileError,
    check_keypoints,
    pack_keypoints,
    read_keypoints,
    unpack_keypoints,
    write_keypoints,
)


def _keypoints(frames=3, seed=0):
    rng = np.random.default_rng(seed)
    points = rng.uniform(0, 60, (frames, 12, 2))
    confidence = rng.uniform(0.1, 1.0, (frames, 12))
    return points, confidence


def test_keypoints_ride_in_the_last_channel_and_leave_the_others_alone():
    rng = np.random.default_rng(1)
    frames = rng.random((3, 40, 50)).astype(np.float32)
    points, confidence = _keypoints()
    points[1, 4] = np.nan  # not found in frame 1
    masks = rng.random((3, 40, 50)) > 0.5
    plain = edge_observations(frames, masks=masks)
    keyed = edge_observations(frames, masks=masks, keypoints=(points, confidence))
    assert keyed.shape == (3, 5, 40, 50)
    np.testing.assert_array_equal(keyed[:, :4], plain)
    for index in range(3):
        read, sure = unpack_keypoints(keyed[index, -1])
        found = np.isfinite(points[index]).all(-1)
        np.testing.assert_allclose(read[found], points[index][found], rtol=1e-6)
        np.testing.assert_allclose(sure[found], confidence[index][found], rtol=1e-6)
        assert np.all(sure[~found] == 0) and np.all(read[~found] == 0)
    assert np.count_nonzero(keyed[:, -1].reshape(3, -1)[:, KEYPOINT_VALUES:]) == 0
    # positions alone: confidence 1 where found
    alone = edge_observations(frames, keypoints=points)
    assert alone.shape == (3, 4, 40, 50)
    np.testing.assert_array_equal(unpack_keypoints(alone[1, -1])[1],
                                  np.isfinite(points[1]).all(-1).astype(np.float32))


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
    with pytest.raises(ValueError, match="too small to carry 12 keypoints"):
        pack_keypoints(*check_keypoints(points, confidence), np.zeros((3, 5, 5), np.float32))
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
