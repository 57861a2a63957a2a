"""Kwatra, Bobick & Johnson (2002), each stage alone on a synthetic sequence whose answer is known:
drawn silhouettes (standing, then lying facing left from frame :data:`SWITCH`), hypotheses with
known noise, posture likelihoods from the drawn figures' histograms.

Stages: the posture likelihood against its histograms (§3.1), the hypotheses against the drawn
parts (§2), F's direct sampling against its rows (eq. 8–9), the smoother's posture against
brute-force enumeration (§3.3), the part likelihood's δ, R and k (eq. 4–7); and what the paper's
gain needs: hypotheses that the true posture makes right and a wrong posture makes wrong."""

import itertools

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy import stats

from jaxtrack.likelihoods.part_distances import PartDistances
from jaxtrack.priors.postures import (
    LYING_LEFT,
    NUM_POSTURES,
    STANDING,
    PostureModel,
    fit_posture_model,
)
from jaxtrack.trackers.mixed_state import (
    MixedStateFrame,
    MixedStateModel,
    filter_sequence,
    instantaneous_estimates,
    observations_from_silhouettes,
    smooth,
)
from jaxtrack.vision.histograms import FRAME_EMPTY, projection_histograms
from jaxtrack.vision.parts import posture_hypotheses

from ..mixed_state._figures import HEAD_RADIUS, draw

pytest.importorskip("cv2")

NUM_FRAMES, SWITCH, BINS = 12, 6, 8
FIGURES = ("standing", "sitting", "crawling_bending", "lying_left", ("lying_left", True))


def _sequence():
    """``(time, 100, 120)`` masks, ``(time, 5, 2)`` true parts and ``(time,)`` postures: the
    figure moving right 1 px a frame, standing, then lying facing left from frame SWITCH on."""
    masks, truths, labels = [], [], []
    for t in range(NUM_FRAMES):
        name, label = ("standing", STANDING) if t < SWITCH else ("lying_left", LYING_LEFT)
        mask, truth = draw(name)
        shift = t % SWITCH
        masks.append(np.roll(mask, shift, axis=1))
        truths.append(truth + [shift, 0])
        labels.append(label)
    return np.stack(masks), np.stack(truths), np.array(labels)


def _figure_features():
    """Each posture's drawn figure's histograms (lying right: lying left mirrored)."""
    features = []
    for figure in FIGURES:
        name, mirror = (figure, False) if isinstance(figure, str) else figure
        features.append(projection_histograms(draw(name, mirror=mirror)[0], BINS))
    return features


def test_posture_likelihoods_are_the_truncated_gaussians_of_their_histograms():
    """§3.1: fitted on noisy copies of each drawn figure's histograms, log p(h | q) is
    −½ min(d_q(h), c) − ½ log|Σ_q| with μ_q, Σ_q the sample mean and ridged covariance of
    posture q's histograms; the drawn sequence's frames are classified as drawn."""
    rng = np.random.default_rng(0)
    centres = _figure_features()
    features = [centre + 0.02 * rng.normal(size=(40, centre.size)) for centre in centres]
    labels = [np.full(40, q) for q in range(NUM_POSTURES)]
    model = fit_posture_model(features, labels, regularisation=0.2, cutoff=30.0)
    everything = np.concatenate(features)
    ridge = 0.2 * np.trace(np.cov(everything.T)) / everything.shape[1]
    probe = centres[0] + 0.03 * rng.normal(size=centres[0].size)
    for q in range(NUM_POSTURES):
        covariance = np.cov(features[q].T) + ridge * np.eye(everything.shape[1])
        difference = probe - features[q].mean(axis=0)
        distance = difference @ np.linalg.solve(covariance, difference)
        expected = -0.5 * min(distance, 30.0) - 0.5 * np.linalg.slogdet(covariance)[1]
        assert float(model.log_likelihoods(jnp.asarray(probe))[q]) == pytest.approx(
            expected, rel=1e-8, abs=1e-8)
    masks, _, truth = _sequence()
    observations = observations_from_silhouettes(masks, num_bins=BINS)
    np.testing.assert_array_equal(np.asarray(model.classify(observations.features)), truth)


