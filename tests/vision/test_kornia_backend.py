"""The kornia backend of the preprocessing agrees with OpenCV, and hands JAX its result through
DLPack without a copy (``_kornia_checks.py``, run in its own process: torch and XLA loaded in
one process have crashed XLA's compiler, so this process never imports torch)."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from jaxtrack.vision.foreground import foreground_mask

CHECKS = Path(__file__).with_name("_kornia_checks.py")


@pytest.mark.skipif(importlib.util.find_spec("torch") is None
                    or importlib.util.find_spec("kornia") is None,
                    reason="torch and kornia are not installed (the optional kornia extra)")
def test_the_kornia_backend_matches_opencv_and_shares_its_memory_with_jax():
    result = subprocess.run([sys.executable, str(CHECKS)], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr[-3000:]
    assert result.stdout.count(": ok") == 5, result.stdout


def test_an_unknown_backend_is_refused_before_any_import():
    import numpy as np

    frame = np.zeros((8, 8, 3), np.uint8)
    with pytest.raises(ValueError, match="backend must be one of opencv, kornia"):
        foreground_mask(frame, frame, backend="torch")
    assert "torch" not in sys.modules
