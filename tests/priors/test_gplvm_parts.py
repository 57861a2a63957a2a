"""PartsGPLVM: one GPLVM per body part, their latents side by side (no fitting: tiny models)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.priors.gplvm import (
    GPLVM,
    GPLVMFormatError,
    KernelParameters,
    PartsGPLVM,
    load_gplvm,
    part_features,
    save_gplvm,
)

LINKS = ((0, 2), (1,))  # part "a": links 0 and 2 (features 0, 1, 4, 5); part "b": link 1


def _part(seed, dims, rows=40):
    rng = np.random.default_rng(seed)
    latents = rng.normal(size=(rows, 2))
    poses = np.concatenate([np.sin(latents @ rng.normal(size=(2, dims))),
                            np.zeros((rows, 0))], axis=1)
    with jax.enable_x64(True):
        return GPLVM.from_active_set(
            KernelParameters.create(1.0, 200.0, 1.0), jnp.asarray(poses - poses.mean(0)),
            jnp.asarray(poses.mean(0)), jnp.asarray(latents), jnp.arange(0, rows, 2),
            dynamics_std=jnp.asarray([0.1 + seed, 0.2 + seed]), dynamics_fps=30.0)


@pytest.fixture(scope="module")
def model():
    return PartsGPLVM((_part(0, 4), _part(1, 2)), LINKS, ("a", "b"))


def test_mean_puts_each_parts_pose_in_its_links_places(model):
    with jax.enable_x64(True):
        latent = jnp.asarray([0.3, -0.2, 0.5, 0.1])
        pose = np.asarray(model.mean(latent))
        a, b = np.asarray(model.parts[0].mean(latent[:2])), np.asarray(model.parts[1].mean(
            latent[2:]))
    assert pose.shape == (6,)
    np.testing.assert_allclose(pose[[0, 1, 4, 5]], a)
    np.testing.assert_allclose(pose[[2, 3]], b)
    np.testing.assert_allclose(part_features(pose[None], (0, 2))[0], a)
    assert (model.latent_dim, model.pose_dim) == (4, 6)
    np.testing.assert_allclose(model.dynamics_std, [0.1, 0.2, 1.1, 1.2])
    assert model.latents.shape == (40, 4)
    np.testing.assert_allclose(model.latents[:, 2:], model.parts[1].latents)


def test_inverse_of_a_decoded_pose_decodes_to_it_again(model):
    with jax.enable_x64(True):
        latents = model.latents[:3] + 0.05
        poses = jax.vmap(model.mean)(latents)
        rebuilt = model.reconstruct(poses, objective="reconstruction")
        found = model.inverse(poses, objective="reconstruction")
    np.testing.assert_allclose(rebuilt, poses, atol=1e-4)
    assert found.latents.shape == (3, 4)
    assert found.objective.shape == (3,)
    with pytest.raises(ValueError, match=r"poses must have shape \(num_poses, 6\)"):
        model.inverse(jnp.zeros((2, 5)))


def test_parts_must_cover_every_link_once_with_matching_sizes():
    with pytest.raises(ValueError, match="cover links 0..2 once each"):
        PartsGPLVM((_part(0, 4), _part(1, 2)), ((0, 2), (2,)), ("a", "b"))
    with pytest.raises(ValueError, match="part 'b' has 2 links but its GPLVM models 2"):
        PartsGPLVM((_part(0, 2), _part(1, 2)), ((0,), (1, 2)), ("a", "b"))
    with pytest.raises(ValueError, match="different numbers of poses"):
        PartsGPLVM((_part(0, 4), _part(1, 2, rows=30)), LINKS, ("a", "b"))


def test_save_and_load_keep_every_part(model, tmp_path):
    path = save_gplvm(tmp_path / "parts.npz", model, description={"what": "test"},
                      arrays={"labels": np.array(["x"])})
    loaded = load_gplvm(path)
    assert isinstance(loaded.model, PartsGPLVM)
    assert loaded.model.links == LINKS and loaded.model.names == ("a", "b")
    with jax.enable_x64(True):
        latent = jnp.asarray([0.1, 0.2, -0.3, 0.4])
        np.testing.assert_allclose(loaded.model.mean(latent), model.mean(latent), rtol=1e-12)
    assert loaded.description == {"what": "test"}
    # a part's array damaged: refused with the file named
    with np.load(path) as archive:
        contents = {name: archive[name] for name in archive.files}
    contents["part1/weights"] = contents["part1/weights"][:, :1]
    broken = tmp_path / "broken.npz"
    np.savez(broken, **contents)
    with pytest.raises(GPLVMFormatError, match="broken.npz: array 'weights' has shape"):
        load_gplvm(broken)
