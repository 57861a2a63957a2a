"""The README's Python examples run as written, each in a fresh interpreter in an empty folder.

The engine's example runs in the default suite, with warnings as errors; the GPLVM's and the
trackers' train a prior and track a clip (minutes on 2 cores), so they are marked slow
(``pytest -m slow tests/test_readme.py``)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).parents[1] / "README.md"


def _examples() -> dict[str, str]:
    """``{section heading: code}`` for every ``python`` block of the README."""
    examples, heading = {}, ""
    for match in re.finditer(r"^## ([^\n]+)$|^```python\n(.*?)^```", README.read_text(),
                             re.M | re.S):
        if match.group(1):
            heading = match.group(1)
        else:
            examples[heading] = match.group(2)
    return examples


EXAMPLES = _examples()


def _run(code: str, folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-W", "error", "-c", code], cwd=folder,
                          capture_output=True, text=True, timeout=1800)


def test_the_readme_has_the_examples_this_test_runs():
    assert set(EXAMPLES) == {"Quick start: the engine", "Quick start: the GPLVM prior",
                             "Quick start: trackers"}


def test_the_engine_example_runs_without_warnings(tmp_path):
    result = _run(EXAMPLES["Quick start: the engine"], tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    log_evidence, exact = (float(value) for value in result.stdout.split())
    assert abs(log_evidence - exact) < 5.0  # 10 000 particles, 100 frames: a few nats at most


@pytest.mark.slow
@pytest.mark.parametrize("heading", ["Quick start: the GPLVM prior", "Quick start: trackers"])
def test_the_slow_examples_run(heading, tmp_path):
    result = _run(EXAMPLES[heading], tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
