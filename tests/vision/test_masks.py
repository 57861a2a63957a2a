"""Person masks from a file (``jaxtrack.vision.masks``): the formats read, the frames and size
they are fitted to, and one-line errors naming the file for anything else."""

import numpy as np
import pytest

from jaxtrack.vision import MaskFileError, masks_for_frames, read_masks, write_masks


def _masks(frames=4, height=20, width=10):
    masks = np.zeros((frames, height, width), bool)
    for t in range(frames):
        masks[t, 2 + t:12 + t, 3:7] = True  # a box moving down one row per frame
    return masks


def test_written_masks_read_back_and_integer_masks_are_accepted(tmp_path):
    masks = _masks()
    path = write_masks(tmp_path / "masks.npz", masks)
    np.testing.assert_array_equal(read_masks(path), masks)
    for scale in (1, 255):
        np.save(tmp_path / f"m{scale}.npy", masks.astype(np.uint8) * scale)
        np.testing.assert_array_equal(read_masks(tmp_path / f"m{scale}.npy"), masks)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["m1.npy", "m255.npy",
                                                                 "masks.npz"]


def test_masks_are_picked_by_video_frame_and_resized_by_nearest_neighbour():
    masks = _masks()
    fitted = masks_for_frames(masks, [3, 1], (20, 40))
    assert fitted.shape == (2, 40, 20) and fitted.dtype == np.bool_
    np.testing.assert_array_equal(fitted[0], np.repeat(np.repeat(masks[3], 2, 0), 2, 1))
    np.testing.assert_array_equal(fitted[1], np.repeat(np.repeat(masks[1], 2, 0), 2, 1))
    same = masks_for_frames(masks, [2], (10, 20))
    np.testing.assert_array_equal(same[0], masks[2])


@pytest.mark.parametrize("case, message", [
    ("missing", "{tmp}/missing.npz: no such masks file"),
    ("text", "{tmp}/text.npz: not a .npz or .npy file"),
    ("truncated", "{tmp}/truncated.npz: damaged or truncated"),
    ("other array", "{tmp}/other.npz: no array 'masks' (it has silhouettes)"),
    ("two-d", "{tmp}/flat.npy: masks must be (frames, height, width), got shape (20, 10)"),
    ("float", "{tmp}/float.npy: masks must be bool or integer 0/1 or 0/255, got dtype float32"),
    ("grey levels", "{tmp}/grey.npy: integer masks must hold only 0 and 1, or 0 and 255; "
                    "found values [0, 7]"),
])
def test_a_bad_masks_file_is_named_in_one_line(tmp_path, case, message):
    masks = _masks()
    files = {"missing": "missing.npz", "text": "text.npz", "truncated": "truncated.npz",
             "other array": "other.npz", "two-d": "flat.npy", "float": "float.npy",
             "grey levels": "grey.npy"}
    path = tmp_path / files[case]
    if case == "text":
        path.write_text("not masks")
    elif case == "truncated":
        write_masks(tmp_path / "whole.npz", masks)
        path.write_bytes((tmp_path / "whole.npz").read_bytes()[:120])
    elif case == "other array":
        np.savez(path, silhouettes=masks)
    elif case == "two-d":
        np.save(path, masks[0])
    elif case == "float":
        np.save(path, masks.astype(np.float32))
    elif case == "grey levels":
        np.save(path, masks.astype(np.uint8) * 7)
    with pytest.raises(MaskFileError) as error:
        read_masks(path)
    assert str(error.value).startswith(message.format(tmp=tmp_path))
    assert "\n" not in str(error.value)


def test_masks_that_do_not_fit_the_video_are_refused_naming_the_file():
    masks = _masks()
    with pytest.raises(MaskFileError, match=r"^m\.npz: holds 4 masks, but video frame 4 is "
                                            r"tracked"):
        masks_for_frames(masks, [0, 4], (10, 20), name="m.npz")
    with pytest.raises(MaskFileError, match=r"^m\.npz: masks are 10x20, frames 20x20; the "
                                            r"aspect ratios differ"):
        masks_for_frames(masks, [0], (20, 20), name="m.npz")
