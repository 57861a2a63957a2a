"""Ong & Gong's (2002) linear combinations: global PCA of hybrid vectors, cluster constraints
and cluster dynamics.

    >>> fit = fit_linear_combinations(vectors, sequence_ids, HybridLayout(100, 12))
    >>> model = fit.model
    >>> model.coefficients(vectors[0])                 # eq. 2
    >>> model.constrain(coefficients, cluster)         # eq. 5-6
    >>> model.reconstruct(coefficients)                # eq. 7
"""

from jaxtrack.priors.linear_combinations._ambiguity import (
    nearest_ambiguity,
    select_views,
    training_ambiguity,
    view_scores,
)
from jaxtrack.priors.linear_combinations._fit import (
    LinearCombinationFit,
    fit_linear_combinations,
    kmeans,
    part_weights,
    transition_matrix,
)
from jaxtrack.priors.linear_combinations._io import (
    LinearCombinationFormatError,
    SavedLinearCombinations,
    load_linear_combinations,
    save_linear_combinations,
)
from jaxtrack.priors.linear_combinations._model import LinearCombinationModel

__all__ = [
    "LinearCombinationFit", "LinearCombinationFormatError", "LinearCombinationModel",
    "SavedLinearCombinations", "fit_linear_combinations", "kmeans", "load_linear_combinations",
    "nearest_ambiguity", "part_weights", "save_linear_combinations", "select_views",
    "training_ambiguity", "transition_matrix", "view_scores",
]
