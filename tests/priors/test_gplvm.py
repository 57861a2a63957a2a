"""GPLVM: objective and gradients against NumPy, IVM, training on a known GP, μ⁻¹, files."""

import json
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import cho_factor, cho_solve

from jaxtrack.priors.gplvm import (
    GPLVM,
    GPLVMFormatError,
    KernelParameters,
    active_objective,
    entropy_reductions,
    fit_gplvm,
    initial_latents,
    load_gplvm,
    pca,
    save_gplvm,
    select_active_set,
)


def numpy_objective(alpha, beta, gamma, latents, poses):
    """Eq. 1 written out independently with NumPy/SciPy."""
    squared = ((latents[:, None, :] - latents[None, :, :]) ** 2).sum(-1)
    gram = alpha * np.exp(-0.5 * gamma * squared) + (1 / beta + 1e-8 * alpha) * np.eye(len(latents))
    factor = cho_factor(gram, lower=True)
    log_determinant = 2 * np.log(np.diag(factor[0])).sum()
    trace = np.sum(poses * cho_solve(factor, poses))
    return 0.5 * poses.shape[1] * log_determinant + 0.5 * trace + 0.5 * np.sum(latents**2)


def latent_finite_difference(alpha, beta, gamma, latents, poses, i, j, step):
    """Central difference of :func:`numpy_objective` in latent coordinate ``[i, j]``."""
    up, down = latents.copy(), latents.copy()
    up[i, j] += step
    down[i, j] -= step
    return (numpy_objective(alpha, beta, gamma, up, poses)
            - numpy_objective(alpha, beta, gamma, down, poses)) / (2 * step)


