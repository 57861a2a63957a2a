"""Rendered sequences with exact ground truth, and their versioned `.npz` file format.

A file holds the arrays of a :class:`RenderedSequence` plus one JSON string, `metadata`, with the
format name and version, image size, fps, marker names, camera, source clip, seed and render
settings. Silhouettes are stored bit-packed along the width. Files are written atomically (a
temporary file in the same folder, then `os.replace`), so a reader never sees half a file and a
failed write leaves nothing behind.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from jaxtrack._files import write_npz_atomically
from jaxtrack.body.camera import Camera

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "RenderedSequence", "SequenceFormatError",
           "load_sequence", "save_sequence"]

FORMAT_NAME = "jaxtrack.sequence"
FORMAT_VERSION = 1
_ARRAYS = ("images", "silhouettes", "markers_2d", "joints_3d", "visibility")
_CAMERA_FIELDS = ("focal_length", "principal_point", "rotation", "translation", "distortion")


class SequenceFormatError(ValueError):
    """A sequence file is missing, damaged or of another format; the message names the file."""


@dataclass(frozen=True, eq=False)
class RenderedSequence:
    """Frames rendered from real motion, with exact ground truth per frame.

    Attributes:
        images: `(time, height, width, 3)` uint8 RGB.
        silhouettes: `(time, height, width)` bool, the figure's own pixels minus occluders.
        markers_2d: `(time, markers, 2)` float pixels (OpenCV: pixel centres at integers).
        joints_3d: `(time, markers, 3)` float world metres, Y up.
        visibility: `(time, markers)` bool: in the image, not behind a nearer body part, not under
            an occluder.
        marker_names: `(markers,)` names.
        camera: the camera the frames were rendered with (its `image_size` is the frames' size).
        fps: frames per second.
        source: the motion clip the frames come from.
        seed: the render's random seed.
        settings: JSON-able render settings (background, noise, blur, lighting, occluders, ...).
    """

    images: np.ndarray
    silhouettes: np.ndarray
    markers_2d: np.ndarray
    joints_3d: np.ndarray
    visibility: np.ndarray
    marker_names: tuple[str, ...]
    camera: Camera
    fps: float
    source: str
    seed: int
    settings: dict = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return self.images.shape[0]

    @property
    def image_size(self) -> tuple[int, int]:
        """`(width, height)`."""
        return self.images.shape[2], self.images.shape[1]


def _camera_to_json(camera: Camera) -> dict:
    values = {name: np.asarray(getattr(camera, name), dtype=np.float64).tolist()
              for name in _CAMERA_FIELDS}
    return {**values, "image_size": list(camera.image_size), "name": camera.name}


def _camera_from_json(values: dict) -> Camera:
    return Camera(**{name: jnp.asarray(np.array(values[name], dtype=np.float64))
                     for name in _CAMERA_FIELDS},
                  image_size=tuple(int(v) for v in values["image_size"]), name=values["name"])


def save_sequence(path: str | os.PathLike, sequence: RenderedSequence, *,
                  compress: bool = False) -> Path:
    """Write `sequence` to `path` (`.npz`, written as named, atomically). Returns the path.

    Args:
        compress: zlib-compress the arrays (about 3x smaller images, several times slower).
    """
    path = Path(path)
    metadata = {
        "format": FORMAT_NAME, "format_version": FORMAT_VERSION,
        "image_size": list(sequence.image_size), "num_frames": sequence.num_frames,
        "fps": float(sequence.fps), "marker_names": list(sequence.marker_names),
        "camera": _camera_to_json(sequence.camera), "source": sequence.source,
        "seed": int(sequence.seed), "settings": sequence.settings,
    }
    arrays = {
        "images": np.asarray(sequence.images, np.uint8),
        "silhouettes": np.packbits(np.asarray(sequence.silhouettes, bool), axis=-1),
        "markers_2d": np.asarray(sequence.markers_2d, np.float64),
        "joints_3d": np.asarray(sequence.joints_3d, np.float64),
        "visibility": np.asarray(sequence.visibility, bool),
    }
    return write_npz_atomically(path, arrays, metadata, compress=compress, what="settings")


def load_sequence(path: str | os.PathLike) -> RenderedSequence:
    """Read a file written by :func:`save_sequence`.

    Raises:
        SequenceFormatError: the file is missing, truncated or corrupt, of another format or
            version, or lacks an array; the message names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise SequenceFormatError(f"{path}: no such sequence file")
    try:
        with np.load(path, allow_pickle=False) as contents:
            if "metadata" not in contents.files:
                raise SequenceFormatError(f"{path}: not a jaxtrack sequence (no metadata)")
            metadata = json.loads(str(contents["metadata"]))
            if metadata.get("format") != FORMAT_NAME:
                raise SequenceFormatError(f"{path}: format is {metadata.get('format')!r}, "
                                          f"expected {FORMAT_NAME!r}")
            if metadata.get("format_version") != FORMAT_VERSION:
                raise SequenceFormatError(
                    f"{path}: format version {metadata.get('format_version')!r} is not supported "
                    f"(this jaxtrack reads version {FORMAT_VERSION}); re-render the sequence")
            missing = [name for name in _ARRAYS if name not in contents.files]
            if missing:
                raise SequenceFormatError(f"{path}: missing arrays {missing}")
            arrays = {name: contents[name] for name in _ARRAYS}
    except SequenceFormatError:
        raise
    except (OSError, EOFError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as error:
        raise SequenceFormatError(f"{path}: damaged or not an .npz sequence file "
                                  f"({type(error).__name__}: {error})") from error
    try:
        width, height = metadata["image_size"]
        silhouettes = np.unpackbits(arrays["silhouettes"], axis=-1, count=width).astype(bool)
        sequence = RenderedSequence(
            images=arrays["images"], silhouettes=silhouettes, markers_2d=arrays["markers_2d"],
            joints_3d=arrays["joints_3d"], visibility=arrays["visibility"],
            marker_names=tuple(metadata["marker_names"]),
            camera=_camera_from_json(metadata["camera"]), fps=float(metadata["fps"]),
            source=str(metadata["source"]), seed=int(metadata["seed"]),
            settings=dict(metadata.get("settings", {})),
        )
    except (KeyError, TypeError, ValueError) as error:
        raise SequenceFormatError(f"{path}: inconsistent metadata or arrays ({error})") from error
    expected = (sequence.num_frames, height, width)
    if sequence.images.shape != (*expected, 3) or sequence.silhouettes.shape != expected:
        raise SequenceFormatError(f"{path}: images {sequence.images.shape} do not match the "
                                  f"metadata's {sequence.num_frames} frames of {width}x{height}")
    return sequence
