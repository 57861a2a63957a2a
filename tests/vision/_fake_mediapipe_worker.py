"""A stand-in for MediaPipe behind the real worker (jaxtrack/vision/_mediapipe_worker.py): it
"detects" a person at the centroid of an image's bright pixels (all 33 landmarks there,
visibility 0.9), so the files, the pipe, the crops and the mapping back to frame pixels are the
worker's own code with a known answer. Run by the tests with jaxtrack's python."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "jaxtrack" / "vision"))
import _mediapipe_worker  # noqa: E402


def bright_pixels(options):
    def process(image):
        rows, cols = np.nonzero(image[..., 0] > 128)
        if rows.size == 0:
            return None
        height, width = image.shape[:2]
        centre = np.array([cols.mean() / width, rows.mean() / height])
        mask = (image[..., 0] > 128).astype(np.float32)
        return np.tile(centre, (33, 1)), np.full(33, 0.9), mask

    return process, lambda: None, "fake-1.0"


if __name__ == "__main__":
    raise SystemExit(_mediapipe_worker.main(sys.argv[1:], make_process=bright_pixels))
