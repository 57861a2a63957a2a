"""Partitioned sampling's stages: which latent dimensions each part moves, which strips weigh
it, and a part's move leaving the other parts where they were (tiny models, no fitting)."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.likelihoods import LIMB_SEGMENTS
from jaxtrack.priors.dynamics import LatentWalk
from jaxtrack.priors.gplvm import GPLVM, UPPER_BODY_PARTS, KernelParameters, PartsGPLVM
from jaxtrack.trackers._partitioned import Stage, _move, stages_of


def _part(seed, dims, rows=20):
    rng = np.random.default_rng(seed)
    latents = rng.normal(size=(rows, 2))
    poses = np.sin(latents @ rng.normal(size=(2, dims)))
    with jax.enable_x64(True):
        return GPLVM.from_active_set(
            KernelParameters.create(1.0, 200.0, 1.0), jnp.asarray(poses - poses.mean(0)),
            jnp.asarray(poses.mean(0)), jnp.asarray(latents), jnp.arange(0, rows, 2),
            dynamics_std=jnp.asarray([0.1, 0.2]), dynamics_fps=30.0)


def _parts_prior():
    links = tuple(UPPER_BODY_PARTS.values())
    return PartsGPLVM(tuple(_part(k, 2 * len(group)) for k, group in enumerate(links)), links,
                      tuple(UPPER_BODY_PARTS))


def test_each_part_moves_its_own_dimensions_and_every_strip_weighs_one_stage():
    stages = stages_of(_parts_prior())
    assert [stage.dims for stage in stages] == [(0, 1), (2, 3), (4, 5)]
    assert [stage.placement for stage in stages] == [True, False, False]
    strips = sorted(strip for stage in stages for strip in stage.strips)
    assert strips == list(range(len(LIMB_SEGMENTS)))
    names = [[LIMB_SEGMENTS[strip][0] for strip in stage.strips] for stage in stages]
    assert "right forearm and hand" in names[1] and "shoulders" in names[2]
    with pytest.raises(ValueError, match="needs a PartsGPLVM"):
        stages_of(_part(0, 22))


def test_a_partitioned_tracker_needs_parts_and_limb_strips():
    from jaxtrack.body import SPM_MARKERS, build_template
    from jaxtrack.trackers import Likelihood, latent_tracker

    rng = np.random.default_rng(3)
    template = build_template(rng.normal(size=(4, len(SPM_MARKERS), 2)) * 20 + 100)
    with pytest.raises(ValueError, match="limb strips"):
        latent_tracker(_parts_prior(), template, likelihood=Likelihood("markers"),
                       partitioned=True)
    with pytest.raises(ValueError, match="needs a PartsGPLVM"):
        latent_tracker(_part(0, 22), template, partitioned=True)
    with pytest.raises(ValueError, match="the coverage term belongs to no part"):
        latent_tracker(_parts_prior(), template, likelihood=Likelihood(coverage_weight=5.0),
                       partitioned=True)


def test_a_stage_moves_only_its_part_and_the_placement_only_with_the_torso():
    walk = LatentWalk(latent_std=jnp.full(6, 0.5), jump_threshold=jnp.asarray(-jnp.inf),
                      pool=jnp.zeros((4, 6)), placement_std=jnp.full(3, 0.5))
    particle = {"latent": jnp.arange(6.0), "placement": jnp.ones(3)}
    arm = _move(walk, jr.PRNGKey(0), particle, Stage(dims=(2, 3), strips=(3, 4),
                                                     placement=False))
    moved = np.asarray(arm["latent"]) != np.arange(6.0)
    np.testing.assert_array_equal(moved, [False, False, True, True, False, False])
    np.testing.assert_array_equal(arm["placement"], np.ones(3))
    torso = _move(walk, jr.PRNGKey(1), particle, Stage(dims=(0, 1), strips=(0,),
                                                       placement=True))
    assert np.all(np.asarray(torso["placement"]) != 1.0)
    # a jump (threshold +inf: always) lands the part on a training latent's part
    pool = jnp.arange(24.0).reshape(4, 6)
    always = LatentWalk(latent_std=jnp.zeros(6), jump_threshold=jnp.asarray(jnp.inf),
                        pool=pool, placement_std=jnp.zeros(3))
    jumped = np.asarray(_move(always, jr.PRNGKey(2), particle,
                              Stage(dims=(4, 5), strips=(5,), placement=False))["latent"])
    np.testing.assert_array_equal(jumped[:4], np.arange(4.0))
    assert any(np.array_equal(jumped[4:], row[4:]) for row in np.asarray(pool))
