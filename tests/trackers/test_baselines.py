"""The paper's baselines: CONDENSATION with AR(2) dynamics in the 25-d SPM state, its random-walk
ablation, and Cham & Rehg-style multiple-hypothesis tracking (MHT)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import optimistix as optx
import pytest

import jaxtrack
from jaxtrack.body import UPPER_BODY_12, build_template, spm_fit, spm_forward, spm_initial_state
from jaxtrack.data import load_clip
from jaxtrack.likelihoods import make_templates, ncc_log_likelihood
from jaxtrack.priors.dynamics import AR2Dynamics, fit_ar2, random_walk_dynamics
from jaxtrack.trackers import (
    CondensationTracker,
    Engine,
    FrameInChunk,
    Likelihood,
    MHTTracker,
    condensation_tracker,
    mht_tracker,
    random_walk_tracker,
    refine_pose,
    refinement_cost,
    track,
)
from jaxtrack.trackers.mht import _surviving
from jaxtrack.vision import edge_observations, to_grey
from jaxtrack.vision.observations import image_observations

CLIP = "animateddrawings/history_c119d6b/cmu_1006_wave_hello_2"
SIZE = (320, 240)
TRACKED = 8  # frames tracked in the end-to-end tests (the clip's calm start)


def _simulate_ar2(rng, first, second, mean, noise, length):
    x = np.zeros((length, first.size))
    x[:2] = mean
    for t in range(2, length):
        x[t] = (mean + first * (x[t - 1] - mean) + second * (x[t - 2] - mean)
                + noise * rng.standard_normal(first.size))
    return x


def _roots(dynamics: AR2Dynamics) -> np.ndarray:
    """Moduli of the roots of z² − a₁ z − a₂, per dimension."""
    first = np.asarray(dynamics.first_coefficients)
    second = np.asarray(dynamics.second_coefficients)
    pairs = zip(first, second, strict=True)
    return np.array([np.abs(np.roots([1.0, -a, -b])).max() for a, b in pairs])


# ---------------------------------------------------------------- AR(2) fit


def test_fit_ar2_recovers_known_coefficients():
    rng = np.random.default_rng(0)
    first = np.array([1.5, 0.5, 1.8, 0.0])
    second = np.array([-0.7, 0.2, -0.9, 0.0])
    mean = np.array([2.0, -1.0, 0.0, 5.0])
    noise = np.array([0.1, 0.5, 0.01, 1.0])
    states = _simulate_ar2(rng, first, second, mean, noise, 6000)
    dynamics = fit_ar2(states)
    # coefficient standard errors are ~ 1/sqrt(T) ≈ 0.013 here
    np.testing.assert_allclose(dynamics.first_coefficients, first, atol=0.04)
    np.testing.assert_allclose(dynamics.second_coefficients, second, atol=0.04)
    np.testing.assert_allclose(dynamics.noise_std, noise, rtol=0.05)
    stationary_offset = (1 - first - second) * mean
    np.testing.assert_allclose(dynamics.offset, stationary_offset,
                               atol=0.1 * np.abs(mean).max() + 0.05)
    # the one-step prediction is the true conditional mean up to the estimation error
    predicted = dynamics.predict(jnp.asarray(states[1:-1]), jnp.asarray(states[:-2]))
    residual_std = np.std(states[2:] - np.asarray(predicted), axis=0)
    np.testing.assert_allclose(residual_std, noise, rtol=0.05)


def test_fit_ar2_floors_noise_and_stabilises():
    t = np.arange(30.0)
    states = np.stack([
        np.full(30, 3.0),  # constant: no information, becomes a random walk with floor noise
        1.2**t,  # explosive real root 1.2
        1.1**t * np.cos(0.3 * t),  # explosive complex pair of modulus 1.1
        np.sin(0.2 * t),  # a clean stable oscillation (root modulus 1)
    ], axis=1)
    dynamics = fit_ar2(states, min_noise_std=1e-3, max_root=1.0)
    assert np.all(np.asarray(dynamics.noise_std) >= 1e-3)
    assert float(dynamics.noise_std[0]) == pytest.approx(1e-3)
    assert float(dynamics.first_coefficients[0]) == pytest.approx(1.0)
    assert float(dynamics.second_coefficients[0]) == pytest.approx(0.0)
    assert np.all(_roots(dynamics) <= 1.0 + 1e-9)
    unconstrained = fit_ar2(states, ridge=0.0, max_root=10.0)
    assert _roots(unconstrained)[1] == pytest.approx(1.2, abs=0.02)
    assert _roots(unconstrained)[2] == pytest.approx(1.1, abs=0.02)
    # the clean oscillation: cos-recurrence a₁ = 2 cos 0.2, a₂ = −1
    assert float(unconstrained.first_coefficients[3]) == pytest.approx(2 * np.cos(0.2), abs=0.01)
    assert float(unconstrained.second_coefficients[3]) == pytest.approx(-1.0, abs=0.01)
    # a ridge toward the random walk damps it (roots inside the unit circle), more when larger
    roots = [_roots(fit_ar2(states, ridge=ridge, max_root=10.0))[3] for ridge in (1e-4, 1e-2)]
    assert 1.0 > roots[0] > roots[1] > 0.8


def test_fit_ar2_jit_matches_eager_and_float32():
    rng = np.random.default_rng(1)
    states = _simulate_ar2(rng, np.array([1.2, 0.8]), np.array([-0.3, 0.1]), np.zeros(2),
                           np.array([1.0, 0.2]), 40)
    eager = fit_ar2(states)
    with jax.disable_jit():
        unjitted = fit_ar2(states)
    for a, b in zip(jax.tree.leaves(eager), jax.tree.leaves(unjitted), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-10)
    single = fit_ar2(states.astype(np.float32))
    assert single.noise_std.dtype == jnp.float32
    np.testing.assert_allclose(single.first_coefficients, eager.first_coefficients, atol=1e-4)


def test_fit_ar2_rejects_bad_input():
    with pytest.raises(ValueError, match="at least 4 frames"):
        fit_ar2(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        fit_ar2(np.full((10, 2), np.nan))
    with pytest.raises(ValueError, match="positive"):
        fit_ar2(np.ones((10, 2)), min_noise_std=0.0)


def test_ar2_sample_vmap_matches_loop_and_has_the_noise():
    dynamics = AR2Dynamics(jnp.array([1.5, 1.0]), jnp.array([-0.5, 0.0]), jnp.array([0.1, 0.0]),
                           jnp.array([0.3, 2.0]))
    current, previous = jnp.array([1.0, 4.0]), jnp.array([0.5, 3.0])
    keys = jr.split(jr.key(0), 4000)
    batched = jax.vmap(dynamics.sample, in_axes=(0, None, None))(keys, current, previous)
    looped = jnp.stack([dynamics.sample(k, current, previous) for k in keys[:5]])
    np.testing.assert_allclose(batched[:5], looped, rtol=1e-12)
    mean = dynamics.predict(current, previous)
    np.testing.assert_allclose(mean, [1.35, 4.0])
    standard_error = np.asarray(dynamics.noise_std) / np.sqrt(4000)
    assert np.all(np.abs(np.mean(batched, 0) - mean) < 4 * standard_error)
    np.testing.assert_allclose(np.std(batched, 0), dynamics.noise_std, rtol=0.05)


# ---------------------------------------------------------------- the rendered wave


@pytest.fixture(scope="module")
def wave():
    motion = load_clip(CLIP).resample(30.0).select(0, 30)
    camera = jaxtrack.body.frontal_camera(motion, SIZE)
    sequence = jaxtrack.body.render_motion(motion, camera, image_size=SIZE, background="photo",
                                           markers=UPPER_BODY_12, seed=1, progress=False)
    frames = to_grey(sequence.images)
    truth = np.asarray(sequence.markers_2d, np.float64)
    template = build_template(truth)
    states = np.asarray(spm_fit(truth, template))
    torso = float(np.median(np.linalg.norm(truth[:, 3] - truth[:, 1], axis=-1)))
    return dict(frames=np.asarray(frames), truth=truth, template=template, states=states,
                torso=torso)


def _errors(markers, truth):
    return np.linalg.norm(np.asarray(markers) - truth, axis=-1).mean(axis=-1)


def test_ar2_predicts_the_training_frames_better_than_a_random_walk(wave):
    # in-sample one-step prediction: the learned AR(2) beats x_t = x_{t−1} on the 30 frames
    states = wave["states"]
    ar2 = fit_ar2(states)
    walk = random_walk_dynamics(states)
    ar2_error = states[2:] - np.asarray(ar2.predict(states[1:-1], states[:-2]))
    walk_error = states[2:] - np.asarray(walk.predict(states[1:-1], states[:-2]))
    assert np.sum(ar2_error**2) < 0.5 * np.sum(walk_error**2)
    np.testing.assert_allclose(walk.noise_std, np.sqrt(np.mean(np.diff(states, axis=0) ** 2, 0)),
                               rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("make", [condensation_tracker, random_walk_tracker])
def test_condensation_follows_the_first_frames(wave, make):
    tracker = make(wave["template"], wave["states"], engine=Engine(200))
    assert isinstance(tracker, CondensationTracker)
    result = track(tracker, jr.key(0), wave["frames"][:TRACKED], wave["truth"][0],
                   chunk_size=TRACKED - 1, progress=False)
    truth = wave["truth"][:TRACKED]
    assert result.markers.shape == truth.shape
    assert np.all(np.isfinite(result.markers)) and np.all(np.isfinite(result.best_markers))
    assert not result.degenerate.any()
    assert np.all((result.ess > 1) & (result.ess <= 200))
    # frame 0: the initial cloud about the true state (a fraction of a noise step)
    assert _errors(result.markers[:1], truth[:1])[0] < 0.02 * wave["torso"]
    # the clip starts calmly: within 6 % of the torso (≈ 4 px here) on every frame
    assert _errors(result.markers, truth).max() < 0.06 * wave["torso"]


@pytest.mark.parametrize("nearest", [pytest.param(True, marks=pytest.mark.slow), False])
def test_condensation_model_jit_matches_eager(wave, nearest):
    tracker = condensation_tracker(wave["template"], wave["states"], engine=Engine(4),
                                   likelihood=Likelihood(nearest=nearest))
    # the default likelihood observes the grey frame with its edge maps
    frames = edge_observations(wave["frames"][:2])
    model = tracker.start(jr.key(0), frames[0], wave["truth"][0]).model
    frame = jnp.asarray(frames[1])

    def one_particle(key):
        key_init, key_propagate = jr.split(key)
        child = model.propagate(key_propagate, model.init(key_init), 1)
        return child, model.log_likelihood(child, frame), model.markers_of(child)

    jitted = eqx.filter_jit(one_particle)(jr.key(3))
    with jax.disable_jit():
        eager = one_particle(jr.key(3))
    for a, b in zip(jax.tree.leaves(jitted), jax.tree.leaves(eager), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4)


def test_condensation_particles_hold_the_previous_state(wave):
    tracker = condensation_tracker(wave["template"], wave["states"], engine=Engine(4))
    first = edge_observations(wave["frames"][:1])[0]
    model = tracker.start(jr.key(0), first, wave["truth"][0]).model
    particle = model.init(jr.key(0))
    np.testing.assert_array_equal(particle["current"], particle["previous"])
    child = model.propagate(jr.key(1), particle, 1)
    np.testing.assert_array_equal(child["previous"], particle["current"])
    mean = model.dynamics.predict(particle["current"], particle["previous"])
    # one step away by about the learned noise, not more
    z = (child["current"] - mean) / model.dynamics.noise_std
    assert np.all(np.abs(np.asarray(z)) < 6)


def test_condensation_rejects_bad_training_states(wave):
    with pytest.raises(ValueError, match="training_states"):
        condensation_tracker(wave["template"], wave["states"][:, :10])
    with pytest.raises(ValueError, match="num_particles"):
        condensation_tracker(wave["template"], wave["states"], engine=Engine(0))
    with pytest.raises(ValueError, match="initial_spread"):
        condensation_tracker(wave["template"], wave["states"], initial_spread=-1.0)


# ---------------------------------------------------------------- MHT


def _refinement_problem(wave, dtype):
    template = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), wave["template"])
    frame = jnp.asarray(wave["frames"][1], dtype)
    templates = make_templates(jnp.asarray(wave["frames"][0], dtype),
                               jnp.asarray(wave["truth"][0], dtype))
    truth = jnp.asarray(wave["truth"][1], dtype)
    state = spm_initial_state(truth, template)
    # shift the body 3 px and swing both arms by 0.06 rad
    perturbation = jnp.zeros(25, dtype).at[1].set(3.0).at[2].set(-2.0)
    perturbation = perturbation.at[jnp.array([11, 13, 19, 21])].set(0.06)
    return template, frame, templates, truth, state + perturbation


@pytest.mark.parametrize("dtype", [pytest.param(jnp.float32, marks=pytest.mark.slow),
                                   jnp.float64])
def test_refine_pose_reduces_the_ncc_cost(wave, dtype):
    template, frame, templates, truth, start = _refinement_problem(wave, dtype)
    wide = jnp.full(25, 10.0, dtype)  # a weak prior: the image decides

    def ncc_cost(state):
        return -float(ncc_log_likelihood(spm_forward(state, template), frame, templates, 1.0))

    refined, result = jax.jit(lambda s: refine_pose(s, frame, templates, template, s, wide,
                                                    max_steps=20))(start)
    assert refined.dtype == dtype
    assert result in (optx.RESULTS.successful, optx.RESULTS.nonlinear_max_steps_reached)
    before, after = ncc_cost(start), ncc_cost(refined)
    assert after < 0.7 * before
    cost = lambda s: float(refinement_cost(s, frame, templates, template, start, wide))  # noqa: E731
    assert cost(refined) < cost(start)
    # and the markers move toward the truth
    assert (_errors(spm_forward(refined, template), np.asarray(truth))
            < 0.8 * _errors(spm_forward(start, template), np.asarray(truth)))


def test_refinement_cost_is_the_ncc_cost_plus_the_prior(wave):
    template, frame, templates, _, start = _refinement_problem(wave, jnp.float64)
    mean = start + 0.01
    std = jnp.linspace(0.5, 2.0, 25)
    ncc = -ncc_log_likelihood(spm_forward(start, template), frame, templates, 2.5)
    prior = 0.5 * jnp.sum(((start - mean) / std) ** 2)
    np.testing.assert_allclose(refinement_cost(start, frame, templates, template, mean, std, 2.5),
                               ncc + prior, rtol=1e-9)


def test_mht_follows_the_first_frames(wave):
    tracker = mht_tracker(wave["template"], wave["states"], num_modes=6, max_steps=6)
    assert isinstance(tracker, MHTTracker)
    result = track(tracker, jr.key(0), wave["frames"][:TRACKED], wave["truth"][0],
                   chunk_size=TRACKED - 1, progress=False)
    truth = wave["truth"][:TRACKED]
    assert np.all(np.isfinite(result.markers))
    np.testing.assert_allclose(result.markers[0], truth[0], atol=1e-3)  # frame 0 is given
    assert result.ess[0] == 1 and np.all((result.ess[1:] >= 1) & (result.ess[1:] <= 6))
    assert result.num_particles == 6 and not result.degenerate.any()
    assert np.all(result.log_likelihood[1:] <= 0)
    np.testing.assert_array_equal(result.markers, result.best_markers)
    # each mode is refined onto the frame: within 3 % of the torso (≈ 2 px here)
    assert _errors(result.markers, truth).max() < 0.03 * wave["torso"]


def test_mht_scan_matches_a_loop_of_updates(wave):
    # track() scans update over a chunk; one jitted update per frame must give the same track
    # (same settings and chunk as above, so the chunk's compilation is shared)
    frames = wave["frames"][:TRACKED]
    tracker = mht_tracker(wave["template"], wave["states"], num_modes=6, max_steps=6)
    key = jr.key(5)
    scanned = track(tracker, key, frames, wave["truth"][0], chunk_size=TRACKED - 1,
                    progress=False)
    key_start, key_frames = jr.split(key)
    observations = edge_observations(frames[:4])  # what track() adds for the default likelihood
    state = tracker.start(key_start, observations[0], wave["truth"][0])
    update = eqx.filter_jit(tracker.update)
    looped = [tracker.first_estimate(state).markers]
    for frame_key, frame in zip(jr.split(key_frames, TRACKED - 1)[:3], observations[1:],
                                strict=True):
        state, estimate = update(frame_key, state, jnp.asarray(frame))
        looped.append(estimate.markers)
    np.testing.assert_allclose(scanned.markers[:4], np.stack(looped), atol=1e-3)
    assert int(state.pool.time) == 3 and int(state.pool.failed_refinements) == 0


def test_mht_merges_duplicates_and_prunes_unlikely_modes():
    base = np.zeros((12, 2))
    markers = jnp.asarray(np.stack([base, base + 0.5, base + 10.0, base + 20.0, base - 10.0]))
    log_likelihoods = jnp.array([-1.0, -0.5, -1.2, -4.0, jnp.nan])
    kept = _surviving(markers, log_likelihoods, jnp.asarray(2.0), jnp.asarray(1.0))
    # 1 is the best; 0 lies within 2 px of it (merged); 2 is distinct and plausible; 3 is more
    # than 1 nat under the best (pruned); NaN is never kept
    np.testing.assert_array_equal(kept, [False, True, True, False, False])
    every = _surviving(markers, jnp.full(5, jnp.nan), jnp.asarray(2.0), jnp.asarray(1.0))
    assert int(jnp.sum(every)) == 1  # the pool never empties


def test_mht_rejects_bad_input(wave):
    with pytest.raises(ValueError, match="step_std"):
        mht_tracker(wave["template"], step_std=np.ones(3))
    with pytest.raises(ValueError, match="training_states"):
        mht_tracker(wave["template"], wave["states"][:1])
    with pytest.raises(ValueError, match="num_modes"):
        mht_tracker(wave["template"], num_modes=0)
    with pytest.raises(ValueError, match="max_steps"):
        mht_tracker(wave["template"], max_steps=0)
    with pytest.raises(ValueError, match="prune_below"):
        mht_tracker(wave["template"], prune_below=-1.0)


def test_marker_colours_never_put_two_markers_of_one_part_together():
    from jaxtrack.likelihoods.limbs import PART_MARKERS, STRIP_ENDS
    from jaxtrack.trackers._parts_gauss_newton import marker_colours

    colours = marker_colours(PART_MARKERS, 12)
    for markers in PART_MARKERS:
        assert len({colours[marker] for marker in set(markers)}) == len(set(markers)), markers
    # neck and pelvis (read by every strip) alone, the other ten in two colours: 8 tangents
    assert max(colours) + 1 == 4
    # the strips' ends alone (the spine length given apart): the skeleton's tree in 2 colours
    assert max(marker_colours(STRIP_ENDS, 12)) + 1 == 2
    assert marker_colours([(m,) for m in range(12)], 12) == (0,) * 12
    with pytest.raises(ValueError, match="below 12"):
        marker_colours([(0, 12)], 12)


@pytest.mark.parametrize("likelihood", ["markers",
                                        pytest.param("limbs+edges", marks=pytest.mark.slow),
                                        pytest.param("whole-pose terms",
                                                     marks=pytest.mark.slow)])
def test_the_parts_solver_takes_optimistix_steps(wave, likelihood):
    """``refine_pose(solver="parts")`` (Jacobian blocks per likelihood part, own Armijo loop)
    reaches the iterate of optimistix's Armijo Gauss–Newton from the same start (float64),
    also with terms of the whole pose (coverage and keypoints), whose Jacobian it takes
    densely."""
    from jaxtrack.likelihoods import make_appearance_templates

    template, frame, templates, _, start = _refinement_problem(wave, jnp.float64)
    if likelihood != "markers":
        whole = likelihood == "whole-pose terms"
        truth = np.asarray(wave["truth"][:2])
        grey = np.asarray(wave["frames"][:2])
        masks = np.zeros(grey.shape, bool)
        masks[:, 40:-40, 200:-200] = True
        keypoints = (truth + np.random.default_rng(0).normal(0, 4, truth.shape),
                     np.full(truth.shape[:2], 0.9))
        frames = image_observations(grey, masks=masks if whole else None,
                                    keypoints=keypoints if whole else None)
        options = {"coverage_weight": 2.0, "keypoint_weight": 1.5} if whole else {}
        templates = make_appearance_templates("limbs+edges", frames.images[0], wave["truth"][0],
                                              **options)
        assert templates.has_whole_pose_terms == whole
        frame = jax.tree.map(lambda leaf: jnp.asarray(leaf[1], jnp.float64), frames)
    std = jnp.full(25, 0.3, jnp.float64).at[1:3].set(5.0)

    def refined(solver):
        return jax.jit(lambda s: refine_pose(s, frame, templates, template, s, std, 4.0,
                                             max_steps=8, solver=solver))(start)

    (reference, reference_result), (parts, parts_result) = refined("optimistix"), refined("parts")
    np.testing.assert_allclose(parts, reference, atol=1e-8)
    assert parts_result == reference_result
    # the frame given as a FrameInChunk, read in place inside the loop: the same iterate (to
    # rounding: XLA fuses the reads differently)
    frames = jax.tree.map(lambda leaf: jnp.stack([jnp.zeros_like(leaf), leaf]), frame)
    in_place, _ = jax.jit(lambda s, i: refine_pose(s, FrameInChunk(frames, i), templates,
                                                   template, s, std, 4.0, max_steps=8,
                                                   solver="parts"))(start, 1)
    np.testing.assert_allclose(in_place, parts, rtol=0, atol=1e-12)
    assert float(refinement_cost(parts, frame, templates, template, start, std, 4.0)) < float(
        refinement_cost(start, frame, templates, template, start, std, 4.0))
    with pytest.raises(ValueError, match="solver"):
        refine_pose(start, frame, templates, template, start, std, solver="lbfgs")
    with pytest.raises(ValueError, match="FrameInChunk"):
        refine_pose(start, (frames, 1, 0), templates, template, start, std, solver="parts")


def test_fit_ar2_over_several_trajectories_never_fits_across_two():
    rng = np.random.default_rng(0)

    def trajectory(mean, length=300):
        x = np.zeros((length, 2))
        for t in range(2, length):
            x[t] = 1.5 * x[t - 1] - 0.7 * x[t - 2] + rng.normal(0, 0.1, 2)
        return x + mean

    states = np.concatenate([trajectory(0.0), trajectory(50.0)])
    ids = np.repeat([3, 7], 300)
    joint = fit_ar2(states, sequence_ids=ids)
    np.testing.assert_allclose(joint.first_coefficients, 1.5, atol=0.05)
    np.testing.assert_allclose(joint.second_coefficients, -0.7, atol=0.05)
    np.testing.assert_allclose(joint.noise_std, 0.1, atol=0.01)
    # stacked as one trajectory, the jump between the two means inflates the noise
    assert np.all(np.asarray(fit_ar2(states).noise_std) > 2 * np.asarray(joint.noise_std))
    with pytest.raises(ValueError, match="one id per row"):
        fit_ar2(states, sequence_ids=ids[:-1])


def test_mht_never_reports_a_runaway_mode(wave):
    # a pool whose modes ran away (NaN, or far beyond the frame: pixel reads there are clamped
    # and finite, so the likelihood alone would keep them) is a degenerate frame: it reports
    # frame 0's pose and starts again from it, never NaN or a pose off the image
    frames = edge_observations(wave["frames"][:2])
    tracker = mht_tracker(wave["template"], wave["states"], num_modes=6, max_steps=6)
    state = tracker.start(jr.key(0), frames[0], wave["truth"][0])
    update = eqx.filter_jit(tracker.update)
    far = state.pool.modes + 1e6  # every state component: the figure far off the frame
    for modes in (jnp.full_like(state.pool.modes, jnp.nan), far):
        pool = eqx.tree_at(lambda p: (p.modes, p.previous), state.pool, (modes, modes))
        _, estimate = update(jr.key(1), eqx.tree_at(lambda s: s.pool, state, pool),
                             jnp.asarray(frames[1]))
        assert bool(estimate.degenerate)
        np.testing.assert_allclose(estimate.markers, wave["truth"][0], atol=1e-2)