def sample_gp_data(seed, n, dims=6, noise=0.02):
    """Poses drawn from a GP over a known 2-D latent space (ring-shaped, so PCA folds it)."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, n)
    radius = rng.uniform(0.8, 1.6, n)
    latents = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    squared = ((latents[:, None] - latents[None]) ** 2).sum(-1)
    gram = np.exp(-0.5 * 4.0 * squared) + 1e-8 * np.eye(n)
    poses = np.linalg.cholesky(gram) @ rng.normal(size=(n, dims))
    return latents, poses + noise * rng.normal(size=poses.shape)


def test_objective_and_gradient_match_numpy_and_finite_differences():
    rng = np.random.default_rng(0)
    latents, poses = rng.normal(size=(9, 2)), rng.normal(size=(9, 3))
    alpha, beta, gamma = 1.3, 20.0, 0.7
    kernel = KernelParameters.create(alpha, beta, gamma)
    value = active_objective(kernel, jnp.asarray(latents), jnp.asarray(poses))
    assert value == pytest.approx(numpy_objective(alpha, beta, gamma, latents, poses), rel=1e-10)

    gradient_kernel, gradient_latents = jax.grad(active_objective, argnums=(0, 1))(
        kernel, jnp.asarray(latents), jnp.asarray(poses))
    step = 1e-6
    for i, j in [(0, 0), (4, 1), (8, 0)]:
        numeric = latent_finite_difference(alpha, beta, gamma, latents, poses, i, j, step)
        assert gradient_latents[i, j] == pytest.approx(numeric, rel=1e-6, abs=1e-7)
    for name, index in (("log_alpha", 0), ("log_beta", 1), ("log_gamma", 2)):
        logs = np.log([alpha, beta, gamma])
        up, down = logs.copy(), logs.copy()
        up[index] += step
        down[index] -= step
        numeric = (numpy_objective(*np.exp(up), latents, poses)
                   - numpy_objective(*np.exp(down), latents, poses)) / (2 * step)
        assert getattr(gradient_kernel, name) == pytest.approx(numeric, rel=1e-6, abs=1e-7)


def test_exact_objective_gradient_matches_autodiff_through_the_cholesky():
    # from FAST_SIZE points on eq. 1 takes its written-out gradient (exact_objective); check it
    # against plain autodiff through jnp.linalg.cholesky and against finite differences
    from jaxtrack.priors.gplvm._kernel import FAST_SIZE

    rng = np.random.default_rng(3)
    latents, poses = rng.normal(size=(FAST_SIZE, 2)), rng.normal(size=(FAST_SIZE, 3))
    alpha, beta, gamma = 1.3, 20.0, 0.7
    kernel = KernelParameters.create(alpha, beta, gamma)

    def autodiff_objective(kernel, latents, poses):
        squared = jnp.sum((latents[:, None] - latents[None]) ** 2, axis=-1)
        gram = kernel.alpha * jnp.exp(-0.5 * kernel.gamma * squared) + (
            kernel.noise_variance + 1e-8 * kernel.alpha) * jnp.eye(len(latents))
        factor = jnp.linalg.cholesky(gram)
        solved = jax.scipy.linalg.cho_solve((factor, True), poses)
        return (poses.shape[1] * jnp.sum(jnp.log(jnp.diagonal(factor)))
                + 0.5 * jnp.sum(poses * solved) + 0.5 * jnp.sum(latents**2))

    arguments = (kernel, jnp.asarray(latents), jnp.asarray(poses))
    value, (gradient_kernel, gradient_latents) = jax.jit(
        jax.value_and_grad(active_objective, argnums=(0, 1)))(*arguments)
    expected_value, (expected_kernel, expected_latents) = jax.jit(
        jax.value_and_grad(autodiff_objective, argnums=(0, 1)))(*arguments)
    assert value == pytest.approx(numpy_objective(alpha, beta, gamma, latents, poses), rel=1e-10)
    assert value == pytest.approx(float(expected_value), rel=1e-10)
    np.testing.assert_allclose(gradient_latents, expected_latents, rtol=1e-8,
                               atol=1e-8 * np.abs(expected_latents).max())
    for name in ("log_alpha", "log_beta", "log_gamma"):
        assert float(getattr(gradient_kernel, name)) == pytest.approx(
            float(getattr(expected_kernel, name)), rel=1e-8)
    for i, j in [(0, 0), (FAST_SIZE - 1, 1)]:
        numeric = latent_finite_difference(alpha, beta, gamma, latents, poses, i, j, 1e-6)
        assert gradient_latents[i, j] == pytest.approx(numeric, rel=1e-5, abs=1e-5)


def test_lbfgs_first_step_is_scaled_by_the_gradient():
    # L-BFGS's first trial step is −∇L; from the Isomap start |∇L| is ~2 600 here (~10⁵ on
    # 1 000 real poses), so unscaled it is halved many times before anything is accepted, as
    # BFGS's still is (its arithmetic is what the tracking priors were validated with). With
    # eq. 1 divided by max|∇L(start)| L-BFGS's first trial is accepted.
    from jaxtrack.priors.gplvm._fit import _optimise_active

    _, poses = sample_gp_data(0, 60)
    centred = poses - poses.mean(axis=0)
    start_latents, _ = initial_latents(centred, 2, "isomap", neighbours=10, seed=0)
    signal = float(np.mean(np.var(centred, axis=0)))
    kernel = KernelParameters.create(signal, 100.0 / signal, 1.0)
    arguments = (kernel, jnp.asarray(start_latents), jnp.asarray(centred))
    start = float(active_objective(*arguments))
    lbfgs = _optimise_active(*arguments, max_steps=2, tolerance=1e-6, optimiser="lbfgs")
    bfgs = _optimise_active(*arguments, max_steps=2, tolerance=1e-6, optimiser="bfgs")
    assert float(lbfgs[2]) < 0.5 * start
    assert float(bfgs[2]) == pytest.approx(start, rel=1e-12)


_INVERSE_SCRIPT = """
import jax, jax.numpy as jnp, numpy as np
from jaxtrack.priors.gplvm._kernel import inverse_from_factor
a = np.random.default_rng(0).normal(size=(30, 30))
matrix = a @ a.T + 30 * np.eye(30)
for x64 in (True, False):
    with jax.enable_x64(x64):
        dtype = jnp.float64 if x64 else jnp.float32
        factor = jnp.linalg.cholesky(jnp.asarray(matrix, dtype))
        inverse = jax.jit(inverse_from_factor)(factor)
        batched = jax.vmap(inverse_from_factor)(jnp.stack([factor, 2 * factor]))
        assert inverse.dtype == dtype, inverse.dtype
        expected = np.linalg.inv(matrix)
        tolerance = (1e-12 if x64 else 1e-5) * np.abs(expected).max()
        np.testing.assert_allclose(inverse, expected, rtol=0, atol=tolerance)
        np.testing.assert_allclose(batched[1], expected / 4, rtol=0, atol=tolerance)
