"""Generic sequential Monte Carlo engine: knows nothing of bodies or images.

Models implement ``StateSpaceModel`` for one particle; ``run`` filters a whole sequence in one
compiled ``lax.scan``; ``step`` is the same frame update for online use.
"""

from jaxtrack.smc._batch import auto_chunk_size, run_batch
from jaxtrack.smc._cond import cond_any
from jaxtrack.smc._filter import (
    FilterResult,
    FilterState,
    StepInfo,
    best_particle,
    filter_sequence,
    initialize,
    run,
    step,
    weighted_mean,
)
from jaxtrack.smc._fitting import (
    FitResult,
    adam_update,
    fit_log_evidence,
    log_evidence_and_gradient,
)
from jaxtrack.smc._linear_gaussian import (
    KalmanResult,
    LinearGaussian,
    kalman_filter,
    random_linear_gaussian,
    rts_smoother,
)
from jaxtrack.smc._model import StateSpaceModel
from jaxtrack.smc._random import fast_normal, fast_uniform_bits, particle_keys, split, uniform
from jaxtrack.smc._resampling import (
    Multinomial,
    Resampler,
    Residual,
    SoftResampling,
    StopGradient,
    Stratified,
    Systematic,
    effective_sample_size,
    evenly_spaced_ancestors,
    multinomial_ancestors,
    residual_ancestors,
    stratified_ancestors,
    systematic_ancestors,
)
from jaxtrack.smc._smoothing import (
    LaggedParticles,
    SmoothedPaths,
    discrete_marginals,
    ffbsi,
    fixed_lag_ancestry,
    trace_ancestry,
)

__all__ = [
    "FitResult", "LaggedParticles", "adam_update", "fit_log_evidence", "fixed_lag_ancestry",
    "log_evidence_and_gradient",
    "FilterResult", "FilterState", "KalmanResult", "LinearGaussian", "Multinomial", "Resampler",
    "Residual", "SmoothedPaths", "SoftResampling", "StateSpaceModel", "StepInfo", "StopGradient",
    "Stratified", "Systematic", "auto_chunk_size", "best_particle", "cond_any",
    "discrete_marginals",
    "effective_sample_size", "evenly_spaced_ancestors",
    "fast_normal", "fast_uniform_bits", "ffbsi", "filter_sequence", "initialize",
    "kalman_filter", "particle_keys", "split", "uniform",
    "multinomial_ancestors",
    "random_linear_gaussian", "residual_ancestors", "rts_smoother", "run", "run_batch", "step",
    "stratified_ancestors", "systematic_ancestors", "trace_ancestry", "weighted_mean",
]
