"""Run peer particle-filter libraries on the benchmark's model and data, each in its own venv.

``particles`` (N. Chopin, NumPy), ``cuthbert`` (JAX) and ``pydpf`` (Brady et al., PyTorch) never
enter the jaxtrack venv; create theirs once with ``make bench-peers-env``
(``.venv-peers-particles``, ``.venv-peers-cuthbert``, ``.venv-peers-pydpf``).
The model's arrays and the observations go to a temporary .npz, ``_peer_filters.py LIBRARY`` runs
under the peer venv's python and writes JSON back. ``JAXTRACK_PEER_<LIBRARY>_PYTHON`` may name
another python that has the library.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from benchmarks._common import run_in_venv

ROOT = Path(__file__).resolve().parent.parent
PEERS = ("particles", "cuthbert", "pydpf")
BATCHED = ("pydpf",)
"""Peers that filter a batch of sequences in one call (as their own benchmarks do): they get the
batch handed to :func:`run_peers` whole, the others a few sequences one at a time."""


def peer_python(library: str) -> Path:
    """``$JAXTRACK_PEER_<LIBRARY>_PYTHON`` or ``.venv-peers-<library>/bin/python``."""
    override = os.environ.get(f"JAXTRACK_PEER_{library.upper()}_PYTHON")
    return Path(override) if override else ROOT / f".venv-peers-{library}" / "bin" / "python"


def run_peer(library: str, model, observations, particle_counts, *, seed: int = 0,
             timeout: float | None = 3600.0) -> dict:
    """Run ``library``'s bootstrap filter on each of ``observations`` (sequences, frames, dim)
    for each particle count.

    Returns the script's JSON (``library``, ``version``, ``runs``: per particle count
    ``particles``, ``seconds`` and ``log_evidence`` per sequence, and for cuthbert
    ``compile_s`` and ``first_call_s``), or ``{"skipped": reason}`` when the peer's python is
    missing or the run fails or times out.
    """
    python = peer_python(library)
    if not python.exists():
        return {"skipped": f"no {library} python at {python} (make bench-peers-env)"}
    inputs = {
        "transition": np.asarray(model.transition_matrix, np.float32),
        "transition_covariance": np.asarray(model.transition_covariance, np.float32),
        "observation": np.asarray(model.observation_matrix, np.float32),
        "observation_covariance": np.asarray(model.observation_covariance, np.float32),
        "initial_mean": np.asarray(model.initial_mean, np.float32),
        "initial_covariance": np.asarray(model.initial_covariance, np.float32),
        "observations": np.asarray(observations, np.float32),
        "particle_counts": np.asarray(particle_counts, np.int64),
        "seed": np.int64(seed),
    }
    script = Path(__file__).resolve().parent / "_peer_filters.py"
    return run_in_venv(python, script, inputs, output="out.json", arguments=(library,),
                       read=lambda path: json.loads(path.read_text()), label=library,
                       timeout=timeout)


def run_peers(model, observations, particle_counts, *, sequences: int, batched_sequences=None,
              seed: int = 0) -> dict:
    """{library: :func:`run_peer`'s result} for every peer; prints a note for each skipped.

    The one-sequence-at-a-time peers run the first ``sequences`` of ``observations``; the
    :data:`BATCHED` ones the first ``batched_sequences`` (all of them when None) in one call."""
    results = {}
    for library in PEERS:
        count = (batched_sequences or len(observations)) if library in BATCHED else sequences
        results[library] = run_peer(library, model, observations[:count], particle_counts,
                                    seed=seed)
        if "skipped" in results[library]:
            print(f"note: {library} skipped: {results[library]['skipped']}")
    return results
