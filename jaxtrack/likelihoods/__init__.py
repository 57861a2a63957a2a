"""Likelihoods: one particle's fit to one frame's observations, pure JAX (the engine vmaps)."""

from jaxtrack.likelihoods.ncc import (
    DEFAULT_NCC_SHARPNESS,
    NCCTemplates,
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
    "DEFAULT_NCC_SHARPNESS", "NCCTemplates", "make_templates", "ncc_log_likelihood",
    "ncc_log_likelihood_nearest", "ncc_scores", "ncc_scores_nearest", "patch_half_size",
    "sample_patches", "sample_patches_nearest",
]
