"""The mixed-state filter: direct sampling of F (chi-square), projection into the silhouette, the
smoother's posture against brute-force enumeration, temporal integration against the
instantaneous estimate, and frames without a silhouette."""

import itertools

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy import stats

from jaxtrack import smc
from jaxtrack.priors.postures import NUM_POSTURES, POSTURE_NAMES, PostureModel
from jaxtrack.trackers.mixed_state import (
    MixedStateFrame,
    MixedStateModel,
    _project,
    filter_sequence,
    instantaneous_estimates,
    observations_from_silhouettes,
    smooth,
    smooth_backward,
    smooth_fixed_lag,
)
from jaxtrack.vision.parts import nearest_silhouette_points

from ._figures import draw


def _toy_postures(rng, cutoff=1e9):
    """A one-feature posture model with random means, transitions and initial probabilities."""
    transition = rng.dirichlet(np.ones(NUM_POSTURES) * 2, size=NUM_POSTURES)
    initial = rng.dirichlet(np.ones(NUM_POSTURES))
    return PostureModel(jnp.asarray(rng.normal(size=(NUM_POSTURES, 1))),
                        jnp.ones((NUM_POSTURES, 1, 1)), jnp.zeros(NUM_POSTURES),
                        jnp.asarray(np.log(transition)), jnp.asarray(np.log(initial)),
                        jnp.asarray(cutoff))


def _flat_frames(features, size=6):
    """Frames whose silhouette is the whole (small) image and whose hypotheses all coincide:
    the parts then say nothing about the posture."""
    num = len(features)
    grid = np.stack(np.meshgrid(np.arange(size), np.arange(size)), axis=-1).astype(np.int16)
    return MixedStateFrame(jnp.asarray(features, float).reshape(num, 1),
                           jnp.full((num, NUM_POSTURES, 5, 2), 2.0),
                           jnp.asarray(np.broadcast_to(grid, (num, size, size, 2))),
                           jnp.zeros(num, jnp.int32))


def _one_frame(key, model, postures, parts, frame):
    """The engine's step from equally weighted particles (zero velocities) into ``frame``:
    the new particles and the step's info."""
    num = len(postures)
    particles = {"posture": jnp.asarray(postures, jnp.int32), "parts": parts,
                 "velocities": jnp.zeros_like(parts)}
    state = smc.FilterState(particles, jnp.full(num, -np.log(num)), jnp.asarray(0, jnp.int32),
                            jnp.asarray(0.0))
    state, info = eqx.filter_jit(smc.step)(key, state, frame, model)
    return state.particles, info


def test_postures_are_drawn_from_the_rows_of_f():
    rng = np.random.default_rng(0)
    postures = _toy_postures(rng)
    model = MixedStateModel(postures)
    frame = jax_tree_first(_flat_frames([0.7]))
    num = 20000
    log_h = np.asarray(postures.log_likelihoods(frame.features))
    for parent in (1, 3):
        parts = jnp.full((num, 5, 2), 2.0)
        children = _one_frame(jr.PRNGKey(parent), model, np.full(num, parent), parts,
                              frame)[0]["posture"]
        row = np.exp(np.asarray(postures.log_transition)[parent] + log_h)
        expected = num * row / row.sum()
        observed = np.bincount(np.asarray(children), minlength=NUM_POSTURES)
        assert stats.chisquare(observed, expected).pvalue > 1e-3, (observed, expected)


def test_a_particle_that_changes_posture_takes_the_new_postures_hypotheses_only_if_asked():
    """``redraw_on_switch``: parts of a particle whose posture changed are drawn about that
    posture's hypotheses (velocity zero); parts of one that kept its posture are predicted."""
    rng = np.random.default_rng(1)
    postures = _toy_postures(rng)
    size = 40
    grid = np.stack(np.meshgrid(np.arange(size), np.arange(size)), axis=-1).astype(np.int16)
    hypotheses = np.full((NUM_POSTURES, 5, 2), 5.0)
    hypotheses[2] = 30.0  # posture 2's parts are far from where every particle's parts are
    frame = MixedStateFrame(jnp.asarray([0.3]), jnp.asarray(hypotheses), jnp.asarray(grid),
                            jnp.asarray(0, jnp.int32))
    num = 4000
    parts = jnp.full((num, 5, 2), 5.0)
    for redraw in (False, True):
        model = MixedStateModel(postures, position_std=0.5, velocity_std=0.1, initial_std=1.0,
                                initial_velocity_std=0.1, redraw_on_switch=redraw)
        particles, _ = _one_frame(jr.PRNGKey(3), model, np.zeros(num), parts, frame)
        children, moved = np.asarray(particles["posture"]), np.asarray(particles["parts"])
        velocities = particles["velocities"]
        to_two = children == 2
        assert 50 < to_two.sum() < num - 50  # both kinds of particle are there
        centre = moved[to_two].reshape(-1, 2).mean(axis=0)
        np.testing.assert_allclose(centre, [30.0, 30.0] if redraw else [5.0, 5.0], atol=0.5)
        np.testing.assert_allclose(moved[children == 0].reshape(-1, 2).mean(axis=0), 5.0,
                                   atol=0.5)
        if redraw:
            assert np.all(np.asarray(velocities)[to_two] == 0.0)
    with pytest.raises(ValueError, match="redraw_on_switch"):
        MixedStateModel(postures, redraw_on_switch="yes")


