"""The kornia backend of the preprocessing agrees with OpenCV, and hands JAX its result through
DLPack without a copy."""

import numpy as np
import pytest

from jaxtrack.vision.foreground import foreground_mask
from jaxtrack.vision.normals import gradient_magnitude
from jaxtrack.vision.skin import skin_mask

torch = pytest.importorskip("torch")
pytest.importorskip("kornia")

from jaxtrack.vision import _kornia  # noqa: E402

SKIN = (220, 170, 140)


@pytest.fixture(scope="module")
def scene():
    """A noisy background, three frames of a textured person-sized box with a skin patch."""
    rng = np.random.default_rng(0)
    background = rng.integers(0, 255, (96, 128, 3), dtype=np.uint8)
    frames = np.repeat(background[None], 3, axis=0)
    for t in range(3):
        frames[t, 20:80, 30 + 5 * t:80 + 5 * t] = rng.integers(0, 255, (60, 50, 3))
        frames[t, 30:45, 40 + 5 * t:55 + 5 * t] = SKIN
    noisy = frames.astype(int) + rng.integers(-8, 9, frames.shape)
    return np.clip(noisy, 0, 255).astype(np.uint8), background


def test_foreground_masks_match_opencv(scene):
    frames, background = scene
    masks = np.asarray(_kornia.foreground_masks(frames, background))
    for frame, mask in zip(frames, masks, strict=True):
        expected = foreground_mask(frame, background)
        assert 0.1 < expected.mean() < 0.5
        np.testing.assert_array_equal(mask, expected)
    one = foreground_mask(torch.from_numpy(frames[1]), background, backend="kornia")
    np.testing.assert_array_equal(np.asarray(one), masks[1])


@pytest.mark.parametrize("reference", [None, SKIN])
def test_skin_masks_match_opencv(scene, reference):
    frames, background = scene
    foreground = np.stack([foreground_mask(frame, background) for frame in frames])
    masks = np.asarray(_kornia.skin_masks(frames, foreground, reference=reference))
    for frame, inside, mask in zip(frames, foreground, masks, strict=True):
        expected = skin_mask(frame, inside, reference=reference)
        assert expected.sum() > 100
        # chroma rounded once per pixel: a level's difference flips at most a few pixels
        assert np.mean(mask != expected) < 0.005


def test_gradient_magnitudes_match_opencv(scene):
    frames, _ = scene
    maps = np.asarray(_kornia.gradient_magnitudes(frames, sigma=1.0))
    assert maps.dtype == np.float32
    for frame, gradient in zip(frames, maps, strict=True):
        np.testing.assert_allclose(gradient, gradient_magnitude(frame, sigma=1.0), atol=5e-3)
    flat = np.zeros((1, 16, 16, 3), np.uint8)
    assert np.all(np.asarray(_kornia.gradient_magnitudes(flat)) == 0)


def test_results_reach_jax_without_a_copy():
    tensor = torch.arange(12, dtype=torch.float32).reshape(3, 4)
    array = _kornia.to_jax(tensor)
    assert array.unsafe_buffer_pointer() == tensor.data_ptr()
    np.testing.assert_array_equal(np.asarray(array), tensor.numpy())


def test_bad_backend_and_bad_frames_are_refused(scene):
    frames, background = scene
    with pytest.raises(ValueError, match="backend must be one of opencv, kornia"):
        foreground_mask(frames[0], background, backend="torch")
    with pytest.raises(ValueError, match="frames must be"):
        _kornia.foreground_masks(frames.astype(np.float32), background)
    with pytest.raises(ValueError, match="differ in size"):
        _kornia.foreground_masks(frames, background[:-1])