def test_hypotheses_find_the_drawn_parts_under_the_true_posture_only():
    """§2: every frame's hypotheses of its own posture lie on the drawn head, hands and feet
    (the head's extreme is a radius out; ends half a stroke); another posture's do not."""
    masks, truths, labels = _sequence()
    for mask, truth, label in zip(masks, truths, labels, strict=True):
        hypotheses = posture_hypotheses(mask)
        own = hypotheses[label]
        head = np.linalg.norm(own[0] - truth[0])
        assert head <= HEAD_RADIUS + 1.5
        for pair in ((1, 2), (3, 4)):
            straight = np.linalg.norm(own[list(pair)] - truth[list(pair)], axis=1)
            crossed = np.linalg.norm(own[list(pair)] - truth[list(pair[::-1])], axis=1)
            best = straight if straight.sum() <= crossed.sum() else crossed
            assert np.all(best <= 5), (label, best)
        wrong = hypotheses[LYING_LEFT if label == STANDING else STANDING]
        assert np.linalg.norm(wrong[0] - truth[0]) > 20


def _toy_postures(rng, cutoff=1e9):
    """One feature: log p(h | q) = −½ (h − μ_q)² exactly (unit precision, no truncation)."""
    transition = rng.dirichlet(np.ones(NUM_POSTURES) * 2, size=NUM_POSTURES)
    initial = rng.dirichlet(np.ones(NUM_POSTURES))
    return PostureModel(jnp.asarray(rng.normal(size=(NUM_POSTURES, 1))),
                        jnp.ones((NUM_POSTURES, 1, 1)), jnp.zeros(NUM_POSTURES),
                        jnp.asarray(np.log(transition)), jnp.asarray(np.log(initial)),
                        jnp.asarray(cutoff))


FLAT = PartDistances((1e6,) * 5)
"""A part likelihood flat over the image (σ_i 10⁶ px): the parts say nothing, so the posture
marginals are those of the posture chain alone (with σ_init, re-drawn parts on a switch would
otherwise sit nearer the hypotheses than carried ones and tilt the posture paths)."""


def _flat_frames(features, status=None, size=6):
    """Frames whose silhouette fills a small image and whose hypotheses coincide for every
    posture: the parts then carry no posture information."""
    num = len(features)
    grid = np.stack(np.meshgrid(np.arange(size), np.arange(size)), axis=-1).astype(np.int16)
    return MixedStateFrame(jnp.asarray(features, float).reshape(num, 1),
                           jnp.full((num, NUM_POSTURES, 5, 2), 2.0),
                           jnp.asarray(np.broadcast_to(grid, (num, size, size, 2))),
                           jnp.zeros(num, jnp.int32) if status is None else jnp.asarray(status))


@pytest.mark.slow  # a compiled filter of 20 000 particles; tests/mixed_state checks F fast
@pytest.mark.parametrize("parent", [0, 3])
def test_f_is_sampled_from_its_rows(parent):
    """Eq. 8–9 through the public filter: every particle starts in ``parent`` (π one-hot, a
    first frame with no silhouette), so frame 2's postures are draws from row ``parent`` of
    F_ij ∝ p(h | j) T_ij (chi-square on 20 000 draws)."""
    rng = np.random.default_rng(1)
    toy = _toy_postures(rng)
    initial = np.full(NUM_POSTURES, 1e-300)
    initial[parent] = 1.0
    postures = eqx.tree_at(lambda m: m.log_initial, toy, jnp.asarray(np.log(initial)))
    # four frames and 20 000 particles, as the enumeration test: one compiled filter for both
    model = MixedStateModel(postures, FLAT, initial_std=1.0, position_std=0.5, velocity_std=0.5)
    frames = _flat_frames([0.0, 0.4, 0.0, 0.0], status=[FRAME_EMPTY, 0, 0, 0])
    num = 20000
    result = filter_sequence(jr.PRNGKey(parent), model, frames, num)
    assert np.all(np.asarray(result.postures[0]) == parent)
    log_h = -0.5 * (0.4 - np.asarray(toy.means)[:, 0, 0]) ** 2
    row = np.exp(np.asarray(toy.log_transition)[parent] + log_h)
    observed = np.bincount(np.asarray(result.postures[1]), minlength=NUM_POSTURES)
    assert stats.chisquare(observed, num * row / row.sum()).pvalue > 1e-3, observed


