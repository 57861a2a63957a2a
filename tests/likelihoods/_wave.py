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


RIGHT_ELBOW, RIGHT_WRIST, LEFT_ELBOW, LEFT_WRIST = 5, 6, 9, 10


def rotate_about(markers, pivot, moved, degrees):
    """``markers`` with the markers ``moved`` turned about marker ``pivot`` by ``degrees``."""
    angle = np.deg2rad(degrees)
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    out = markers.copy()
    out[moved] = (markers[moved] - markers[pivot]) @ rotation.T + markers[pivot]
    return out.astype(np.float32)


def wrong_poses(pose: np.ndarray) -> np.ndarray:
    """``(24, 12, 2)`` poses near ``pose`` that a likelihood should rank below it: each forearm
    turned about its elbow by ±15° and ±30°, and every marker moved 4 px in 16 random ways."""
    directions = np.random.default_rng(0).normal(size=(16, 12, 2))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    turned = [rotate_about(pose, elbow, [wrist], degrees)
              for elbow, wrist in ((RIGHT_ELBOW, RIGHT_WRIST), (LEFT_ELBOW, LEFT_WRIST))
              for degrees in (-30, -15, 15, 30)]
    return np.stack([*turned, *(pose + 4 * directions).astype(np.float32)])