def jax_tree_first(frames):
    import jax

    return jax.tree.map(lambda leaf: leaf[0], frames)


def test_parts_outside_the_silhouette_go_to_its_nearest_pixel():
    mask, _ = draw("standing")
    nearest = jnp.asarray(nearest_silhouette_points(mask))
    ys, xs = np.nonzero(mask)
    points = np.array([[50.0, 40.0], [3.0, 3.0], [110.0, 95.0], [-40.0, 500.0], [25.2, 44.9]])
    projected = np.asarray(_project(jnp.asarray(points), nearest))
    for point, moved in zip(points, projected, strict=True):
        column, row = np.clip(np.round(point), 0, [119, 99]).astype(int)
        if mask[row, column]:
            np.testing.assert_array_equal(moved, point)  # inside: untouched
        else:
            distances = np.hypot(xs - column, ys - row)
            assert mask[int(moved[1]), int(moved[0])]
            assert np.hypot(*(moved - [column, row])) == pytest.approx(distances.min())


def _brute_force(postures, features):
    """Posterior posture marginals of the hidden Markov model, by enumeration."""
    log_h = np.array([np.asarray(postures.log_likelihoods(jnp.asarray([f]))) for f in features])
    log_t = np.asarray(postures.log_transition)
    log_pi = np.asarray(postures.log_initial)
    num = len(features)
    sequences = np.array(list(itertools.product(range(NUM_POSTURES), repeat=num)))
    log_p = log_pi[sequences[:, 0]] + log_h[0, sequences[:, 0]]
    for t in range(1, num):
        log_p += log_t[sequences[:, t - 1], sequences[:, t]] + log_h[t, sequences[:, t]]
    weights = np.exp(log_p - log_p.max())
    weights /= weights.sum()
    marginals = np.zeros((num, NUM_POSTURES))
    for t in range(num):
        np.add.at(marginals[t], sequences[:, t], weights)
    filtered = np.zeros((num, NUM_POSTURES))  # forward algorithm for the causal marginals
    alpha = np.exp(log_pi + log_h[0])
    filtered[0] = alpha / alpha.sum()
    for t in range(1, num):
        alpha = (filtered[t - 1] @ np.exp(log_t)) * np.exp(log_h[t])
        filtered[t] = alpha / alpha.sum()
    return marginals, filtered


def test_smoothed_posture_matches_enumeration():
    rng = np.random.default_rng(3)
    postures = _toy_postures(rng)
    features = rng.normal(size=4) * 1.5
    marginals, filtered = _brute_force(postures, features)
    model = MixedStateModel(postures, initial_std=1.0, position_std=0.5, velocity_std=0.5)
    result = filter_sequence(jr.PRNGKey(0), model, _flat_frames(features), 20000)
    smoothed = smooth(result)
    np.testing.assert_allclose(smoothed.posture_probabilities, marginals, atol=0.03)
    np.testing.assert_allclose(result.filtered_posture_probabilities, filtered, atol=0.03)
    clear = np.sort(marginals, axis=1)[:, -1] - np.sort(marginals, axis=1)[:, -2] > 0.1
    np.testing.assert_array_equal(np.asarray(smoothed.posture)[clear],
                                  marginals.argmax(1)[clear])
    # fixed lag: the last frames' lag-smoothed estimate is the whole-sequence one
    lagged = smooth_fixed_lag(result, 3)
    np.testing.assert_allclose(lagged.posture_probabilities, smoothed.posture_probabilities)
    np.testing.assert_allclose(smooth_fixed_lag(result, 0).posture_probabilities,
                               result.filtered_posture_probabilities, atol=1e-12)


@pytest.mark.parametrize("redraw_on_switch", [False, True])
def test_backward_simulation_matches_enumeration(redraw_on_switch):
    """The two-pass smoother's posture marginals are the exact ones too: where the parts say
    nothing, the dynamics' density it weighs by must not tilt the postures."""
    rng = np.random.default_rng(3)
    postures = _toy_postures(rng)
    features = rng.normal(size=4) * 1.5
    marginals, _ = _brute_force(postures, features)
    model = MixedStateModel(postures, initial_std=1.0, position_std=0.5, velocity_std=0.5,
                            redraw_on_switch=redraw_on_switch)
    frames = _flat_frames(features)
    result = filter_sequence(jr.PRNGKey(0), model, frames, 4000)
    backward = smooth_backward(jr.PRNGKey(1), result, model, frames, 4000)
    np.testing.assert_allclose(backward.posture_probabilities, marginals, atol=0.04)
    assert np.all(np.isfinite(np.asarray(backward.parts)))
    with pytest.raises(ValueError, match="num_paths must be at least 1"):
        smooth_backward(jr.PRNGKey(1), result, model, frames, 0)


