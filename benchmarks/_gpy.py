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
import tempfile
from pathlib import Path

import numpy as np

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
    with tempfile.TemporaryDirectory(prefix="jaxtrack-gpy-") as folder:
        in_path, out_path = Path(folder) / "in.npz", Path(folder) / "out.npz"
        np.savez(in_path, **inputs)
        command = [str(python), str(SCRIPT), str(in_path), str(out_path)]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"skipped": f"GPy {model} run timed out after {timeout:g} s"}
        except OSError as error:
            return {"skipped": f"cannot run {python}: {error}"}
        if done.returncode != 0 or not out_path.exists():
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            return {"skipped": f"GPy {model} run failed ({done.returncode}): " + " | ".join(tail)}
        with np.load(out_path, allow_pickle=False) as data:
            result = {key: data[key] for key in data.files}
    result = {k: (v.item() if v.ndim == 0 else v) for k, v in result.items()}
    result["summary"] = done.stdout.strip()
    return result


if __name__ == "__main__":
    print(ensure_gpy_env(sys.argv[1] if len(sys.argv) > 1 else VENV))
