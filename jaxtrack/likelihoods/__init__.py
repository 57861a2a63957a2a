"""Likelihoods: one particle's fit to one frame's observations, pure JAX (the engine vmaps).

Every appearance likelihood keeps one contract, :class:`PartTemplates` (``_base.py``); the
design page is ``docs/likelihoods.md``.
"""

from jaxtrack.likelihoods._base import PartTemplates, check_markers
from jaxtrack.likelihoods._strips import squared_segment_distances
from jaxtrack.likelihoods.appearance import (
    DEFAULT_LIKELIHOOD,
    LIKELIHOODS,
    AppearanceTemplates,
    default_sharpness,
    make_appearance_templates,
    needs_edges,
)
from jaxtrack.likelihoods.detections import (
    DetectionModel,
    DetectionsFrame,
    detection_model,
    detections_frames,
)
from jaxtrack.likelihoods.detections import log_density as detections_log_density
from jaxtrack.likelihoods.edges import (
    DEFAULT_BORDER_MARGIN,
    DEFAULT_BORDER_SCALES,
    DEFAULT_EDGE_SCALE,
    DEFAULT_EDGE_TOLERANCE,
    DEFAULT_EDGE_WEIGHT,
    EdgeLimbTemplates,
    fit_border_widths,
    limb_edge_distances,
    make_edge_limb_templates,
)
from jaxtrack.likelihoods.limbs import (
    DEFAULT_LIMB_SHARPNESS,
    DEFAULT_STRIP_WIDTH,
    LIMB_SEGMENTS,
    LimbTemplates,
    limb_ncc_log_likelihood,
    limb_ncc_scores,
    limb_points,
    make_limb_templates,
)
from jaxtrack.likelihoods.ncc import (
    DEFAULT_NCC_SHARPNESS,
    NCCTemplates,
    bilinear_sample,
    make_templates,
    ncc_log_likelihood,
    ncc_log_likelihood_nearest,
    ncc_scores,
    ncc_scores_nearest,
    patch_half_size,
    sample_patches,
    sample_patches_nearest,
)

__all__ = [
    "DEFAULT_BORDER_MARGIN", "DEFAULT_BORDER_SCALES", "DEFAULT_EDGE_SCALE",
    "DEFAULT_EDGE_TOLERANCE", "DEFAULT_EDGE_WEIGHT", "DEFAULT_LIKELIHOOD",
    "DEFAULT_LIMB_SHARPNESS", "DEFAULT_NCC_SHARPNESS", "DEFAULT_STRIP_WIDTH", "LIKELIHOODS",
    "LIMB_SEGMENTS",
    "AppearanceTemplates", "DetectionModel", "DetectionsFrame", "EdgeLimbTemplates",
    "LimbTemplates", "NCCTemplates", "PartTemplates",
    "check_markers",
    "bilinear_sample", "default_sharpness", "detection_model",
    "detections_frames", "detections_log_density", "fit_border_widths",
    "limb_edge_distances",
    "make_edge_limb_templates", "needs_edges",
    "limb_ncc_log_likelihood", "limb_ncc_scores", "limb_points", "make_appearance_templates",
    "make_limb_templates", "make_templates", "ncc_log_likelihood", "ncc_log_likelihood_nearest",
    "ncc_scores", "ncc_scores_nearest", "patch_half_size", "sample_patches",
    "sample_patches_nearest", "squared_segment_distances",
]
