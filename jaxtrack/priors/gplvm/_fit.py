"""Training a GPLVM as Algorithm 1 of Tian, Li & Sclaroff (2005), with jax.grad + optimistix.

    X ← Isomap(Y)
    for t = 1..T:
        I ← IVM(X)                       active set by the information criterion
        α, β, γ, X_I ← argmin L          eq. 1 on the active set, BFGS
        I ← IVM(X)                       reselect with the new kernel
        x_j ← argmin L′(x_j, y_j)        eq. 2, every non-active point alone, one vmapped BFGS

By default μ and σ² (in L′ and in the returned model) come from all poses through the active set
(the projected process, ``all_poses``) rather than from the active poses alone, and the last
iteration repeats the non-active stage once with the model rebuilt (``final_rounds``).

With ``back_constraint`` (Lawrence & Quiñonero-Candela 2006) the latents are not free: every
latent is a smooth function of its pose, x = g(y) = Σ_c a_c k(y, y_c) over fixed centre poses,
and eq. 1 is minimised over A and the kernel instead of X_I; the non-active points take
x_j = g(y_j) (no eq. 2 stage), so poses that are alike get latents that are alike.

Every stage is jitted for its shapes, so the outer loop compiles once. Training runs in float64
(``jax.enable_x64`` inside): the objective holds ln|K| of a matrix whose noise is a small
fraction of its signal.
"""

from __future__ import annotations

import contextlib
import ctypes
import time
from dataclasses import dataclass, field

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import ArrayLike, Float
from tqdm.auto import tqdm

from jaxtrack.priors.gplvm._init import initial_latents
from jaxtrack.priors.gplvm._ivm import select_active_set
from jaxtrack.priors.gplvm._kernel import KernelParameters, active_objective
from jaxtrack.priors.gplvm._model import GPLVM

__all__ = ["GPLVMFit", "OPTIMISERS", "back_constraint_kernel", "estimate_dynamics",
           "fit_gplvm"]


@dataclass(frozen=True)
class GPLVMFit:
    """What :func:`fit_gplvm` returns.

    Attributes:
        model: the trained :class:`GPLVM` (float64; ``model.astype(jnp.float32)`` to track).
        trace: one dict per outer iteration: ``iteration``, ``objective`` (eq. 1 on the active
            set after its optimisation), ``mean_point_objective`` (mean L′ of the non-active
            points after theirs), ``active_size``, ``active_steps``, ``unconverged_points``,
            ``alpha``, ``beta``, ``gamma``, ``seconds``, ``stage_seconds`` (ivm, active,
            inactive). The objective is not monotone: the active set changes between iterations.
        init: how X was initialised (``"isomap (k = 10)"``, ``"pca (isomap failed: ...)"``).
        init_seconds: time spent on that.
        seconds: total wall time.
        back_constraint: a back-constrained fit's width, ``centres`` (``(m, dims)`` centred
            centre poses) and ``weights`` A (``(m, latent)``); None for free latents.
    """

    model: GPLVM
    trace: list[dict] = field(default_factory=list)
    init: str = ""
    init_seconds: float = 0.0
    seconds: float = 0.0
    back_constraint: dict | None = None

    def back_project(self, poses: Float[ArrayLike, "n dims"]) -> np.ndarray:
        """``(n, latent)`` g(y) = Σ_c a_c k(y − ȳ, y_c) of a back-constrained fit: the latent of
        a pose in one kernel product (every training pose's is ``model.latents``)."""
        if self.back_constraint is None:
            raise ValueError("back_project needs a back-constrained fit (fit_gplvm's "
                             "back_constraint); this one has free latents")
        poses = np.asarray(poses, np.float64)
        if poses.ndim != 2 or poses.shape[1] != self.model.pose_dim:
            raise ValueError(f"poses must be (n, {self.model.pose_dim}), got {poses.shape}")
        cross = back_constraint_kernel(poses - np.asarray(self.model.pose_mean),
                                       self.back_constraint["centres"],
                                       self.back_constraint["width"])
        return cross @ self.back_constraint["weights"]


