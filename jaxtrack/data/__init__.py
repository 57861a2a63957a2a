"""jaxtrack.data: real motion-capture clips and camera calibrations, found by name.

    >>> from jaxtrack.data import load_clip
    >>> motion = load_clip("animateddrawings/fair1_wave_hello")   # bundled, MIT licensed
    >>> motion.positions.shape                                   # (time, joints, 3) metres, Y up
    (839, 27, 3)

A path to a ``.bvh`` file, or to an ``.amc`` file with its ``.asf`` beside it (or given as
``asf=``), works wherever a clip name does (``resolve_clip``).

CMU data: "The data used in this project was obtained from mocap.cs.cmu.edu. The database was
created with funding from NSF EIA-0196217."
"""

from jaxtrack.data._catalogue import (
    COLLECTIONS,
    bundled_folder,
    clip_files,
    data_folders,
    list_clips,
    load_clip,
    path,
    shared_folder,
)
from jaxtrack.data._sources import ClipSource, clip_identity, is_clip_file, resolve_clip

__all__ = ["COLLECTIONS", "ClipSource", "bundled_folder", "clip_files", "clip_identity",
           "data_folders", "is_clip_file", "list_clips", "load_clip", "path", "resolve_clip",
           "shared_folder"]
