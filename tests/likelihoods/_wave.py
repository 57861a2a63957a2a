"""Frames rendered from a real wave gesture, shared by the likelihood tests."""

from functools import cache

import numpy as np

from jaxtrack.body import UPPER_BODY_12, frontal_camera, render_motion
from jaxtrack.data import load_clip
from jaxtrack.vision import to_grey


@cache
def rendered_wave() -> tuple[np.ndarray, np.ndarray]:
    """Grey frames ``(10, 480, 640)`` float32 and true markers ``(10, 12, 2)`` float32: the
    bundled AnimatedDrawings wave at 10 fps, frames 10–19, over a real photograph."""
    motion = load_clip("animateddrawings/fair1_wave_hello").resample(10.0)
    camera = frontal_camera(motion, (640, 480))
    sequence = render_motion(motion.select(10, 20), camera, background="photo", seed=0,
                             markers=UPPER_BODY_12, progress=False)
    return to_grey(sequence.images), sequence.markers_2d.astype(np.float32)