@contextlib.contextmanager
def _single_threaded_blas():
    """Run the block with every loaded OpenBLAS on one thread, then restore its thread count.

    jaxlib's CPU Cholesky and triangular solves call SciPy's OpenBLAS, which splits even a 200 × 200
    factorisation over its threads and waits for them at every call; eq. 1 makes hundreds of
    such calls per BFGS run, and Isomap's eigendecomposition suffers the same (see
    docs/gplvm.md, "Training"). A no-op where no OpenBLAS is found (threadpoolctl does the same
    more generally; it is not a dependency).
    """
    import scipy.linalg.cython_lapack  # noqa: F401  (loads the OpenBLAS jaxlib's LAPACK calls)

    restore = []
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "openblas" in line.lower()}
    except OSError:
        paths = set()
    for path in sorted(paths):
        try:
            library = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in ("scipy_openblas", "openblas"):
            for suffix in ("64_", ""):
                getter = getattr(library, f"{prefix}_get_num_threads{suffix}", None)
                setter = getattr(library, f"{prefix}_set_num_threads{suffix}", None)
                if getter is not None and setter is not None:
                    break
            else:
                continue
            restore.append((setter, getter()))
            setter(1)
            break
    try:
        yield
    finally:
        for setter, threads in restore:
            setter(threads)


OPTIMISERS = ("bfgs", "lbfgs")


def _solver(optimiser: str, tolerance: float):
    if optimiser == "lbfgs":
        return optx.LBFGS(rtol=tolerance, atol=tolerance, history_length=10)
    return optx.BFGS(rtol=tolerance, atol=tolerance)


@eqx.filter_jit
def _optimise_active(kernel: KernelParameters, latents, poses, *, max_steps: int, tolerance,
                     optimiser: str = "bfgs", cross=None):
    """Eq. 1 on the active set over (kernel, X_I); with ``cross`` (the back-constraint kernel
    K(Y_I, Y_C)), ``latents`` are the weights A and X_I = K(Y_I, Y_C) A."""
    solver = _solver(optimiser, tolerance)

    def objective(parameters, data):
        kernel, free = parameters
        return active_objective(kernel, free if cross is None else cross @ free, data)

    scale = 1.0
    if optimiser == "lbfgs":
        # L-BFGS's first trial step is −∇L (its inverse Hessian starts at the identity), and
        # |∇L| at the Isomap start is ~10⁵ (mostly ln β): ~15 Armijo halvings before the first
        # accepted step. L / max|∇L(start)| makes that trial move the steepest coordinate by
        # 1; later steps are scaled by the curvature pairs, whatever L's units. Exact model, 1 000
        # poses, three subsets: eq. 1 after 100 steps 300–450 lower, after 150 steps 170–270.
        gradient = jax.grad(objective)((kernel, latents), poses)
        steepest = jnp.max(jnp.stack([jnp.max(jnp.abs(leaf))
                                      for leaf in jax.tree.leaves(gradient)]))
        scale = jnp.where(jnp.isfinite(steepest) & (steepest > 1.0), steepest, 1.0)
    solution = optx.minimise(
        lambda parameters, data: objective(parameters, data) / scale,
        solver, (kernel, latents), args=poses, max_steps=max_steps, throw=False)
    kernel, latents = solution.value
    return kernel, latents, objective((kernel, latents), poses), solution.result, \
        solution.stats["num_steps"]


def back_constraint_kernel(poses: Float[ArrayLike, "n dims"], centres: Float[ArrayLike, "m dims"],
                           width: float) -> np.ndarray:
    """``(n, m)`` RBF kernel k(y, y_c) = exp(−|y − y_c|² / (2 w²)) of the back-constraint, with w
    ``width`` times the median distance between two centres (unit-free)."""
    poses, centres = np.asarray(poses, np.float64), np.asarray(centres, np.float64)

    def squared(a, b):
        return np.maximum((a**2).sum(1)[:, None] + (b**2).sum(1)[None, :] - 2 * a @ b.T, 0.0)

    between = squared(centres, centres)[np.triu_indices(len(centres), 1)]
    scale = float(np.median(np.sqrt(between))) if between.size else 1.0
    return np.exp(-0.5 * squared(poses, centres) / (width * max(scale, 1e-12)) ** 2)


def _back_constraint_weights(cross: np.ndarray, latents: np.ndarray) -> np.ndarray:
    """A with K A ≈ X by ridge least squares (the ridge 1e-6 of Kᵀ K's mean diagonal)."""
    gram = cross.T @ cross
    ridge = 1e-6 * float(np.mean(np.diag(gram)))
    return np.linalg.solve(gram + ridge * np.eye(len(gram)), cross.T @ latents)