@pytest.mark.slow  # 20 000 particles; tests/mixed_state/test_filter.py has a fast analogue
def test_smoothed_map_posture_is_the_enumerated_one():
    """§3.3 on a four-frame tiny model: the smoother's posture marginals and MAP posture match
    enumeration of all 5⁴ posture paths of p(q_1:4 | h_1:4) ∝ π T T T Π p(h_t | q_t)."""
    rng = np.random.default_rng(3)
    toy = _toy_postures(rng)
    means = np.asarray(toy.means)[:, 0, 0]
    features = np.array([means[0], means[0] + 0.3, means[2], means[2] - 0.2])  # a switch
    log_pi, log_t = np.asarray(toy.log_initial), np.asarray(toy.log_transition)
    log_h = -0.5 * (features[:, None] - means[None]) ** 2
    marginals = np.zeros((4, NUM_POSTURES))
    for path in itertools.product(range(NUM_POSTURES), repeat=4):
        log_p = log_pi[path[0]] + sum(log_h[t, q] for t, q in enumerate(path)) + sum(
            log_t[a, b] for a, b in itertools.pairwise(path))
        for t, q in enumerate(path):
            marginals[t, q] += np.exp(log_p)
    marginals /= marginals.sum(axis=1, keepdims=True)
    model = MixedStateModel(toy, FLAT, initial_std=1.0, position_std=0.5, velocity_std=0.5)
    smoothed = smooth(filter_sequence(jr.PRNGKey(0), model, _flat_frames(features), 20000))
    np.testing.assert_allclose(smoothed.posture_probabilities, marginals, atol=0.03)
    ordered = np.sort(marginals, axis=1)
    clear = ordered[:, -1] - ordered[:, -2] > 0.1
    assert clear.sum() >= 2
    np.testing.assert_array_equal(np.asarray(smoothed.posture)[clear],
                                  marginals.argmax(axis=1)[clear])


def test_part_likelihood_is_eq_4_to_7():
    """log p(Z | x, q) = −Σ_i min(δ, d_iᵀ R_i⁻¹ d_i) + (|Q| − 1) log k: a full R_i⁻¹, one part
    beyond the cutoff δ, and the other postures' hypotheses entering through k alone."""
    likelihood = PartDistances((2.0, 3.0, 4.0, 5.0, 6.0), cutoff=9.0, log_k=-1.5)
    assert np.allclose(likelihood.inverse_covariances[1], np.eye(2) / 9.0)
    skew = np.array([[0.5, 0.1], [0.1, 0.25]])
    inverse = np.asarray(likelihood.inverse_covariances).copy()
    inverse[0] = skew
    likelihood = eqx.tree_at(lambda m: m.inverse_covariances, likelihood, jnp.asarray(inverse))
    parts = np.zeros((5, 2))
    offsets = np.array([[1.0, 2.0], [3.0, 0.0], [0.0, 8.0], [40.0, 0.0], [0.0, 0.0]])
    hypotheses = np.random.default_rng(0).normal(size=(NUM_POSTURES, 5, 2)) * 50
    hypotheses[2] = parts + offsets
    expected_terms = [offsets[0] @ skew @ offsets[0], 1.0, 4.0, 9.0, 0.0]  # 64/25 > 9: cut
    expected_terms[3] = min(9.0, 40.0 ** 2 / 25.0)
    expected = -sum(expected_terms) + (NUM_POSTURES - 1) * -1.5
    value = likelihood.log_likelihood(jnp.asarray(2), jnp.asarray(parts), jnp.asarray(hypotheses))
    assert float(value) == pytest.approx(expected, rel=1e-12)
    hypotheses[0] += 100.0  # another posture's hypotheses: k stands for them, whatever they are
    again = likelihood.log_likelihood(jnp.asarray(2), jnp.asarray(parts), jnp.asarray(hypotheses))
    assert float(again) == pytest.approx(expected, rel=1e-12)


