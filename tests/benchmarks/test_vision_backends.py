"""``benchmarks.vision_backends`` runs both preprocessing paths, checks that they agree and that
kornia's result reaches JAX without a copy, and refuses a GPU it does not have. Run in a
subprocess: torch and XLA loaded in one process have crashed XLA's compiler
(``tests/vision/test_kornia_backend.py``)."""

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("torch") is None or importlib.util.find_spec("kornia") is None,
    reason="torch and kornia are not installed (the optional kornia extra)")


def run(*arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks.vision_backends", *arguments],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_a_tiny_cpu_run_writes_every_stage_with_agreement_and_a_copy_free_handoff(tmp_path):
    out = tmp_path / "vision_backends.json"
    result = run("--size", "48", "32", "--frames", "2", "--repeats", "1", "--json", str(out))
    assert result.returncode == 0, result.stderr[-3000:]
    written = json.loads(out.read_text())
    assert [row["stage"] for row in written["rows"]] == ["foreground", "skin", "gradient"]
    assert written["frames_on"] == "cpu" and written["gpu"] is None
    assert written["handoff"] == {"jax_device": "cpu:0", "same_memory": True, "equal": True}
    for row in written["rows"]:
        assert row["opencv_ms"] > 0 and row["kornia_ms"] > 0
        assert row["differing_pixels"] <= 1e-3, row
    assert "DLPack hand-off to JAX: on cpu:0, the same memory (no copy)" in result.stdout


def test_cuda_is_refused_in_one_line_where_there_is_none(tmp_path):
    out = tmp_path / "vision_backends.json"
    result = run("--device", "cuda", "--size", "48", "32", "--json", str(out))
    if result.returncode == 0:
        pytest.skip("this machine has a CUDA device")
    assert result.returncode == 2
    assert "--device cuda:" in result.stderr.strip().splitlines()[-1]
    assert not out.exists()