@eqx.filter_jit
def _optimise_inactive(model: GPLVM, current_latents, poses, *, max_steps: int, dtype):
    # eq. 2 in ``dtype`` (float32 by default: the stage is half of training, and μ, σ² of the
    # model are what the trackers evaluate in float32 anyway), the latents returned in float64
    wide = current_latents.dtype
    model, current_latents, poses = (model.astype(dtype), current_latents.astype(dtype),
                                     poses.astype(dtype))
    # start each point at the better of where it is and the best nearby active point
    nearby = model.initial_latents(poses)
    point_objective = jax.vmap(model.point_objective)
    keep = point_objective(current_latents, poses) <= point_objective(nearby, poses)
    starts = jnp.where(keep[:, None], current_latents, nearby)
    tolerance = 1e-6 if jnp.finfo(dtype).bits == 64 else 1e-4
    inverse = model.inverse(poses, max_steps=max_steps, initial_latents=starts,
                            tolerance=tolerance)
    return (inverse.latents.astype(wide), inverse.objective.astype(wide),
            inverse.result != optx.RESULTS.successful)


def _active_set(kernel: KernelParameters, latents, active_size: int):
    """The IVM's active set, or every point when it would take them all anyway (the exact
    GPLVM of eq. 1: selecting all n points greedily costs O(n³) for nothing)."""
    if active_size == latents.shape[0]:
        return jnp.arange(active_size)
    return select_active_set(kernel, latents, active_size)


def _check_poses(poses: np.ndarray, latent_dim: int, active_size: int) -> None:
    if poses.ndim != 2:
        raise ValueError(f"poses must be a (num_poses, dims) array, got shape {poses.shape}")
    if not np.all(np.isfinite(poses)):
        raise ValueError(f"poses contain {np.sum(~np.isfinite(poses))} non-finite values")
    if not 1 <= latent_dim < poses.shape[1]:
        raise ValueError(f"latent_dim must be in [1, {poses.shape[1] - 1}], got {latent_dim}")
    if not latent_dim < active_size <= poses.shape[0]:
        raise ValueError(f"active_size must be in ({latent_dim}, {poses.shape[0]}] "
                         f"(latent_dim, num_poses], got {active_size}")


