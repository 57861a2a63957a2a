"""jaxtrack.data: real motion-capture clips and camera calibrations, found by name.

    >>> from jaxtrack.data import load_clip
    >>> motion = load_clip("animateddrawings/fair1_wave_hello")   # bundled, MIT licensed
    >>> motion.positions.shape                                   # (time, joints, 3) metres, Y up
    (839, 27, 3)

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

__all__ = ["COLLECTIONS", "bundled_folder", "clip_files", "data_folders", "list_clips", "load_clip",
           "path", "shared_folder"]
