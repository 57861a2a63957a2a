"""Gaussian Process Latent Variable Model of poses (Tian, Li & Sclaroff 2005; Lawrence 2004).

    >>> fit = fit_gplvm(poses, latent_dim=2, active_size=200)        # Algorithm 1
    >>> model = fit.model
    >>> jax.vmap(model.mean)(particles)                               # eq. 3, per particle
    >>> model.inverse(poses).latents                                  # eq. 5, μ⁻¹
    >>> model.inverse(poses, objective="reconstruction").latents      # argmin |y − μ(x)|²
    >>> fit_gplvm(poses, active_size=len(poses), iterations=1,        # the exact GPLVM
    ...           optimiser="lbfgs", active_steps=100)
"""

from jaxtrack.priors.gplvm._fit import (
    OPTIMISERS,
    GPLVMFit,
    back_constraint_kernel,
    estimate_dynamics,
    fit_gplvm,
)
from jaxtrack.priors.gplvm._init import initial_latents, isomap, pca
from jaxtrack.priors.gplvm._io import GPLVMFormatError, SavedGPLVM, load_gplvm, save_gplvm
from jaxtrack.priors.gplvm._ivm import entropy_reductions, select_active_set
from jaxtrack.priors.gplvm._kernel import (
    KernelParameters,
    active_objective,
    exact_objective,
    gaussian_process_term,
    kernel_matrix,
    rbf,
)
from jaxtrack.priors.gplvm._model import GPLVM, INVERSE_OBJECTIVES, InverseResult
from jaxtrack.priors.gplvm._parts import (
    UPPER_BODY_PARTS,
    PartsGPLVM,
    feature_columns,
    part_features,
)
from jaxtrack.priors.gplvm._plot import plot_latent_space

__all__ = [
    "GPLVM",
    "INVERSE_OBJECTIVES",
    "OPTIMISERS",
    "UPPER_BODY_PARTS",
    "PartsGPLVM",
    "feature_columns",
    "part_features",
    "GPLVMFit",
    "GPLVMFormatError",
    "SavedGPLVM",
    "InverseResult",
    "KernelParameters",
    "active_objective",
    "back_constraint_kernel",
    "exact_objective",
    "entropy_reductions",
    "estimate_dynamics",
    "fit_gplvm",
    "gaussian_process_term",
    "initial_latents",
    "isomap",
    "kernel_matrix",
    "load_gplvm",
    "plot_latent_space",
    "save_gplvm",
    "pca",
    "rbf",
    "select_active_set",
]
