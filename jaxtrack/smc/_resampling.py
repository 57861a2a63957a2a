"""Resampling schemes and the gradient estimators that wrap them.

Every resampler maps ``(key, log_weights) -> (ancestors, log_weights)``: normalised log weights
in, indices of the selected parents and the normalised log weights the children carry out.
All schemes draw N uniforms (or one) and search them in the cumulative sum of the weights:
``searchsorted``, O(N log N) time, or for systematic resampling's evenly spaced positions a
histogram of thresholds, O(N) time; O(N) memory for all. (``jax.random.categorical`` with a shape
builds an N×N array; never use it for resampling.)

Selection guarantees, also in float32 where the cumulative sum ends below 1: a particle of zero
weight is never selected (its cumulative-sum interval is empty and the search never returns the
index past the last particle of positive weight), and indices are always in ``[0, N)``.

Gradient semantics (``jax.grad`` of the log evidence with respect to model parameters):

=====================  ===========================================================  =========
wrapper                semantics                                                    cost
=====================  ===========================================================  =========
plain scheme           Resets weights to 1/N: the dependence of the selection on   none
                       the parameters is dropped. **Biased** (pathwise part only).
``StopGradient``       Ścibior & Wood (2021): forward pass unchanged; the carried  one
                       weight w[a]/⊥(w[a]) has value 1 and gradient ∇log w[a], so   gather
                       the estimate of the score is the Fisher-identity estimate,
                       **consistent** (unbiased in the limit of N; the usual
                       log-of-an-unbiased-estimator bias, O(1/N)).
``SoftResampling``     Karkus et al. (2018): sample from q = α w + (1−α)/N, carry  one
                       w[a]/q[a]. α = 1 is plain (no gradient through selection),  gather,
                       α < 1 passes partial gradient: **biased** for α > 0, and    higher
                       the forward pass has higher variance as α → 0.               variance
=====================  ===========================================================  =========
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, Float, Int, PRNGKeyArray

from jaxtrack.smc._random import uniform

LogWeights = Float[Array, " particles"]
Ancestors = Int[Array, " particles"]


def effective_sample_size(log_weights: LogWeights) -> Float[Array, ""]:
    """ESS = 1 / Σ w̄² of (possibly unnormalised) log weights; 0 when every weight is zero."""
    log_normaliser = jax.nn.logsumexp(log_weights)
    log_ess = 2.0 * log_normaliser - jax.nn.logsumexp(2.0 * log_weights)
    return jnp.where(jnp.isfinite(log_normaliser), jnp.exp(log_ess), 0.0)


def _cumulative_weights(log_weights: LogWeights) -> tuple[Array, Array]:
    """Unnormalised weights and their cumulative sum, scaled so the largest weight is 1."""
    log_weights = lax.stop_gradient(log_weights)
    largest = jnp.max(log_weights)
    largest = jnp.where(jnp.isfinite(largest), largest, 0.0)
    weights = jnp.exp(log_weights - largest)
    return weights, jnp.cumsum(weights)


def _search(weights: Array, cumulative: Array, positions: Array) -> Ancestors:
    """Parents of ``positions`` in [0, total): the i with cumulative[i-1] <= u < cumulative[i].

    ``side='right'`` skips empty (zero-weight) intervals; rounding of ``u * total`` up to the
    total is mapped to the last particle of positive weight, never past it.
    """
    indices = jnp.searchsorted(cumulative, positions, side="right")
    return _at_most_last_positive(indices, weights)


def _at_most_last_positive(indices: Array, weights: Array) -> Ancestors:
    """``indices`` clamped to the last particle of positive weight, as int32."""
    last_positive = weights.shape[0] - 1 - jnp.argmax(weights[::-1] > 0)
    return jnp.minimum(indices, last_positive).astype(jnp.int32)


def _sorted_search(weights: Array, cumulative: Array, offset: Array) -> Ancestors:
    """``_search`` for the N evenly spaced positions ``(j + offset) / N × total``, in O(N).

    Position j lies past particle i's cumulative weight when ``j ≥ k_i = ⌈N c_i / total −
    offset⌉``, so ``ancestors[j] = #{i : k_i ≤ j}``: a histogram of the ``k_i`` (one
    scatter-add) and its cumulative sum replace the N binary searches (docs/engine.md,
    "Speed"). A particle of zero weight has ``k_i = k_{i−1}`` and
    is never selected; the last index is clamped as in ``_search``.
    """
    num = weights.shape[0]
    total = cumulative[-1]
    thresholds = jnp.ceil(cumulative * (num / total) - offset)
    thresholds = jnp.clip(thresholds, 0, num).astype(jnp.int32)
    histogram = jnp.zeros(num + 1, jnp.int32).at[thresholds].add(1)
    return _at_most_last_positive(jnp.cumsum(histogram[:num]), weights)



evenly_spaced_ancestors = _sorted_search
"""The ancestors of ``N`` evenly spaced positions ``(j + offset) / N × total`` on the
cumulative weights, in O(N) (the search behind systematic and stratified selection), for
benchmarks and custom resamplers: ``evenly_spaced_ancestors(weights, cumsum(weights),
offset)``."""

def draw_indices(key: PRNGKeyArray, log_weights: LogWeights, num_draws: int) -> Ancestors:
    """``num_draws`` independent indices from the categorical distribution of the weights."""
    weights, cumulative = _cumulative_weights(log_weights)
    uniforms = uniform(key, (num_draws,), dtype=cumulative.dtype)
    return _search(weights, cumulative, uniforms * cumulative[-1])


def multinomial_ancestors(key: PRNGKeyArray, log_weights: LogWeights) -> Ancestors:
    """N independent draws from the categorical distribution of the weights."""
    return draw_indices(key, log_weights, log_weights.shape[0])


def stratified_ancestors(key: PRNGKeyArray, log_weights: LogWeights) -> Ancestors:
    """One uniform draw in each of N equal strata of [0, 1)."""
    weights, cumulative = _cumulative_weights(log_weights)
    num = weights.shape[0]
    uniforms = uniform(key, (num,), dtype=cumulative.dtype)
    positions = (jnp.arange(num, dtype=cumulative.dtype) + uniforms) / num
    return _search(weights, cumulative, positions * cumulative[-1])


def systematic_ancestors(key: PRNGKeyArray, log_weights: LogWeights) -> Ancestors:
    """One uniform offset shared by N evenly spaced positions (lowest variance, O(N))."""
    weights, cumulative = _cumulative_weights(log_weights)
    offset = uniform(key, (), dtype=cumulative.dtype)
    return _sorted_search(weights, cumulative, offset)


def residual_ancestors(key: PRNGKeyArray, log_weights: LogWeights) -> Ancestors:
    """floor(N w̄_i) deterministic copies of each particle, the rest multinomial on the residuals."""
    weights, cumulative = _cumulative_weights(log_weights)
    num = weights.shape[0]
    expected = num * weights / cumulative[-1]
    copies = jnp.floor(expected)
    copies_cumulative = jnp.cumsum(copies)
    num_copies = copies_cumulative[-1].astype(jnp.int32)
    slots = jnp.arange(num)
    deterministic = jnp.searchsorted(copies_cumulative, slots.astype(copies.dtype), side="right")
    residual = expected - copies
    random = _search(residual, jnp.cumsum(residual), uniform(key, (num,), dtype=copies.dtype)
                     * jnp.sum(residual))
    # Slots past the deterministic copies take the residual draws, in order.
    random = random[jnp.clip(slots - num_copies, 0, num - 1)]
    ancestors = jnp.where(slots < num_copies, deterministic, random)
    return jnp.minimum(ancestors, num - 1).astype(jnp.int32)


class Resampler(eqx.Module):
    """``(key, normalised log weights) -> (ancestors, carried normalised log weights)``."""

    @abc.abstractmethod
    def __call__(self, key: PRNGKeyArray, log_weights: LogWeights) -> tuple[Ancestors, LogWeights]:
        ...


def _uniform_log_weights(log_weights: LogWeights) -> LogWeights:
    num = log_weights.shape[0]
    return jnp.full_like(log_weights, -math.log(num))


class Multinomial(Resampler):
    """Multinomial resampling; plain gradient semantics (biased)."""

    def __call__(self, key, log_weights):
        return multinomial_ancestors(key, log_weights), _uniform_log_weights(log_weights)


class Stratified(Resampler):
    """Stratified resampling; plain gradient semantics (biased)."""

    def __call__(self, key, log_weights):
        return stratified_ancestors(key, log_weights), _uniform_log_weights(log_weights)


class Systematic(Resampler):
    """Systematic resampling; plain gradient semantics (biased). The default."""

    def __call__(self, key, log_weights):
        return systematic_ancestors(key, log_weights), _uniform_log_weights(log_weights)


class Residual(Resampler):
    """Residual resampling; plain gradient semantics (biased)."""

    def __call__(self, key, log_weights):
        return residual_ancestors(key, log_weights), _uniform_log_weights(log_weights)


class StopGradient(Resampler):
    """Ścibior & Wood (2021) stop-gradient estimator around any scheme: unchanged forward pass.

    Children carry log w̄[a] − ⊥(log w̄[a]) − log N: the value is the plain −log N, the gradient
    is ∇ log w̄[a], the score of the selection. Summed over frames this yields the
    Fisher-identity estimate of ∇ log p(y_{0:T}) — consistent, at the cost of one gather.
    """

    scheme: Resampler = Systematic()

    def __call__(self, key, log_weights):
        ancestors, carried = self.scheme(key, lax.stop_gradient(log_weights))
        selected = log_weights[ancestors]
        return ancestors, lax.stop_gradient(carried) + selected - lax.stop_gradient(selected)


class SoftResampling(Resampler):
    """Karkus et al. (2018) soft resampling: draw from q = α w̄ + (1 − α)/N, carry w̄[a] / q[a].

    ``alpha = 1`` reproduces plain resampling (no gradient through the selection); smaller
    ``alpha`` lets more gradient through, biased for every α > 0, and raises the variance of the
    forward pass because the carried weights are no longer uniform.
    """

    alpha: Float[Array, ""] | float = 0.5
    scheme: Resampler = Systematic()

    def __check_init__(self):
        if isinstance(self.alpha, int | float) and not 0.0 <= self.alpha <= 1.0:
            raise ValueError(f"SoftResampling alpha must lie in [0, 1], got {self.alpha}")

    def __call__(self, key, log_weights):
        num = log_weights.shape[0]
        alpha = jnp.asarray(self.alpha, dtype=log_weights.dtype)
        log_proposal = jnp.logaddexp(
            jnp.log(alpha) + log_weights, jnp.log1p(-alpha) - math.log(num)
        )
        ancestors, _ = self.scheme(key, lax.stop_gradient(log_proposal))
        carried = log_weights[ancestors] - log_proposal[ancestors]
        return ancestors, carried - jax.nn.logsumexp(carried)
