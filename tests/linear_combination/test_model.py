"""The linear-combination model (Ong & Gong 2002, §3-4): eq. 2 / 7 round trips against a NumPy
eigen-decomposition, the ±1 clamp of eq. 5-6, transition counts, k-means, the propagation of
eq. 4-6, and the model file."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.body.hybrid import HybridLayout
from jaxtrack.priors.linear_combinations import (
    LinearCombinationFormatError,
    fit_linear_combinations,
    kmeans,
    load_linear_combinations,
    save_linear_combinations,
    transition_matrix,
)
from jaxtrack.trackers.linear_combination import propagate_particle

LAYOUT = HybridLayout(num_contour=6, num_skeleton=2)


@pytest.fixture(scope="module")
def data():
    """Three well separated groups of vectors on a 4-D linear subspace plus small noise."""
    rng = np.random.default_rng(0)
    latent = np.concatenate([rng.normal(loc, 0.3, size=(60, 4)) for loc in (-3.0, 0.0, 3.0)])
    mixing = rng.normal(size=(4, LAYOUT.size))
    vectors = latent @ mixing + 0.01 * rng.normal(size=(180, LAYOUT.size))
    return vectors, np.repeat([0, 1, 2], 60)


@pytest.fixture(scope="module")
def fit(data):
    vectors, ids = data
    return fit_linear_combinations(vectors, ids, LAYOUT, variance_fraction=0.99,
                                   num_clusters=3)


def test_coefficients_match_numpy_pca(data, fit):
    """eq. 2 against numpy's eigh of the scaled covariance: a_j = e_jᵀ(t − m)/λ_j."""
    vectors, _ = data
    model = fit.model
    weights = np.asarray(model.weights())
    scaled = vectors * weights
    covariance = np.cov(scaled.T)
    values, vectors_np = np.linalg.eigh(covariance)
    order = np.argsort(values)[::-1][:model.num_components]
    np.testing.assert_allclose(np.asarray(model.eigenvalues), values[order], rtol=1e-8)
    expected = (scaled[5] - scaled.mean(axis=0)) @ vectors_np[:, order] / values[order]
    got = np.asarray(model.coefficients(jnp.asarray(vectors[5])))
    signs = np.sign(got * expected)  # eigenvectors are defined up to sign
    np.testing.assert_allclose(got, signs * expected, rtol=1e-6, atol=1e-10)


def test_round_trip_eq2_eq7(fit):
    model = fit.model
    coefficients = jnp.asarray(np.random.default_rng(1).normal(size=model.num_components))
    vector = model.reconstruct(coefficients)
    np.testing.assert_allclose(model.coefficients(vector), coefficients, rtol=1e-9, atol=1e-9)
    again = model.reconstruct(model.coefficients(vector))
    np.testing.assert_allclose(again, vector, rtol=1e-9, atol=1e-9)


def test_clamp_to_the_cluster_box(fit):
    """eq. 5-6: every training member lies in its cluster's box and is kept by the clamp (up
    to the part outside the local subspace); a far point lands on the box's surface."""
    model = fit.model
    for index in range(0, 180, 7):
        cluster = model.training_clusters[index]
        coefficients = model.training_coefficients[index]
        coordinates = model.cluster_coordinates(coefficients, cluster)
        assert np.all(np.abs(np.asarray(coordinates)) <= 1 + 1e-9)
    cluster = jnp.asarray(1)
    far = model.cluster_means[1] + 50.0 * model.local_bases[1][:, 0] * model.local_extents[1, 0]
    clamped = model.constrain(far, cluster)
    coordinates = np.asarray(model.cluster_coordinates(clamped, cluster))
    assert coordinates[0] == pytest.approx(1.0)
    assert np.all(np.abs(coordinates) <= 1 + 1e-12)
    inside = model.cluster_means[1] + model.local_bases[1] @ (0.5 * model.local_extents[1])
    np.testing.assert_allclose(model.constrain(inside, cluster), inside, atol=1e-12)