# inside a solver's loop the callback runs in another thread (where the float32 cast struck);
# an exact GPLVM of FAST_SIZE poses is the smallest fit that calls it
from jaxtrack.priors.gplvm import fit_gplvm
from jaxtrack.priors.gplvm._kernel import FAST_SIZE
poses = np.random.default_rng(1).normal(size=(FAST_SIZE, 5))
fit = fit_gplvm(poses, active_size=FAST_SIZE, iterations=1, active_steps=3, progress=False)
print(repr(fit.trace[-1]["objective"]))
"""


def test_inverse_from_factor_is_the_inverse_in_either_precision():
    # eq. 1's VJP takes K⁻¹ from LAPACK's potri through a host callback on CPU. The callback
    # runs in a thread that does not see a ``jax.enable_x64`` context (how training enables
    # float64), which once cast its float64 result to float32 and failed the fit. This test
    # process enables x64 globally, which would hide that: a fresh interpreter, x64 off
    # globally and on in a context, as in any user's script.
    done = subprocess.run([sys.executable, "-c", _INVERSE_SCRIPT], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    from jaxtrack.priors.gplvm._kernel import FAST_SIZE

    poses = np.random.default_rng(1).normal(size=(FAST_SIZE, 5))
    fit = fit_gplvm(poses, active_size=FAST_SIZE, iterations=1, active_steps=3, progress=False)
    assert float(done.stdout.strip().splitlines()[-1]) == pytest.approx(
        fit.trace[-1]["objective"], rel=1e-9)


def test_kernel_matrix_is_the_same_kernel_on_either_side_of_the_fast_size():
    # from FAST_SIZE points on K is built elementwise; below, from |x|² + |x′|² − 2x·x′
    from jaxtrack.priors.gplvm._kernel import FAST_SIZE, kernel_matrix

    latents = np.random.default_rng(2).normal(size=(FAST_SIZE, 2))
    kernel = KernelParameters.create(0.7, 50.0, 1.3)
    with jax.enable_x64(True):
        large = np.asarray(kernel_matrix(kernel, jnp.asarray(latents)))
        small = np.asarray(kernel_matrix(kernel, jnp.asarray(latents[:FAST_SIZE - 1])))
    distances = np.sum((latents[:, None] - latents[None]) ** 2, axis=-1)
    expected = 0.7 * np.exp(-0.65 * distances) + (1 / 50.0 + 1e-8 * 0.7) * np.eye(FAST_SIZE)
    np.testing.assert_allclose(large, expected, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(small, expected[:-1, :-1], rtol=1e-12, atol=1e-14)


def test_ivm_beats_random_active_sets_on_held_out_point_objective():
    latents, poses = sample_gp_data(1, 500, noise=0.1)
    kernel = KernelParameters.create(1.0, 1 / 0.1**2, 4.0)
    train, held_out = slice(0, 200), slice(200, None)
    X, Y = jnp.asarray(latents[train]), jnp.asarray(poses[train])

    def held_out_objective(active):
        model = GPLVM.from_active_set(kernel, Y, jnp.zeros(Y.shape[1]), X, active)
        values = jax.vmap(model.point_objective)(jnp.asarray(latents[held_out]),
                                                 jnp.asarray(poses[held_out]))
        return float(jnp.mean(values))

    chosen = select_active_set(kernel, X, 25)
    assert len(set(np.asarray(chosen).tolist())) == 25
    gains = np.asarray(entropy_reductions(kernel, X, 25))
    assert np.all(np.diff(gains) <= 1e-12)  # greedy: each point is worth less than the last
    rng = np.random.default_rng(0)
    random_values = np.array([held_out_objective(jnp.asarray(rng.choice(200, 25, replace=False)))
                              for _ in range(20)])
    # lower is better; an occasional lucky random set may win, a typical one must not
    ivm_value = held_out_objective(chosen)
    assert ivm_value < np.median(random_values) and np.mean(ivm_value < random_values) >= 0.8, (
        ivm_value, np.sort(random_values))


def test_isomap_unrolls_a_curve_that_pca_folds_and_falls_back_when_disconnected():
    t = np.linspace(0.0, 3 * np.pi, 300)
    spiral = np.stack([t * np.cos(t), t * np.sin(t), 0.1 * np.sin(5 * t)], axis=1)
    latents, how = initial_latents(spiral, 1, "isomap", neighbours=8)
    assert how.startswith("isomap")
    rank = lambda v: np.argsort(np.argsort(v))  # noqa: E731
    assert abs(np.corrcoef(rank(latents[:, 0]), rank(t))[0, 1]) > 0.99
    assert abs(np.corrcoef(rank(pca(spiral, 1)[:, 0]), rank(t))[0, 1]) < 0.9

    two_blobs = np.concatenate([np.random.default_rng(0).normal(size=(40, 3)),
                                np.random.default_rng(1).normal(size=(40, 3)) + 1e3])
    latents, how = initial_latents(two_blobs, 2, "isomap", neighbours=5)
    assert how.startswith("pca (isomap failed") and "components" in how
    assert latents.shape == (80, 2)


@pytest.fixture(scope="module")
def trained():
    latents, poses = sample_gp_data(2, 200)
    train, test = poses[:160], poses[160:]
    ids = np.repeat(np.arange(4), 40)
    fit = fit_gplvm(train, active_size=50, iterations=2, active_steps=150, inactive_steps=30,
                    sequence_ids=ids, fps=30.0, progress=False)
    return fit, train, test


def test_training_reproduces_held_out_gp_data_better_than_pca(trained):
    fit, train, test = trained
    model = fit.model
    assert len(fit.trace) == 2 and all(np.isfinite(r["objective"]) for r in fit.trace)
    # the non-active stage runs in float32 by default; the model it leaves is float64
    assert all(leaf.dtype == jnp.float64 for leaf in jax.tree.leaves(model)
               if jnp.issubdtype(leaf.dtype, jnp.floating))
    reconstruction = np.asarray(model.reconstruct(jnp.asarray(test)))
    gplvm_error = np.sqrt(np.mean((reconstruction - test) ** 2))
    mean = train.mean(0)
    _, _, components = np.linalg.svd(train - mean, full_matrices=False)
    projector = components[:2].T @ components[:2]
    pca_error = np.sqrt(np.mean(((test - mean) @ projector + mean - test) ** 2))
    assert gplvm_error < 0.8 * pca_error, (gplvm_error, pca_error)

    # μ⁻¹ finds the training poses' own latents (or better ones): μ(μ⁻¹(y)) ≈ y as well as
    # the model fits its training data at all
    inverse = model.inverse(jnp.asarray(train))
    at_training = jax.vmap(model.point_objective)(model.latents, jnp.asarray(train))
    assert np.mean(np.asarray(inverse.objective) <= np.asarray(at_training) + 1e-6) > 0.95
    train_reconstruction = np.asarray(jax.vmap(model.mean)(inverse.latents))
    relative = np.linalg.norm(train_reconstruction - train) / np.linalg.norm(train - mean)
    pca_relative = np.linalg.norm((train - mean) @ projector + mean - train) / np.linalg.norm(
        train - mean)
    assert relative < 0.3 and relative < 0.7 * pca_relative, (relative, pca_relative)
    assert np.all(np.isfinite(np.asarray(model.dynamics_std)))
    assert float(model.dynamics_fps) == 30.0


def test_variance_small_at_active_points_and_grows_away(trained):
    model = trained[0].model
    at_active = np.asarray(jax.vmap(model.variance)(model.active_latents))
    prior = float(model.kernel.alpha + model.kernel.noise_variance)
    far = float(model.variance(jnp.array([50.0, 50.0])))
    assert far == pytest.approx(prior, rel=1e-9)
    assert np.median(at_active) < 0.2 * prior
    direction = jnp.array([1.0, 0.0])
    start = model.active_latents[0]
    along = [float(model.variance(start + r * direction)) for r in (0.0, 2.0, 8.0)]
    assert along[0] < along[1] < along[2] + 1e-12


def test_inverse_gradient_matches_finite_differences(trained):
    model, _, test = trained[0].model, trained[1], trained[2]
    pose = jnp.asarray(test[3])
    start = model.initial_latents(pose[None])

    def latent_sum(y):
        return jnp.sum(model.inverse(y[None], initial_latents=start, max_steps=200,
                                     tolerance=1e-12).latents)

    gradient = np.asarray(jax.grad(latent_sum)(pose))
    step = 1e-3  # smaller steps drown in the solver's own tolerance
    for i in range(3):
        bump = jnp.zeros_like(pose).at[i].set(step)
        numeric = (latent_sum(pose + bump) - latent_sum(pose - bump)) / (2 * step)
        assert gradient[i] == pytest.approx(float(numeric), rel=2e-3, abs=1e-5)


def test_save_load_round_trip_and_damaged_files(trained, tmp_path):
    fit, _, test = trained
    path = save_gplvm(tmp_path / "model.npz", fit.model, description={"clips": ["a", "b"]},
                      arrays={"template": np.arange(3.0)}, trace=fit.trace)
    saved = load_gplvm(path)
    poses = jnp.asarray(test[:5])
    assert np.array_equal(np.asarray(saved.model.reconstruct(poses)),
                          np.asarray(fit.model.reconstruct(poses)))
    assert saved.description == {"clips": ["a", "b"]}
    assert np.array_equal(saved.arrays["template"], np.arange(3.0))
    assert len(saved.trace) == 2

    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(GPLVMFormatError, match="truncated.npz: damaged or truncated"):
        load_gplvm(truncated)
    other = tmp_path / "other.npz"
    np.savez(other, metadata=np.array(json.dumps({"format": "jaxtrack.sequence"})))
    with pytest.raises(GPLVMFormatError, match="not a jaxtrack GPLVM"):
        load_gplvm(other)
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        load_gplvm(tmp_path / "missing.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.npz", "other.npz",
                                                          "truncated.npz"]


@pytest.mark.parametrize("optimiser", ["bfgs", "lbfgs"])
def test_active_set_of_every_pose_is_the_exact_gplvm(optimiser):
    # active_size = n skips the IVM (it would select every point) and optimises eq. 1 over all
    # poses: the objective in the trace is eq. 1 of every latent, and μ fits the poses
    _, poses = sample_gp_data(3, 40)
    fit = fit_gplvm(poses, active_size=40, iterations=1, active_steps=60, optimiser=optimiser,
                    progress=False)
    model = fit.model
    assert np.array_equal(np.sort(np.asarray(model.active_indices)), np.arange(40))
    centred = poses - poses.mean(axis=0)
    latents = np.asarray(model.latents)
    with jax.enable_x64(True):
        expected = numpy_objective(float(model.kernel.alpha), float(model.kernel.beta),
                                   float(model.kernel.gamma), latents, centred)
        fitted = np.asarray(jax.vmap(model.mean)(jnp.asarray(latents)))
    np.testing.assert_allclose(fit.trace[-1]["objective"], expected, rtol=1e-6)
    assert np.sqrt(np.mean((fitted - poses) ** 2)) < 0.2 * np.std(poses)


def test_bad_training_input_is_named():
    with pytest.raises(ValueError, match="non-finite"):
        fit_gplvm(np.full((30, 4), np.nan), active_size=10, progress=False)
    with pytest.raises(ValueError, match="active_size"):
        fit_gplvm(np.ones((30, 4)), active_size=2, progress=False)
    with pytest.raises(ValueError, match="init must be"):
        initial_latents(np.ones((30, 4)), 2, "tsne")
    with pytest.raises(ValueError, match="optimiser must be one of"):
        fit_gplvm(np.ones((30, 4)), active_size=10, optimiser="adam", progress=False)


@pytest.mark.parametrize("objective", ["posterior", "reconstruction"])
def test_solver_objective_has_the_derivatives_of_its_objective(trained, objective):
    # μ⁻¹'s BFGS minimises a custom-JVP copy of L′ (or of ½|y − μ|²), its gradient in x from
    # the forward pass; value, x-gradient, x-Hessian and model/pose gradients must be those of
    # the plain objective
    from jaxtrack.priors.gplvm._model import _solver_objective

    model, _, test = trained[0].model, trained[1], trained[2]
    latent, pose = model.latents[7] + 0.05, jnp.asarray(test[0])
    if objective == "posterior":
        plain = lambda x, m, y: m.point_objective(x, y)  # noqa: E731
    else:
        plain = lambda x, m, y: 0.5 * jnp.sum((y - m.mean(x)) ** 2)  # noqa: E731
    ours_fn = lambda x, m, y: _solver_objective(x, m, y, objective)  # noqa: E731
    assert ours_fn(latent, model, pose) == pytest.approx(
        float(plain(latent, model, pose)), rel=1e-12)
    for argnums in (0, (0, 1, 2)):
        ours = jax.grad(ours_fn, argnums=argnums, allow_int=True)(latent, model, pose)
        theirs = jax.grad(plain, argnums=argnums, allow_int=True)(latent, model, pose)
        for a, b in zip(jax.tree.leaves(ours), jax.tree.leaves(theirs), strict=True):
            if jnp.issubdtype(a.dtype, jnp.inexact):
                np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(jax.hessian(ours_fn)(latent, model, pose),
                               jax.hessian(plain)(latent, model, pose), rtol=1e-9, atol=1e-9)


def test_reconstruction_inverse_finds_the_nearest_decoded_pose(trained):
    # argmin_x ½|y − μ(x)|²: no point of a fine latent grid (nor any training latent) decodes
    # closer to the held-out pose than the solution, and the solution is no further than eq. 5's
    model, _, test = trained[0].model, trained[1], trained[2]
    poses = jnp.asarray(test[:6])
    found = model.inverse(poses, objective="reconstruction", max_steps=200)
    assert found.objective.shape == (6,)
    distances = np.linalg.norm(np.asarray(jax.vmap(model.mean)(found.latents)) - test[:6],
                               axis=1)
    np.testing.assert_allclose(0.5 * distances**2, found.objective, rtol=1e-9)
    low, high = np.min(model.latents, 0) - 0.5, np.max(model.latents, 0) + 0.5
    grid = np.stack(np.meshgrid(*[np.linspace(low[i], high[i], 150) for i in range(2)]),
                    -1).reshape(-1, 2)
    candidates = jnp.asarray(np.concatenate([grid, np.asarray(model.latents)]))
    decoded = np.asarray(jax.vmap(model.mean)(candidates))
    best = np.min(np.linalg.norm(decoded[None] - test[:6, None], axis=2), axis=1)
    assert np.all(distances <= best + 1e-6), (distances, best)
    posterior = np.asarray(model.reconstruct(poses))
    assert np.all(distances <= np.linalg.norm(posterior - test[:6], axis=1) + 1e-6)
    with pytest.raises(ValueError, match="objective must be one of"):
        model.inverse(poses, objective="likelihood")


def test_all_poses_model_is_the_projected_process_written_out_with_numpy(trained):
    # μ and σ² from every training pose through the active set (DTC / projected process):
    # μ(x) = k_Iᵀ β Σ K_IN Y, σ² = β⁻¹ + α − k_Iᵀ (K̃⁻¹ − Σ) k_I, Σ = (K̃ + β K_IN K_NI)⁻¹
    model = trained[0].model
    kernel = model.kernel
    with jax.enable_x64(True):
        projected = GPLVM.from_active_set(kernel, model.poses, model.pose_mean, model.latents,
                                          model.active_indices, all_poses=True)
        latents, active = np.asarray(model.latents), np.asarray(model.active_indices)
        alpha, beta, gamma = (float(v) for v in (kernel.alpha, kernel.beta, kernel.gamma))

        def rbf_np(a, b):
            return alpha * np.exp(-0.5 * gamma * ((a[:, None] - b[None]) ** 2).sum(-1))

        noise_free = rbf_np(latents[active], latents[active]) + 1e-6 * alpha * np.eye(len(active))
        cross = rbf_np(latents[active], latents)
        sigma = np.linalg.inv(noise_free + beta * cross @ cross.T)
        points = latents[:20] + 0.1
        k = rbf_np(latents[active], points)  # (active, points)
        mean = np.asarray(model.pose_mean) + k.T @ (beta * sigma @ cross @ np.asarray(model.poses))
        variance = 1 / beta + alpha - np.einsum("ip,ij,jp->p", k, np.linalg.inv(noise_free) - sigma,
                                                k)
        ours_mean, ours_variance = jax.vmap(projected.mean_and_variance)(jnp.asarray(points))
        np.testing.assert_allclose(ours_mean, mean, rtol=1e-7, atol=1e-8)
        np.testing.assert_allclose(ours_variance, variance, rtol=1e-5)
        # the fitted model (fit_gplvm's default all_poses=True) is that projected process
        np.testing.assert_allclose(model.weights, projected.weights, rtol=1e-9, atol=1e-12)
        active_only = GPLVM.from_active_set(kernel, model.poses, model.pose_mean, model.latents,
                                            model.active_indices)
        assert not np.allclose(active_only.weights, projected.weights)


def test_back_constrained_latents_are_a_smooth_function_of_the_poses():
    # Lawrence & Quiñonero-Candela's back-constraint: every latent is g(y) = Σ_c a_c k(y, y_c),
    # so the training latents are g of the training poses and ν comes from their steps
    latents, poses = sample_gp_data(4, 120)
    order = np.argsort(np.arctan2(latents[:, 1], latents[:, 0]))  # one trajectory round the ring
    train, test = poses[order][::2], poses[order][1::2]
    ids = np.zeros(len(train), int)
    fit = fit_gplvm(train, active_size=30, iterations=2, active_steps=80, back_constraint=0.3,
                    sequence_ids=ids, fps=30.0, progress=False)
    model = fit.model
    assert fit.back_constraint["centres"].shape == (30, train.shape[1])
    np.testing.assert_allclose(fit.back_project(train), np.asarray(model.latents), atol=1e-9)
    steps = np.diff(np.asarray(model.latents), axis=0)
    np.testing.assert_allclose(np.asarray(model.dynamics_std), steps.std(axis=0), rtol=1e-9)
    # g is smooth: a small change of the pose moves its latent little
    rng = np.random.default_rng(0)
    nudge = 1e-3 * np.std(train) * rng.normal(size=train.shape)
    moved = np.linalg.norm(fit.back_project(train + nudge) - fit.back_project(train), axis=1)
    assert moved.max() < 0.05 * np.asarray(model.latents).std(), moved.max()
    # μ⁻¹ of a held-out pose (eq. 5, from the nearest active point) still decodes near it,
    # better than 2-component PCA; g alone, from 30 centres, is only a starting point
    reconstruction = np.asarray(model.reconstruct(jnp.asarray(test)))
    mean = train.mean(0)
    _, _, components = np.linalg.svd(train - mean, full_matrices=False)
    pca = (test - mean) @ components[:2].T @ components[:2] + mean
    gplvm_error, pca_error = (np.sqrt(np.mean((reconstruction - test) ** 2)),
                              np.sqrt(np.mean((pca - test) ** 2)))
    assert gplvm_error < 0.8 * pca_error, (gplvm_error, pca_error)
    # bad widths and a free fit are refused in one line
    with pytest.raises(ValueError, match="back_constraint must be a positive width"):
        fit_gplvm(train, active_size=30, back_constraint=0.0, progress=False)
    free = fit_gplvm(train, active_size=30, iterations=1, active_steps=5, progress=False)
    with pytest.raises(ValueError, match="needs a back-constrained fit"):
        free.back_project(test)
    with pytest.raises(ValueError, match="poses must be"):
        fit.back_project(test[:, :3])