def fit_gplvm(
    poses: Float[ArrayLike, "n dims"],
    *,
    latent_dim: int = 2,
    active_size: int = 200,
    iterations: int = 2,
    init: str = "isomap",
    neighbours: int = 10,
    active_steps: int = 150,
    optimiser: str = "bfgs",
    inactive_steps: int = 40,
    inactive_dtype=jnp.float32,
    all_poses: bool = True,
    final_rounds: int = 1,
    sequence_ids: ArrayLike | None = None,
    fps: float | None = None,
    back_constraint: float | None = None,
    seed: int = 0,
    progress: bool = True,
) -> GPLVMFit:
    """Learn a GPLVM from poses (Algorithm 1 of Tian et al., see the module docstring).

    Args:
        poses: ``(n, dims)`` training poses (e.g. SPM states); centred inside.
        latent_dim: latent dimension q (2 in the paper).
        active_size: size d of the IVM active set (capped at n). At n (or more) every pose is
            active, the IVM is skipped and eq. 1 is optimised over all poses: the exact GPLVM
            (``iterations=1, optimiser="lbfgs", active_steps=30``: the fewest steps whose
            held-out error on the validation subjects is no worse than 150 steps'; docs/gplvm.md);
            μ and eq. 5's μ⁻¹ then cost more per point, since every pose is a kernel centre.
        iterations: outer iterations T (2 with ``active_steps`` 150: the lowest held-out error
            of T ∈ {1, 2, 3} × steps ∈ {75, 150, 300} on the validation subjects' clips;
            docs/gplvm.md).
        init: ``"isomap"`` (PCA when the neighbour graph stays disconnected) or ``"pca"``.
        neighbours: k of Isomap's nearest-neighbour graph.
        active_steps: step cap for eq. 1.
        inactive_steps: step cap for each eq. 2 solve.
        optimiser: eq. 1's optimistix minimiser, ``"bfgs"`` or ``"lbfgs"`` (history 10).
            Both backtrack (Armijo) from a unit step. L-BFGS minimises eq. 1 / max|∇L(start)|,
            so that its first trial step (−∇L) is not halved many times first, and fits the
            exact model far better; BFGS keeps the unscaled arithmetic that the trackers'
            priors were validated with.
        inactive_dtype: float type of the eq. 2 solves (float32; eq. 1 and the model stay
            float64): the same validation error, that stage faster; more of the points stop
            at ``inactive_steps`` (``unconverged_points`` in the trace).
        all_poses: μ and σ² (for the non-active points' L′ and in the returned model) from all
            n poses through the active set, the projected process of
            :meth:`GPLVM.from_active_set`; ``False``: from the active poses alone (eqs. 3–4 as
            in the paper). Same cost per evaluation, lower held-out error.
        final_rounds: extra non-active stages in the last iteration, each with the model
            rebuilt from the points the previous one moved (one lowers the held-out error;
            more change little).
        sequence_ids: ``(n,)`` which sequence each pose belongs to (consecutive rows of one id
            are consecutive frames); with it the random-walk ν is estimated
            (:func:`estimate_dynamics`).
        fps: frame rate of those sequences, stored with ν.
        back_constraint: None (Tian et al.: free latents), or the width w of a back-constrained
            GPLVM (Lawrence & Quiñonero-Candela 2006; module docstring): x = g(y) over the
            first active set's poses as centres, with an RBF kernel of width w × the median
            distance between two centres. Smaller widths let the latents move more freely;
            larger ones keep alike poses closer. ``inactive_steps``, ``inactive_dtype`` and
            ``final_rounds`` are then unused (every latent is g(y)).
        progress: show a bar with the objective and active-set size per outer iteration.

    The measurements behind these defaults: see docs/gplvm.md, "Training".
    """
    poses = np.asarray(poses, np.float64)
    active_size = min(int(active_size), poses.shape[0])
    _check_poses(poses, latent_dim, active_size)
    if iterations < 1:
        raise ValueError(f"iterations must be at least 1, got {iterations}")
    if final_rounds < 0:
        raise ValueError(f"final_rounds must be at least 0, got {final_rounds}")
    if optimiser not in OPTIMISERS:
        raise ValueError(f"optimiser must be one of {OPTIMISERS}, got {optimiser!r}")
    if back_constraint is not None and not (np.isfinite(back_constraint) and back_constraint > 0):
        raise ValueError(f"back_constraint must be a positive width or None, got "
                         f"{back_constraint!r}")
    start = time.perf_counter()
    mean = poses.mean(axis=0)
    centred = poses - mean
    with _single_threaded_blas():
        tick = time.perf_counter()
        latents, description = initial_latents(centred, latent_dim, init,
                                               neighbours=neighbours, seed=seed)
        init_seconds = time.perf_counter() - tick
    with jax.enable_x64(True), _single_threaded_blas():
        centred_jax = jnp.asarray(centred)
        latents = jnp.asarray(latents)
        signal = float(np.mean(np.var(centred, axis=0)))
        kernel = KernelParameters.create(alpha=signal, beta=100.0 / signal, gamma=1.0)
        trace: list[dict] = []
        bar = tqdm(range(iterations), desc="GPLVM", unit="iter", disable=not progress,
                   dynamic_ncols=True)
        cross = weights = None
        for iteration in bar:
            tick = time.perf_counter()
            active = _active_set(kernel, latents, active_size)
            timings = {"ivm": time.perf_counter() - tick}
            if back_constraint is not None and cross is None:
                # the centres are the first active set's poses, fixed from here on
                centres = centred[np.asarray(active)]
                cross = jnp.asarray(back_constraint_kernel(centred, centres, back_constraint))
                weights = jnp.asarray(_back_constraint_weights(np.asarray(cross),
                                                               np.asarray(latents)))
                latents = cross @ weights
            if cross is None:
                kernel, active_latents, objective, _, steps = jax.block_until_ready(
                    _optimise_active(kernel, latents[active], centred_jax[active],
                                     max_steps=active_steps, tolerance=1e-6,
                                     optimiser=optimiser))
                latents = latents.at[active].set(active_latents)
            else:
                kernel, weights, objective, _, steps = jax.block_until_ready(_optimise_active(
                    kernel, weights, centred_jax[active], max_steps=active_steps,
                    tolerance=1e-6, optimiser=optimiser, cross=cross[active]))
                latents = cross @ weights
            timings["active"] = time.perf_counter() - tick - sum(timings.values())
            active = _active_set(kernel, latents, active_size)
            inactive = np.setdiff1d(np.arange(poses.shape[0]), np.asarray(active))
            point_objective, unconverged = jnp.nan, 0
            # the last iteration repeats the stage with the model rebuilt from the moved points
            # (the all-poses μ depends on them): a step towards their common fixed point
            rounds = 1 + (final_rounds if iteration == iterations - 1 else 0)
            for _ in range(rounds if inactive.size and cross is None else 0):
                model = GPLVM.from_active_set(kernel, centred_jax,
                                              jnp.zeros_like(centred_jax[0]), latents, active,
                                              all_poses=all_poses)
                moved, values, failed = _optimise_inactive(
                    model, latents[inactive], centred_jax[inactive], max_steps=inactive_steps,
                    dtype=inactive_dtype)
                latents = latents.at[inactive].set(moved)
                point_objective, unconverged = float(jnp.mean(values)), int(jnp.sum(failed))
            timings["inactive"] = time.perf_counter() - tick - sum(timings.values())
            trace.append({
                "iteration": iteration, "objective": float(objective),
                "mean_point_objective": float(point_objective), "active_size": active_size,
                "active_steps": int(steps), "unconverged_points": unconverged,
                "alpha": float(kernel.alpha), "beta": float(kernel.beta),
                "gamma": float(kernel.gamma), "seconds": time.perf_counter() - tick,
                "stage_seconds": timings,
            })
            bar.set_postfix(L=f"{float(objective):.1f}", active=active_size,
                            Lp=f"{float(point_objective):.2f}")
        bar.close()
        model = GPLVM.from_active_set(kernel, centred_jax, jnp.asarray(mean), latents, active,
                                      all_poses=all_poses)
        if sequence_ids is not None:
            # back-constrained, the training poses' latents are g(y) by construction; μ⁻¹
            # would move each to its own posterior mode and add that scatter to ν
            std = (estimate_dynamics(model, poses, sequence_ids) if cross is None
                   else _step_std(np.asarray(latents), sequence_ids))
            model = eqx.tree_at(lambda m: (m.dynamics_std, m.dynamics_fps), model,
                                (jnp.asarray(std), jnp.asarray(float(fps or np.nan))))
        constraint = None if cross is None else {
            "width": float(back_constraint), "centres": centres,
            "weights": np.asarray(weights, np.float64)}
    return GPLVMFit(model=model, trace=trace, init=description, init_seconds=init_seconds,
                    seconds=time.perf_counter() - start, back_constraint=constraint)


