"""GPy's GPLVM, the reference the GPLVM benchmark compares with: run in its own venv, as a
subprocess, so that GPy never enters the jaxtrack venv.

From jaxtrack's side, :func:`run_gpy_reference` writes the inputs and runs this same file with
the GPy venv's python (``.venv-gpy/bin/python benchmarks/_gpy.py run IN.npz OUT.npz``, the part
below the line "run under the GPy venv", which imports only NumPy, SciPy and GPy). Create the
venv once with

    python3 -m venv .venv-gpy && .venv-gpy/bin/pip install -r benchmarks/requirements-gpy.txt

or ``python -m benchmarks._gpy`` (which calls :func:`ensure_gpy_env`). ``JAXTRACK_GPY_PYTHON``
may name another python executable that has GPy.

IN.npz: ``train`` (N, D), ``test`` (M, D), ``latent_dim``, ``num_inducing``, ``max_iters``,
``model`` ("sparse" or "full"), optional ``init_latents`` (N, q) and ``seed``.
Both models use an isotropic RBF kernel plus Gaussian noise (GPy's ``GPLVM`` would otherwise
default to ARD RBF + Bias) and GPy's default optimizer, L-BFGS-B, whose ``max_iters`` caps
both iterations and function evaluations. Test poses are reconstructed as
``predict(infer_newX(test))``. OUT.npz is written atomically; stdout gets one summary line.
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv-gpy"
REQUIREMENTS = Path(__file__).resolve().parent / "requirements-gpy.txt"
SCRIPT = Path(__file__).resolve()


def gpy_python() -> Path:
    """The python that runs GPy: ``$JAXTRACK_GPY_PYTHON`` or ``.venv-gpy/bin/python``."""
    override = os.environ.get("JAXTRACK_GPY_PYTHON")
    return Path(override) if override else VENV / "bin" / "python"


def ensure_gpy_env(venv: str | Path = VENV) -> Path:
    """Create ``venv`` from requirements-gpy.txt unless it already imports GPy; its python."""
    venv = Path(venv)
    python = venv / "bin" / "python"
    if python.exists() and _imports_gpy(python):
        return python
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = [str(python), "-m", "pip", "install", "-q", "-r", str(REQUIREMENTS)]
    subprocess.run(pip, check=True)
    return python


def _imports_gpy(python: Path) -> bool:
    probe = subprocess.run([str(python), "-c", "import GPy"], capture_output=True)
    return probe.returncode == 0


def run_gpy_reference(
    train: np.ndarray,
    test: np.ndarray,
    *,
    latent_dim: int = 2,
    num_inducing: int = 200,
    max_iters: int = 1000,
    model: str = "sparse",
    init_latents: np.ndarray | None = None,
    seed: int = 0,
    timeout: float | None = 1800.0,
) -> dict:
    """Train GPy's SparseGPLVM ("sparse") or GPLVM ("full") on ``train`` and reconstruct ``test``.

    Returns the outputs of :func:`reference_run` (``reconstructions``, ``train_latents``,
    ``test_latents``, ``train_seconds``, ``inverse_seconds``, ``initial_objective``,
    ``final_objective``, ``iterations``, ``function_evaluations``, ``status``,
    ``inverse_function_evaluations``, ``rbf_variance``, ``rbf_lengthscale``,
    ``noise_variance``, ``gpy_version``, ``model``, plus ``summary``: the script's line), or
    ``{"skipped": reason}`` when the GPy python is missing or the run fails or times out.
    """
    if model not in ("sparse", "full"):
        raise ValueError(f"model must be 'sparse' or 'full', not {model!r}")
    python = gpy_python()
    if not python.exists():
        return {"skipped": f"no GPy python at {python} (make bench-gpy-env)"}
    inputs = {
        "train": np.asarray(train, dtype=np.float64),
        "test": np.asarray(test, dtype=np.float64),
        "latent_dim": np.int64(latent_dim),
        "num_inducing": np.int64(num_inducing),
        "max_iters": np.int64(max_iters),
        "model": np.str_(model),
        "seed": np.int64(seed),
    }
    if init_latents is not None:
        inputs["init_latents"] = np.asarray(init_latents, dtype=np.float64)
    from benchmarks._common import run_in_venv  # jaxtrack's side only

    return run_in_venv(python, SCRIPT, inputs, output="out.npz", read=_read_npz,
                       label=f"GPy {model}", timeout=timeout, arguments=("run",))


def _read_npz(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as data:
        return {key: (data[key].item() if data[key].ndim == 0 else data[key])
                for key in data.files}


# ---- run under the GPy venv (``_gpy.py run IN.npz OUT.npz``): NumPy, SciPy and GPy only ----
def _counting_lbfgsb(max_iters: int):
    """paramz's L-BFGS-B with the same settings, also recording the iteration count."""
    from paramz.optimization.optimization import opt_lbfgsb
    from scipy import optimize

    class CountingLBFGSB(opt_lbfgsb):
        nit = None

        def opt(self, x_init, f_fp=None, f=None, fp=None):
            kwargs = {} if self.gtol is None else {"pgtol": self.gtol}
            if self.bfgs_factor is not None:
                kwargs["factr"] = self.bfgs_factor
            x, _, info = optimize.fmin_l_bfgs_b(
                f_fp, x_init, maxfun=self.max_iters, maxiter=self.max_iters, **kwargs
            )
            self.x_opt = x
            self.f_opt = f_fp(x)[0]
            self.funct_eval = info["funcalls"]
            self.nit = info["nit"]
            self.status = ["Converged", "Maximum number of f evaluations reached", "Error"][
                info["warnflag"]
            ]

    return CountingLBFGSB(max_iters=max_iters)


def reference_run(inputs: dict) -> dict:
    """Train the GPy model on ``inputs`` and reconstruct the test poses."""
    import GPy

    train = np.asarray(inputs["train"], dtype=np.float64)
    test = np.asarray(inputs["test"], dtype=np.float64)
    q = int(inputs["latent_dim"])
    kind = str(inputs["model"])
    max_iters = int(inputs["max_iters"])
    init = inputs.get("init_latents")
    init = None if init is None else np.asarray(init, dtype=np.float64)
    np.random.seed(int(inputs.get("seed", 0)))  # GPy picks inducing points with np.random

    start = time.perf_counter()
    kernel = GPy.kern.RBF(q)
    if kind == "sparse":
        model = GPy.models.SparseGPLVM(
            train, q, X=init, kernel=kernel, num_inducing=int(inputs["num_inducing"])
        )
    elif kind == "full":
        model = GPy.models.GPLVM(train, q, X=init, kernel=kernel)
    else:
        raise ValueError(f"model must be 'sparse' or 'full', not {kind!r}")
    initial_objective = float(model.objective_function())
    opt = _counting_lbfgsb(max_iters)
    model.optimize(optimizer=opt, max_iters=max_iters, messages=False)
    train_seconds = time.perf_counter() - start

    start = time.perf_counter()
    test_latents, inference = model.infer_newX(test, optimize=True)
    test_latents = np.array(test_latents, dtype=np.float64)
    reconstructions = np.asarray(model.predict(test_latents)[0], dtype=np.float64)
    inverse_seconds = time.perf_counter() - start
    inverse_opt = inference.optimization_runs[-1] if inference.optimization_runs else None

    return {
        "reconstructions": reconstructions,
        "train_latents": np.array(model.X, dtype=np.float64),
        "test_latents": test_latents,
        "train_seconds": train_seconds,
        "inverse_seconds": inverse_seconds,
        "initial_objective": initial_objective,
        "final_objective": float(model.objective_function()),
        "iterations": int(opt.nit),
        "function_evaluations": int(opt.funct_eval),
        "status": str(opt.status),
        "inverse_function_evaluations": int(inverse_opt.funct_eval) if inverse_opt else 0,
        "rbf_variance": float(model.kern.variance[0]),
        "rbf_lengthscale": float(model.kern.lengthscale[0]),
        "noise_variance": float(model.likelihood.variance[0]),
        "gpy_version": str(GPy.__version__),
        "model": kind,
    }


def _save_atomic(path: str, arrays: dict) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(suffix=".npz", dir=folder)
    try:
        with os.fdopen(handle, "wb") as stream:
            np.savez(stream, **arrays)
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise


def reference_main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: _gpy.py run IN.npz OUT.npz", file=sys.stderr)
        return 2
    with np.load(argv[0], allow_pickle=False) as data:
        inputs = {key: data[key] for key in data.files}
    inputs = {k: (v.item() if v.ndim == 0 else v) for k, v in inputs.items()}
    chatter = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(chatter):
        warnings.simplefilter("ignore")
        out = reference_run(inputs)
    _save_atomic(argv[1], out)
    error = np.sqrt(np.mean(np.sum((out["reconstructions"] - inputs["test"]) ** 2, axis=1)))
    print(
        f"GPy {out['gpy_version']} {out['model']}: N={len(inputs['train'])} "
        f"M={len(inputs['test'])} train {out['train_seconds']:.2f}s "
        f"({out['iterations']} it, {out['function_evaluations']} f-evals, {out['status']}) "
        f"objective {out['final_objective']:.3f}, inverse {out['inverse_seconds']:.2f}s, "
        f"rms reconstruction error {error:.4g}"
    )
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["run"]:
        sys.exit(reference_main(sys.argv[2:]))
    print(ensure_gpy_env(sys.argv[1] if len(sys.argv) > 1 else VENV))