def _drawn_clip(num_frames=16):
    """The standing figure walking right 2 px a frame; its true parts per frame."""
    mask, truth = draw("standing")
    masks = np.stack([np.roll(mask, 2 * t, axis=1) for t in range(num_frames)])
    truths = np.stack([truth + [2 * t, 0] for t in range(num_frames)])
    return masks, truths


def _figure_postures(cutoff):
    """Per-posture means from the drawn figures' features, unit-ish covariances."""
    from jaxtrack.vision.histograms import projection_histograms

    figures = [draw("standing")[0], draw("sitting")[0], draw("crawling_bending")[0],
               draw("lying_left")[0], draw("lying_left", mirror=True)[0]]
    means = np.stack([projection_histograms(mask, 8) for mask in figures])
    dimension = means.shape[1]
    transition = np.full((NUM_POSTURES, NUM_POSTURES), 0.025) + np.eye(NUM_POSTURES) * 0.875
    return PostureModel(jnp.asarray(means), jnp.broadcast_to(jnp.eye(dimension) / 0.1 ** 2,
                                                             (NUM_POSTURES, dimension, dimension)),
                        jnp.zeros(NUM_POSTURES), jnp.asarray(np.log(transition)),
                        jnp.full(NUM_POSTURES, -np.log(NUM_POSTURES)), jnp.asarray(cutoff))


@pytest.mark.parametrize("redraw_on_switch", [False, True])
def test_temporal_integration_beats_the_instantaneous_estimate(redraw_on_switch):
    # parts carried over a posture switch (the paper's filter) or re-drawn (the default)
    pytest.importorskip("cv2")
    masks, truths = _drawn_clip()
    observations = observations_from_silhouettes(masks, num_bins=8)
    postures = _figure_postures(cutoff=8.0)
    # every third frame the silhouette classifier misfires: its features read "lying left"
    lying = postures.means[POSTURE_NAMES.index("lying_left")]
    misfire = np.arange(len(masks)) % 3 == 2
    features = jnp.where(jnp.asarray(misfire)[:, None], lying, observations.features)
    observations = MixedStateFrame(features, observations.hypotheses, observations.nearest,
                                   observations.status)
    model = MixedStateModel(postures, position_std=1.5, velocity_std=1.0, initial_std=5.0,
                            redraw_on_switch=redraw_on_switch)
    posture, parts = instantaneous_estimates(model, observations)
    smoothed = smooth(filter_sequence(jr.PRNGKey(1), model, observations, 300))
    truth_posture = POSTURE_NAMES.index("standing")
    instantaneous_error = np.mean(np.asarray(posture) != truth_posture)
    assert instantaneous_error == pytest.approx(misfire.mean())
    smoothed_error = np.mean(np.asarray(smoothed.posture) != truth_posture)
    # re-drawn parts make a switch free in the part likelihood, so a misfire costs less
    assert smoothed_error <= (instantaneous_error / 4 if redraw_on_switch else 0.0)
    head_instantaneous = np.mean(np.sum((np.asarray(parts)[:, 0] - truths[:, 0]) ** 2, -1))
    head_smoothed = np.mean(np.sum((np.asarray(smoothed.parts)[:, 0] - truths[:, 0]) ** 2, -1))
    # (4.6x with re-drawn parts here: the frames after a misfire start again from hypotheses)
    factor = 3 if redraw_on_switch else 5
    assert head_smoothed < head_instantaneous / factor, (head_smoothed, head_instantaneous)


def test_frames_without_a_silhouette_are_reported_and_finite():
    pytest.importorskip("cv2")
    masks, _ = _drawn_clip()  # the shapes of the test above: its compiled filter is reused
    masks[2] = False
    masks[4] = True
    observations = observations_from_silhouettes(masks, num_bins=8)
    expected = [0, 0, 1, 0, 2] + [0] * (len(masks) - 5)
    assert np.asarray(observations.status).tolist() == expected
    model = MixedStateModel(_figure_postures(cutoff=8.0))
    result = filter_sequence(jr.PRNGKey(2), model, observations, 300)
    smoothed = smooth(result)
    assert np.asarray(result.status).tolist() == expected
    for leaf in (result.filtered_parts, result.log_weights, result.ess, smoothed.parts,
                 smoothed.posture_probabilities, result.log_evidence_increments):
        assert np.all(np.isfinite(np.asarray(leaf)))