def test_transition_counts_on_a_tiny_sequence():
    labels = np.array([0, 0, 1, 1, 2, 0, 1, 1])
    ids = np.array([7, 7, 7, 7, 7, 9, 9, 9])  # the pair (2 -> 0) spans two sequences
    matrix, counts, unseen = transition_matrix(labels, ids, 4)
    expected = np.zeros((4, 4))
    for a, b in [(0, 0), (0, 1), (1, 1), (1, 2), (0, 1), (1, 1)]:
        expected[a, b] += 1
    np.testing.assert_array_equal(counts, expected)
    assert unseen == (2, 3)  # cluster 2 only ends a sequence, cluster 3 is never seen
    np.testing.assert_allclose(matrix[0], [1 / 3, 2 / 3, 0, 0])
    np.testing.assert_allclose(matrix[1], [0, 2 / 3, 1 / 3, 0])
    np.testing.assert_allclose(matrix[2], [0, 0, 1, 0])
    np.testing.assert_allclose(matrix[3], [0, 0, 0, 1])
    floored, _, _ = transition_matrix(labels, ids, 4, floor=1.0)
    np.testing.assert_allclose(floored[0], np.array([2, 3, 1, 1]) / 7)


def test_kmeans_finds_separated_groups(data):
    vectors, groups = data
    _, labels = kmeans(vectors, 3, seed=3)
    for group in range(3):  # each true group is one cluster
        assert len(np.unique(labels[groups == group])) == 1
    assert len(np.unique(labels)) == 3


def test_propagation_jumps_by_the_transition_matrix_and_stays_in_the_box(fit):
    model = fit.model
    # force every cluster to jump to the next one
    model = jax.tree_util.tree_map(lambda x: x, model)
    forced = jnp.roll(jnp.eye(3), 1, axis=1)
    import equinox as eqx
    model = eqx.tree_at(lambda m: m.transition, model, forced)
    keys = jr.split(jr.PRNGKey(0), 64)
    clusters = jnp.zeros(64, jnp.int32)
    start = jnp.tile(model.cluster_means[0], (64, 1))
    step = jax.jit(jax.vmap(propagate_particle, in_axes=(None, 0, 0, 0, None, None)))
    new_clusters, new = step(model, keys, clusters, start, jnp.asarray(5.0), jnp.asarray(5.0))
    assert np.all(np.asarray(new_clusters) == 1)
    coordinates = jax.vmap(model.cluster_coordinates)(new, new_clusters)
    assert np.all(np.abs(np.asarray(coordinates)) <= 1 + 1e-9)
    assert np.any(np.isclose(np.abs(np.asarray(coordinates)), 1.0))  # ω = 5 boxes: clamped
    # with U = I a particle stays in its cluster and moves by P_b Λ_b Ω
    model = eqx.tree_at(lambda m: m.transition, model, jnp.eye(3))
    stay_clusters, moved = step(model, keys, clusters, start, jnp.asarray(0.1), jnp.asarray(5.0))
    assert np.all(np.asarray(stay_clusters) == 0)
    offsets = np.asarray(jax.vmap(model.cluster_coordinates, in_axes=(0, None))(moved, 0))
    assert 0.05 < offsets.std() < 0.15  # ω = 0.1 of the box


def test_save_load_round_trip_and_bad_files(fit, tmp_path):
    path = save_linear_combinations(tmp_path / "model.npz", fit.model, description={"a": 1},
                                    arrays={"training_vectors": np.ones((2, LAYOUT.size))})
    saved = load_linear_combinations(path)
    for name in ("mean", "basis", "local_bases", "transition", "training_clusters"):
        np.testing.assert_array_equal(np.asarray(getattr(saved.model, name)),
                                      np.asarray(getattr(fit.model, name)))
    assert saved.description == {"a": 1} and saved.model.layout == LAYOUT
    other = tmp_path / "other.npz"
    np.savez(other, metadata=np.array('{"format": "jaxtrack.gplvm", "format_version": 1}'))
    with pytest.raises(LinearCombinationFormatError, match="not a jaxtrack linear-combination"):
        load_linear_combinations(other)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:200])
    with pytest.raises(LinearCombinationFormatError, match="damaged or truncated"):
        load_linear_combinations(truncated)
    text = tmp_path / "model.txt"
    text.write_text("hello")
    with pytest.raises(LinearCombinationFormatError, match="not a .npz archive"):
        load_linear_combinations(text)
    with pytest.raises(FileNotFoundError):
        load_linear_combinations(tmp_path / "missing.npz")


def test_bad_training_input():
    with pytest.raises(ValueError, match="vectors must be"):
        fit_linear_combinations(np.zeros((5, 3)), np.zeros(5), LAYOUT)
    vectors = np.ones((5, LAYOUT.size))
    with pytest.raises(ValueError, match="never vary"):
        fit_linear_combinations(vectors, np.zeros(5), LAYOUT, num_clusters=2)
    vectors = np.random.default_rng(0).normal(size=(5, LAYOUT.size))
    vectors[2, 3] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        fit_linear_combinations(vectors, np.zeros(5), LAYOUT, num_clusters=2)