def estimate_dynamics(model: GPLVM, poses: Float[ArrayLike, "n dims"], sequence_ids: ArrayLike,
                      *, max_steps: int = 64) -> np.ndarray:
    """ν of the random walk x_{t+1} = x_t + ω, ω ~ N(0, diag ν²) (Tian et al. §4, eq. 6).

    The poses are projected with μ⁻¹ and ν² is the variance of the frame-to-frame latent steps
    within each sequence (rows with the same id, in order). A back-constrained fit takes ν from
    its training latents instead (:func:`fit_gplvm`).
    """
    poses = np.asarray(poses, np.float64)
    ids = np.asarray(sequence_ids)
    if ids.shape != (poses.shape[0],):
        raise ValueError(f"sequence_ids must have shape ({poses.shape[0]},), got {ids.shape}")
    if not np.any(ids[1:] == ids[:-1]):
        raise ValueError("sequence_ids has no two consecutive frames of one sequence")
    with jax.enable_x64(True):
        latents = np.asarray(model.inverse(jnp.asarray(poses), max_steps=max_steps).latents)
    return _step_std(latents, ids)


def _step_std(latents: np.ndarray, sequence_ids: ArrayLike) -> np.ndarray:
    """Std of the frame-to-frame latent steps within each sequence (rows with the same id)."""
    ids = np.asarray(sequence_ids)
    return np.std(np.diff(latents, axis=0)[ids[1:] == ids[:-1]], axis=0)