def _integration_gain(posture_dependent: bool) -> tuple[float, float]:
    """Instantaneous and smoothed MSE (all parts, px²) on the drawn sequence when the
    classifier misfires every third frame (its features read the other posture), hypotheses
    at the drawn parts plus N(0, 2²) noise under the true posture. With ``posture_dependent``
    the wrong posture's hypotheses are its heuristics on the drawn silhouette (far off); else
    every posture's hypotheses are the true posture's (a misfire costs nothing)."""
    masks, truths, labels = _sequence()
    observations = observations_from_silhouettes(masks, num_bins=BINS)
    centres = np.stack(_figure_features())
    transition = np.full((NUM_POSTURES, NUM_POSTURES), 0.02) + np.eye(NUM_POSTURES) * 0.9
    postures = PostureModel(jnp.asarray(centres), jnp.broadcast_to(
        jnp.eye(centres.shape[1]) / 0.1 ** 2, (NUM_POSTURES,) + (centres.shape[1],) * 2),
        jnp.zeros(NUM_POSTURES), jnp.asarray(np.log(transition)),
        jnp.full(NUM_POSTURES, -np.log(NUM_POSTURES)), jnp.asarray(8.0))
    misfire = np.arange(NUM_FRAMES) % 3 == 2
    wrong = np.where(labels == STANDING, LYING_LEFT, STANDING)
    features = np.where(misfire[:, None], centres[wrong], np.asarray(observations.features))
    rng = np.random.default_rng(0)
    hypotheses = np.asarray(observations.hypotheses).copy()
    own = truths + 2.0 * rng.normal(size=truths.shape)
    hypotheses[np.arange(NUM_FRAMES), labels] = own
    if not posture_dependent:
        hypotheses[:] = own[:, None]
    frames = MixedStateFrame(jnp.asarray(features), jnp.asarray(hypotheses),
                             observations.nearest, observations.status)
    model = MixedStateModel(postures, position_std=1.5, velocity_std=1.0, initial_std=5.0)
    posture, parts = instantaneous_estimates(model, frames)
    assert np.mean(np.asarray(posture) != labels) == pytest.approx(misfire.mean())
    smoothed = smooth(filter_sequence(jr.PRNGKey(1), model, frames, 300))
    mse = lambda estimate: float(np.mean(np.sum((np.asarray(estimate) - truths) ** 2, -1)))  # noqa: E731
    return mse(parts), mse(smoothed.parts)


@pytest.mark.slow  # two filter runs on drawn silhouettes
def test_integration_halves_the_error_only_where_a_wrong_posture_misplaces_the_parts():
    """The paper's gain, and why it can vanish: smoothing fixes the misfired frames' posture,
    which lowers the part error only if the wrong posture's hypotheses are worse than the true
    one's; where every posture puts the parts in the same place, it has nothing to fix."""
    instantaneous, smoothed = _integration_gain(posture_dependent=True)
    assert smoothed <= 0.5 * instantaneous, (smoothed, instantaneous)
    instantaneous, smoothed = _integration_gain(posture_dependent=False)
    assert smoothed > 0.5 * instantaneous, (smoothed, instantaneous)



@pytest.mark.slow  # two filter runs of 24 frames, 1000 particles
def test_integration_averages_white_hypothesis_noise_but_not_a_persistent_error():
    """What integration can do with the hypotheses of the right posture: average their error
    over time (papers.kwatra2002.diagnosis.averaging_experiment: hypotheses of known noise,
    a silhouette that fills the image). White noise is averaged (the smoothed MSE well below
    the hypotheses'); an error that persists is not, whatever the filter (why the hands' error
    survives on HDM05: papers/kwatra2002/diagnosis.py).

    Fails with the parts drawn from the dynamics alone (``part_proposal="dynamics"``, the
    paper's and the default): its particles in the 20 dimensions of five parts' positions and
    velocities keep an effective sample size of a few, and the smoothed parts are no less
    noisy than the hypotheses (``python -m papers.kwatra2002.diagnosis --synthetic``)."""
    from papers.kwatra2002.diagnosis import averaging_experiment

    white = averaging_experiment("posterior", 1000, seed=1, noise="white")
    assert white["smoothed"] < 0.75 * white["hypotheses"], white
    persistent = averaging_experiment("posterior", 1000, seed=1, noise="persistent")
    assert persistent["smoothed"] > 0.85 * persistent["hypotheses"], persistent
