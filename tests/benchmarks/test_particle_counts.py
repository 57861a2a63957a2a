"""The engine's throughput benchmark (``python -m benchmarks.particle_counts``) and its peers."""

import json

import numpy as np

from benchmarks import _peers, particle_counts


def test_a_batched_peer_gets_the_whole_batch_the_others_a_few_sequences(monkeypatch):
    seen = {}

    def fake_run_peer(library, model, observations, counts, *, seed=0, timeout=None):
        seen[library] = len(observations)
        return {"library": library, "runs": []}

    monkeypatch.setattr(_peers, "run_peer", fake_run_peer)
    observations = np.zeros((6, 5, 1), np.float32)
    _peers.run_peers(None, observations, [10], sequences=2)
    assert seen == {"particles": 2, "cuthbert": 2, "pydpf": 6}
    _peers.run_peers(None, observations, [10], sequences=2, batched_sequences=4)
    assert seen["pydpf"] == 4 and seen["particles"] == 2


def test_a_missing_peer_is_skipped_with_the_reason(monkeypatch, tmp_path):
    monkeypatch.setenv("JAXTRACK_PEER_PYDPF_PYTHON", str(tmp_path / "no-python"))
    result = _peers.run_peer("pydpf", None, np.zeros((1, 2, 1)), [10])
    assert "no-python" in result["skipped"]


def test_a_batched_peers_columns_give_its_time_per_sequence_and_evidence_error():
    result = {"version": "1.2.3", "runs": [
        {"particles": 10, "batch_seconds": 4.0, "seconds": [1.0] * 4,
         "log_evidence": [-1.0, -2.0, -3.0, -4.0]}]}
    exact = np.array([-1.5, -2.0, -3.0, -4.0])
    columns = particle_counts._peer_columns("pydpf", result, 10, exact, 0.25)
    assert columns["pydpf_per_sequence_s"] == 1.0
    assert columns["speedup_vs_pydpf"] == 4.0  # its 1 s/seq over the engine's 0.25
    assert columns["pydpf_batch_s"] == 4.0 and columns["pydpf_sequences"] == 4
    assert columns["pydpf_error"] == 0.125
    missing = particle_counts._peer_columns("pydpf", result, 100, exact, 0.25)
    assert missing["speedup_vs_pydpf"] is None


def test_the_quick_benchmark_runs_and_checks_every_evidence(tmp_path):
    out = tmp_path / "counts.json"
    assert particle_counts.main(["--quick", "--batch-particles", "50", "--sweep-particles", "50",
                                 "--numpy-sequences", "1", "--peer-sequences", "0",
                                 "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    batch = next(row for row in rows if row["mode"] == "batch")
    assert batch["particles"] == 50 and batch["sequences"] == 8
    assert np.isfinite(batch["engine_error"]) and np.isfinite(batch["simple_error"])
    assert batch["speedup_vs_simple"] > 0
    assert batch["pydpf_published_s"] is None  # pydpf published N = 1 000 and 10 000 only


def test_the_peer_script_names_its_libraries_when_given_another():
    """The one script every peer venv runs imports only NumPy at its top and refuses an
    unknown library with its usage."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(_peers.__file__).with_name("_peer_filters.py")
    done = subprocess.run([sys.executable, str(script), "gpy", "in.npz", "out.json"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "particles|cuthbert|pydpf" in done.stderr
