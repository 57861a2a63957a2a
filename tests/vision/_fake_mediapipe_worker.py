"""A stand-in for MediaPipe behind the real worker (jaxtrack/vision/_mediapipe_worker.py): it
"detects" a person at the centroid of an image's bright pixels (all 33 landmarks there,
visibility 0.9), so the files, the pipe, the crops and the mapping back to frame pixels are the
worker's own code with a known answer. Run by the tests with jaxtrack's python.

With ``FAKE_DETECTOR=largest`` in its environment it is a one-person detector as MediaPipe is:
of the bright rectangles (people) in the image, the largest (the nearest), its landmarks laid
out in its box by :func:`box_landmarks`."""

import os
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


FRACTIONS = {0: (0.5, 0.05), 7: (0.65, 0.1), 8: (0.35, 0.1), 11: (0.8, 0.25),
             12: (0.2, 0.25), 13: (1.0, 0.45), 14: (0.0, 0.45), 15: (0.9, 0.65),
             16: (0.1, 0.65), 23: (0.7, 0.95), 24: (0.3, 0.95)}
"""Where the landmarks MediaPipe's upper body uses lie in a person's box (fractions of its width
and height, the person's left at the right of the image, as seen from the front)."""


def box_landmarks(box) -> np.ndarray:
    """``(33, 2)`` landmarks of a person whose bright box is ``x0, y0, x1, y1`` (the box's
    pixel edges; the unused landmarks at its centre)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    landmarks = np.tile([(x0 + x1) / 2, (y0 + y1) / 2], (33, 1))
    for index, (fx, fy) in FRACTIONS.items():
        landmarks[index] = (x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))
    return landmarks


def largest_person(options):
    from scipy import ndimage

    def process(image):
        labels, count = ndimage.label(image[..., 0] > 128)
        if count == 0:
            return None
        sizes = ndimage.sum_labels(np.ones(labels.shape), labels, np.arange(1, count + 1))
        rows, cols = np.nonzero(labels == 1 + int(np.argmax(sizes)))
        height, width = image.shape[:2]
        box = (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1)
        return box_landmarks(box) / [width, height], np.full(33, 0.9), None

    return process, lambda: None, "fake-largest-1.0"


if __name__ == "__main__":
    make = largest_person if os.environ.get("FAKE_DETECTOR") == "largest" else bright_pixels
    raise SystemExit(_mediapipe_worker.main(sys.argv[1:], make_process=make))
