"""The second-order latent walk: learning the carried share of the last step, and a step of it
(zero noise, so every number is known), whole and one part at a time."""

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.priors.dynamics import LatentVelocity, LatentWalk, fit_latent_velocity


def _trajectories(coefficient, noise, sequences=6, frames=300, seed=0):
    """Latent trajectories whose steps follow Δ_t = a Δ_{t−1} + ω, stacked with their ids."""
    rng = np.random.default_rng(seed)
    rows, ids = [], []
    for sequence in range(sequences):
        step, point = np.zeros(2), rng.normal(size=2)
        for _ in range(frames):
            step = coefficient * step + noise * rng.normal(size=2)
            point = point + step
            rows.append(point.copy())
            ids.append(sequence)
    return np.array(rows), np.array(ids)


def test_fit_recovers_the_carried_share_and_the_noise_within_sequences_only():
    latents, ids = _trajectories(np.array([0.8, 0.3]), np.array([0.05, 0.1]))
    velocity = fit_latent_velocity(latents, ids, fps=30.0)
    np.testing.assert_allclose(np.asarray(velocity.coefficient), [0.8, 0.3], atol=0.05)
    np.testing.assert_allclose(np.asarray(velocity.noise_std), [0.05, 0.1], rtol=0.1)
    assert velocity.fps == 30.0
    # a random walk carries nothing; the steps between two sequences are not counted (each
    # sequence is shifted far away: counted, the jump would pull a towards 0 and σ up)
    walk, walk_ids = _trajectories(np.zeros(2), np.full(2, 0.1), seed=1)
    walk = walk + 100.0 * walk_ids[:, None]
    fitted = fit_latent_velocity(walk, walk_ids)
    assert np.all(np.asarray(fitted.coefficient) < 0.1)
    np.testing.assert_allclose(np.asarray(fitted.noise_std), 0.1, rtol=0.1)
    with pytest.raises(ValueError, match="three consecutive frames"):
        fit_latent_velocity(walk[:4], np.arange(4))
    with pytest.raises(ValueError, match="one sequence id per row"):
        fit_latent_velocity(walk, walk_ids[:-1])


def test_a_step_carries_the_last_one_and_a_jump_carries_none():
    walk = LatentWalk(latent_std=jnp.zeros(4), jump_threshold=jnp.asarray(-jnp.inf),
                      pool=jnp.zeros((3, 4)), placement_std=jnp.zeros(3),
                      velocity=jnp.asarray([0.5, 0.5, 1.0, 0.0]))
    particle = {"latent": jnp.asarray([1.0, 2.0, 3.0, 4.0]), "placement": jnp.ones(3),
                "previous": jnp.asarray([0.0, 0.0, 1.0, 1.0])}
    moved = walk.move(jr.PRNGKey(0), particle)
    np.testing.assert_allclose(moved["latent"], [1.5, 3.0, 5.0, 4.0])
    np.testing.assert_allclose(moved["previous"], particle["latent"])
    # one part: only its dimensions move, and only their x_{t−1}
    part = walk.move(jr.PRNGKey(0), particle, dims=(2, 3), move_placement=False)
    np.testing.assert_allclose(part["latent"], [1.0, 2.0, 5.0, 4.0])
    np.testing.assert_allclose(part["previous"], [0.0, 0.0, 3.0, 4.0])
    # a jump lands on a training latent at rest: x_{t−1} is the landing point
    pool = jnp.arange(12.0).reshape(3, 4)
    always = LatentWalk(latent_std=jnp.zeros(4), jump_threshold=jnp.asarray(jnp.inf),
                        pool=pool, placement_std=jnp.zeros(3), velocity=jnp.ones(4))
    jumped = always.move(jr.PRNGKey(1), particle)
    assert any(np.array_equal(np.asarray(jumped["latent"]), row) for row in np.asarray(pool))
    np.testing.assert_allclose(jumped["previous"], jumped["latent"])
    # without a velocity the particle has no x_{t−1} and the walk is Tian et al.'s
    plain = LatentWalk(latent_std=jnp.zeros(4), jump_threshold=jnp.asarray(-jnp.inf),
                       pool=pool, placement_std=jnp.zeros(3))
    still = plain.move(jr.PRNGKey(0), {"latent": particle["latent"], "placement": jnp.ones(3)})
    assert set(still) == {"latent", "placement"}
    np.testing.assert_allclose(still["latent"], particle["latent"])


def test_the_tracker_refuses_a_velocity_of_another_space_or_frame_rate():
    from jaxtrack.body import SPM_MARKERS, build_template
    from jaxtrack.trackers import latent_tracker
    from tests.trackers.test_partitioned import _parts_prior

    rng = np.random.default_rng(3)
    template = build_template(rng.normal(size=(4, len(SPM_MARKERS), 2)) * 20 + 100)
    prior = _parts_prior()
    two = LatentVelocity(jnp.full(2, 0.5), jnp.full(2, 0.1), 30.0)
    with pytest.raises(ValueError, match="velocity is for a 2-D latent space, the prior's is 6-D"):
        latent_tracker(prior, template, velocity=two)
    six = LatentVelocity(jnp.full(6, 0.5), jnp.full(6, 0.1), 30.0)
    with pytest.raises(ValueError, match="learned at 30 fps and the video is 60 fps"):
        latent_tracker(prior, template, velocity=six, fps=60.0)
    tracker = latent_tracker(prior, template, velocity=six, fps=30.0)
    np.testing.assert_allclose(np.asarray(tracker.latent_std), 0.1)
    assert tracker.options()["latent_velocity"] is True
