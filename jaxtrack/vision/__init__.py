"""Image preprocessing with OpenCV, at the edge: frames in, NumPy arrays out; and the one place
frames are drawn on and written as video.

OpenCV (and the optional kornia/torch) is imported lazily inside functions, so importing this
package does not need them.
"""

from jaxtrack.vision.contours import resample_closed_curve, signed_area, silhouette_contour
from jaxtrack.vision.detections import (
    DetectionFileError,
    Detections,
    load_detections,
    read_coco,
    read_detections,
    read_mediapipe,
    read_openpose,
    write_detections,
)
from jaxtrack.vision.edges import edge_distance_maps, edge_observations
from jaxtrack.vision.faces import (
    FaceDetectorUnavailableError,
    detect_face,
    detect_faces,
    face_candidates,
    face_detector_available,
)
from jaxtrack.vision.foreground import (
    foreground_mask,
    head_boxes,
    median_background,
    median_grey_background,
)
from jaxtrack.vision.keypoints import (
    KeypointFileError,
    check_keypoints,
    read_keypoints,
    write_keypoints,
)
from jaxtrack.vision.masks import (
    MaskFileError,
    check_masks,
    masks_for_frames,
    read_masks,
    write_masks,
)
from jaxtrack.vision.overlay import (
    METHOD_COLOURS,
    TRUTH_COLOUR,
    draw_tracks,
    write_overlay_video,
    write_video,
)
from jaxtrack.vision.panels import (
    compose_views,
    contour_panel,
    draw_contour,
    skeleton_panel,
    write_views_video,
)
from jaxtrack.vision.trc import TRC_HEADER_FIELDS, TrcFileError, read_trc, write_trc
from jaxtrack.vision.video import (
    VideoError,
    VideoFrames,
    iter_video_chunks,
    read_video,
    to_grey,
    write_frames,
)

__all__ = [
    "METHOD_COLOURS", "TRC_HEADER_FIELDS", "TRUTH_COLOUR", "DetectionFileError", "Detections",
    "TrcFileError", "read_trc", "write_trc",
    "FaceDetectorUnavailableError", "KeypointFileError", "load_detections", "read_coco",
    "read_detections", "read_mediapipe", "read_openpose", "write_detections",
    "MaskFileError", "VideoError", "VideoFrames", "check_keypoints", "check_masks",
    "compose_views", "contour_panel", "detect_face",
    "detect_faces", "draw_contour", "draw_tracks", "edge_distance_maps", "edge_observations",
    "face_candidates", "face_detector_available", "foreground_mask", "head_boxes",
    "iter_video_chunks", "masks_for_frames", "median_background", "median_grey_background",
    "read_keypoints", "read_masks", "read_video", "resample_closed_curve", "signed_area",
    "silhouette_contour", "skeleton_panel", "to_grey", "write_frames", "write_keypoints",
    "write_masks", "write_overlay_video", "write_video", "write_views_video",
]
