"""Run the GPy reference GPLVM (``_gpy_reference.py``) in its own venv, as a subprocess.

GPy never enters the jaxtrack venv. Create its venv once with

    python3 -m venv .venv-gpy && .venv-gpy/bin/pip install -r benchmarks/requirements-gpy.txt

or ``python -m benchmarks._gpy`` (which calls :func:`ensure_gpy_env`). ``JAXTRACK_GPY_PYTHON``
may name another python executable that has GPy.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from benchmarks._common import run_in_venv

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv-gpy"
REQUIREMENTS = Path(__file__).resolve().parent / "requirements-gpy.txt"
SCRIPT = Path(__file__).resolve().parent / "_gpy_reference.py"


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

    Returns the outputs of ``_gpy_reference.py`` (``reconstructions``, ``train_latents``,
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
    return run_in_venv(python, SCRIPT, inputs, output="out.npz", read=_read_npz,
                       label=f"GPy {model}", timeout=timeout)


def _read_npz(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as data:
        return {key: (data[key].item() if data[key].ndim == 0 else data[key])
                for key in data.files}


if __name__ == "__main__":
    print(ensure_gpy_env(sys.argv[1] if len(sys.argv) > 1 else VENV))
