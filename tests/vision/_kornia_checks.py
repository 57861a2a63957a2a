"""The kornia backend's checks, run by ``test_kornia_backend.py`` in a separate process: torch
and XLA in one process have crashed XLA's compiler, so the test suite's own process never
imports torch.

    python tests/vision/_kornia_checks.py      # exits 0 when every check passes
"""

import sys

import numpy as np
import torch

from jaxtrack.vision import _kornia
from jaxtrack.vision.foreground import foreground_mask
from jaxtrack.vision.normals import gradient_magnitude
from jaxtrack.vision.skin import skin_mask

SKIN = (220, 170, 140)


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


def check_foreground_masks_match_opencv(frames, background):
    masks = np.asarray(_kornia.foreground_masks(frames, background))
    for frame, mask in zip(frames, masks, strict=True):
        expected = foreground_mask(frame, background)
        assert 0.1 < expected.mean() < 0.5
        np.testing.assert_array_equal(mask, expected)
    one = foreground_mask(torch.from_numpy(frames[1]), background, backend="kornia")
    np.testing.assert_array_equal(np.asarray(one), masks[1])


def check_skin_masks_match_opencv(frames, background):
    foreground = np.stack([foreground_mask(frame, background) for frame in frames])
    for reference in (None, SKIN):
        masks = np.asarray(_kornia.skin_masks(frames, foreground, reference=reference))
        for frame, inside, mask in zip(frames, foreground, masks, strict=True):
            expected = skin_mask(frame, inside, reference=reference)
            assert expected.sum() > 100
            # chroma rounded once per pixel: a level's difference flips at most a few pixels
            assert np.mean(mask != expected) < 0.005, (reference, np.mean(mask != expected))


def check_gradient_magnitudes_match_opencv(frames, background):
    maps = np.asarray(_kornia.gradient_magnitudes(frames, sigma=1.0))
    assert maps.dtype == np.float32
    for frame, gradient in zip(frames, maps, strict=True):
        np.testing.assert_allclose(gradient, gradient_magnitude(frame, sigma=1.0), atol=5e-3)
    flat = np.zeros((1, 16, 16, 3), np.uint8)
    assert np.all(np.asarray(_kornia.gradient_magnitudes(flat)) == 0)


def check_results_reach_jax_without_a_copy(frames, background):
    tensor = torch.arange(12, dtype=torch.float32).reshape(3, 4)
    array = _kornia.to_jax(tensor)
    assert array.unsafe_buffer_pointer() == tensor.data_ptr()
    np.testing.assert_array_equal(np.asarray(array), tensor.numpy())


def check_bad_frames_are_refused(frames, background):
    for call, match in ((lambda: _kornia.foreground_masks(frames.astype(np.float32), background),
                         "frames must be"),
                        (lambda: _kornia.foreground_masks(frames, background[:-1]),
                         "differ in size")):
        try:
            call()
        except ValueError as error:
            assert match in str(error), error
        else:
            raise AssertionError(f"no ValueError ({match})")


def main() -> int:
    frames, background = scene()
    for name, check in list(globals().items()):
        if name.startswith("check_"):
            check(frames, background)
            print(f"{name}: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
