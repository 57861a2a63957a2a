"""The documentation site (design pages and the API reference from the docstrings) builds in
strict mode: a broken link or anchor, a page that cannot be found, or a docstring the Python
handler cannot read (a documented parameter missing from the signature) fails the build."""

import importlib
import importlib.util
import inspect
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS_LINE_LIMIT = 2_500  # design pages a reader reads; dated measurements go with their paper

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
    for package in ["smc", "body", "data", "priors", "likelihoods", "trackers", "vision",
                    "evaluation", "experiments", "cli"]:
        page = (site / "api" / package / "index.html").read_text(encoding="utf-8")
        assert 'id="jaxtrack.' in page, f"api/{package}.md rendered no object"
    assert 'id="jaxtrack.smc.run"' in (site / "api" / "smc" / "index.html").read_text("utf-8")
    for identifier in ["jaxtrack.vision.mediapipe", "jaxtrack.vision.smoothing",
                       "jaxtrack.vision.triangulation", "jaxtrack.likelihoods.detections",
                       "jaxtrack.trackers.mixed_state", "jaxtrack.priors.linear_combinations"]:
        page = site / "api" / identifier.split(".")[1] / "index.html"
        assert f'id="{identifier}"' in page.read_text("utf-8"), f"{identifier} is not rendered"
    # the notebooks as a reader sees them: their committed outputs, figures included
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        page = (site / "notebooks" / notebook.stem / "index.html").read_text(encoding="utf-8")
        assert "data:image/png;base64," in page, f"{notebook.name} is rendered without a figure"
    engine = (site / "notebooks" / "01_engine_tour" / "index.html").read_text(encoding="utf-8")
    assert re.search(r"PF\s+-?\d+\.\d+\s+Kalman", engine), "01's printed output is not rendered"


def test_docs_stay_within_their_line_budget():
    """docs/ holds design pages (what each piece does, its equations, where they are in code,
    how to use it); a paper's dated measurements go to papers/<paper>/history.md."""
    pages = sorted((ROOT / "docs").glob("*.md")) + sorted((ROOT / "docs" / "api").glob("*.md"))
    lines = {page.relative_to(ROOT).as_posix(): len(page.read_text("utf-8").splitlines())
             for page in pages}
    largest = sorted(lines.items(), key=lambda item: -item[1])[:5]
    assert sum(lines.values()) <= DOCS_LINE_LIMIT, (
        f"docs/ holds {sum(lines.values())} lines, over {DOCS_LINE_LIMIT}: move dated "
        f"measurements to papers/<paper>/history.md (largest pages: {largest})")


def _public_names(module) -> list[str]:
    """``__all__``, or the classes and functions a module defines without a leading _."""
    declared = getattr(module, "__all__", None)
    if declared is not None:
        return list(declared)
    return [name for name, value in vars(module).items()
            if not name.startswith("_") and (inspect.isclass(value) or inspect.isfunction(value))
            and value.__module__ == module.__name__]


def test_every_public_module_is_on_an_api_page():
    """Every public package has a ``::: jaxtrack.X`` directive on an API page, and so does
    every public module with a public name its package does not re-export."""
    import jaxtrack

    directives = set()
    for page in (ROOT / "docs" / "api").glob("*.md"):
        directives |= set(re.findall(r"^::: (\S+)", page.read_text("utf-8"), re.MULTILINE))
    missing = []
    for found in pkgutil.walk_packages(jaxtrack.__path__, "jaxtrack."):
        if any(part.startswith("_") for part in found.name.split(".")):
            continue
        module = importlib.import_module(found.name)
        parent = importlib.import_module(found.name.rsplit(".", 1)[0])
        exported = set(getattr(parent, "__all__", ()))
        if found.ispkg or set(_public_names(module)) - exported:
            if found.name not in directives:
                missing.append(found.name)
    assert not missing, (f"no API page renders {missing}: add '::: NAME' to the package's page "
                         "in docs/api/")


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
