"""The documentation site (design pages and the API reference from the docstrings) builds in
strict mode: a broken link or anchor, a page that cannot be found, or a docstring the Python
handler cannot read (a documented parameter missing from the signature) fails the build."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
    reason="mkdocs / mkdocstrings not installed (pip install -e '.[docs]')")


def test_site_builds_in_strict_mode(tmp_path):
    site = tmp_path / "site"
    built = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet",
         "--config-file", str(ROOT / "mkdocs.yml"), "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    log = built.stdout + built.stderr
    assert built.returncode == 0, f"mkdocs build --strict failed:\n{log}"
    assert "WARNING" not in log, log
    # every public package has its API page, rendered from the docstrings
    for package in ["smc", "body", "priors", "likelihoods", "trackers", "vision", "evaluation",
                    "experiments"]:
        page = (site / "api" / package / "index.html").read_text(encoding="utf-8")
        assert 'id="jaxtrack.' in page, f"api/{package}.md rendered no object"
    assert 'id="jaxtrack.smc.run"' in (site / "api" / "smc" / "index.html").read_text("utf-8")


def test_grouped_parameters_are_split():
    spec = importlib.util.spec_from_file_location(
        "_grouped_parameters", ROOT / "docs" / "api" / "_grouped_parameters.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    text = "Do it.\n\nArgs:\n    low, high: thresholds,\n        in pixels.\n    x: a, b: c\n\n" \
           "Returns:\n    a, b: kept\n"
    assert module.split_grouped(text) == (
        "Do it.\n\nArgs:\n    low: thresholds,\n        in pixels.\n    high: thresholds,\n"
        "        in pixels.\n    x: a, b: c\n\nReturns:\n    a, b: kept")
