"""Bodies: real motion capture, marker sets, cameras, pose representations, renderer.

Motion always comes from a real capture (``load_motion``, ``jaxtrack.data.load_clip``); cameras
project it to 2-D ground truth; the Scaled Prismatic Model and the hybrid vector are the pose
representations the trackers use.
"""

from jaxtrack.body.camera import (
    Camera,
    look_at,
    project,
    project_with_depth,
    read_qca,
    rotation_from_rotation_vector,
    stack_cameras,
    to_camera_frame,
)
from jaxtrack.body.hybrid import HybridLayout, HybridParts, make_hybrid, split_hybrid
from jaxtrack.body.markers import (
    HUMANEVA_15,
    MARKER_EDGES,
    RIG_MARKER_MAPS,
    UPPER_BODY_12,
    MarkerMapError,
    marker_edges,
    marker_joint_indices,
    marker_positions,
)
from jaxtrack.body.motion import MocapFormatError, Motion, load_motion
from jaxtrack.body.render import (
    BACKGROUNDS,
    Lighting,
    fit_camera,
    frontal_camera,
    random_camera,
    render_motion,
    scale_camera,
    stage_for_cameras,
)
from jaxtrack.body.sequence import (
    RenderedSequence,
    SequenceFormatError,
    load_sequence,
    save_sequence,
)
from jaxtrack.body.spm import (
    SPM_LINKS,
    SPM_MARKERS,
    SPM_STATE_NAMES,
    SPM_STATE_SIZE,
    SPMFitInfo,
    SPMTemplate,
    build_template,
    spm_fit,
    spm_fit_with_info,
    spm_forward,
    spm_initial_state,
)
from jaxtrack.body.viewpoints import (
    Viewpoint,
    frame_subject,
    sample_viewpoints,
    viewpoint_direction,
)

__all__ = [
    "BACKGROUNDS", "Lighting", "RenderedSequence", "SequenceFormatError", "fit_camera",
    "frontal_camera", "load_sequence", "random_camera", "render_motion", "save_sequence",
    "scale_camera", "stage_for_cameras",
    "HUMANEVA_15", "MARKER_EDGES", "RIG_MARKER_MAPS", "SPM_LINKS", "SPM_MARKERS",
    "SPM_STATE_NAMES", "SPM_STATE_SIZE", "UPPER_BODY_12", "Camera", "HybridLayout", "HybridParts",
    "MarkerMapError", "MocapFormatError", "Motion", "SPMFitInfo", "SPMTemplate", "Viewpoint",
    "build_template", "frame_subject", "load_motion", "look_at", "make_hybrid",
    "marker_edges", "marker_joint_indices", "marker_positions", "project", "project_with_depth",
    "read_qca", "rotation_from_rotation_vector", "sample_viewpoints", "spm_fit",
    "spm_fit_with_info", "spm_forward", "spm_initial_state", "split_hybrid", "stack_cameras",
    "to_camera_frame", "viewpoint_direction",
]
