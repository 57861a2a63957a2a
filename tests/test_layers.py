"""The package's layers (docs/layers.md), read from the source with ``ast``: every import, at module
level or inside a function, of every module under ``jaxtrack/``.

- OpenCV, PyTorch and kornia are imported only in ``jaxtrack/vision/`` and in the renderer that
  draws test video, and only inside functions, so ``import jaxtrack`` needs none of them.
- ``jaxtrack/smc/`` imports nothing else of jaxtrack.
- ``jaxtrack/evaluation/`` holds metrics only: no experiments, trackers, priors or CLI.
- No layer imports a higher one.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "jaxtrack"

OPTIONAL_BACKENDS = {"cv2", "torch", "kornia"}
RENDERER = {"jaxtrack.body.render", "jaxtrack.body._figure", "jaxtrack.body._backgrounds"}

# data flows down the list: a module may import its own layer and lower ones only
LAYERS = {
    "_files": 0, "_plotting": 0, "smc": 0,
    "body": 1, "data": 1,  # the catalogue of bundled clips and photos the body layer loads
    "priors": 2,
    "vision": 3,
    "likelihoods": 4,
    "trackers": 5,
    "evaluation": 6,
    "experiments": 7,
    "cli": 8,
    "_defaults": 8,  # the registry of defaults reads every layer (docs/defaults.md)
    "__main__": 9,  # python -m jaxtrack: the command line
}


@dataclass(frozen=True)
class Import:
    module: str  # the importing module, e.g. "jaxtrack.evaluation.metrics"
    target: str  # what it imports, e.g. "jaxtrack.body.markers" or "cv2"
    line: int
    lazy: bool  # inside a function

    def __str__(self) -> str:
        where = "inside a function" if self.lazy else "at module level"
        return f"{self.module} imports {self.target} (line {self.line}, {where})"


def _module_name(path: Path, package: Path) -> str:
    parts = path.relative_to(package.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> list[str]:
    if node.level:  # relative: from . import x, from ..y import z
        base = module.split(".")
        base = base[:len(base) - node.level + (1 if is_package else 0)]
        stem = ".".join(base + ([node.module] if node.module else []))
    else:
        stem = node.module or ""
    # `from jaxtrack import trackers` imports the subpackage jaxtrack.trackers
    return [f"{stem}.{alias.name}" for alias in node.names] if stem == "jaxtrack" else [stem]


def collect_imports(package: Path = PACKAGE) -> list[Import]:
    """Every import statement in every module under ``package``."""
    found = []
    for path in sorted(package.rglob("*.py")):
        module = _module_name(path, package)
        tree = ast.parse(path.read_text(), filename=str(path))
        lazy_nodes = {id(inner) for node in ast.walk(tree)
                      if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
                      for inner in ast.walk(node) if inner is not node}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                targets = _resolve(module, path.name == "__init__.py", node)
            else:
                continue
            found.extend(Import(module, target, node.lineno, id(node) in lazy_nodes)
                         for target in targets)
    return found


def _layer(name: str) -> str | None:
    """``jaxtrack.evaluation.metrics`` -> ``evaluation``; None for the root package."""
    parts = name.split(".")
    return parts[1] if parts[0] == "jaxtrack" and len(parts) > 1 else None


def _internal(imports: list[Import]) -> list[Import]:
    return [entry for entry in imports if entry.target.split(".")[0] == "jaxtrack"]


def backend_violations(imports: list[Import]) -> list[str]:
    problems = []
    for entry in imports:
        if entry.target.split(".")[0] not in OPTIONAL_BACKENDS:
            continue
        if not (_layer(entry.module) == "vision" or entry.module in RENDERER):
            problems.append(f"{entry}: only jaxtrack.vision and the renderer may import it")
        elif not entry.lazy:
            problems.append(f"{entry}: import it inside the function that needs it")
    return problems


def smc_violations(imports: list[Import]) -> list[str]:
    return [f"{entry}: jaxtrack.smc imports nothing else of jaxtrack"
            for entry in _internal(imports)
            if _layer(entry.module) == "smc" and _layer(entry.target) != "smc"]


def evaluation_violations(imports: list[Import]) -> list[str]:
    allowed = {"evaluation", "body", "data", "_files", "_plotting"}
    return [f"{entry}: jaxtrack.evaluation holds metrics only" for entry in imports
            if _layer(entry.module) == "evaluation"
            and (entry.target.split(".")[0] in OPTIONAL_BACKENDS
                 or entry.target.split(".")[0] == "jaxtrack"
                 and _layer(entry.target) not in allowed)]


def layer_violations(imports: list[Import]) -> list[str]:
    problems = []
    for entry in _internal(imports):
        source, target = _layer(entry.module), _layer(entry.target)
        if source is None or target is None:  # the root package and its own imports
            continue
        for layer in (source, target):
            if layer not in LAYERS:
                problems.append(f"{entry}: jaxtrack.{layer} has no layer; add it to LAYERS in "
                                f"tests/test_layers.py and to docs/layers.md")
        if source in LAYERS and target in LAYERS and LAYERS[target] > LAYERS[source]:
            problems.append(f"{entry}: {source} (layer {LAYERS[source]}) may not import "
                            f"{target} (layer {LAYERS[target]})")
    return problems


@pytest.fixture(scope="module")
def imports() -> list[Import]:
    return collect_imports()


def test_the_scan_sees_module_and_function_level_imports(imports):
    # a known lazy cv2 import in the renderer and a known module-level internal import
    assert any(entry.module == "jaxtrack.body.render" and entry.target == "cv2" and entry.lazy
               for entry in imports)
    assert any(entry.module == "jaxtrack.experiments.protocol"
               and entry.target == "jaxtrack.priors.train" and not entry.lazy
               for entry in imports)
    assert any(entry.module == "jaxtrack.experiments.protocol"
               and entry.target == "jaxtrack.trackers" and entry.lazy for entry in imports)


def test_opencv_torch_and_kornia_only_in_vision_and_the_renderer(imports):
    assert backend_violations(imports) == []


def test_smc_imports_nothing_else_of_jaxtrack(imports):
    assert smc_violations(imports) == []


def test_evaluation_holds_metrics_only(imports):
    assert evaluation_violations(imports) == []


def test_no_layer_imports_a_higher_one(imports):
    assert layer_violations(imports) == []


def test_every_subpackage_has_a_layer():
    subpackages = {path.parent.name for path in PACKAGE.glob("*/__init__.py")}
    assert subpackages - set(LAYERS) == set()


def test_the_checks_catch_a_violation(tmp_path):
    # the same checks on a small package that breaks each rule once
    package = tmp_path / "jaxtrack"
    for folder in ("evaluation", "smc", "body"):
        (package / folder).mkdir(parents=True)
        (package / folder / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "evaluation" / "overlay.py").write_text(
        "def draw():\n    import cv2\n    from jaxtrack import trackers\n")
    (package / "smc" / "_filter.py").write_text("from ..body import motion\n")
    (package / "body" / "render.py").write_text(
        "import cv2\nfrom jaxtrack.experiments import protocol\n")
    imports = collect_imports(package)
    assert backend_violations(imports) == [
        "jaxtrack.body.render imports cv2 (line 1, at module level): import it inside the "
        "function that needs it",
        "jaxtrack.evaluation.overlay imports cv2 (line 2, inside a function): only "
        "jaxtrack.vision and the renderer may import it"]
    assert smc_violations(imports) == [
        "jaxtrack.smc._filter imports jaxtrack.body (line 1, at module level): jaxtrack.smc "
        "imports nothing else of jaxtrack"]
    assert evaluation_violations(imports) == [
        "jaxtrack.evaluation.overlay imports cv2 (line 2, inside a function): "
        "jaxtrack.evaluation holds metrics only",
        "jaxtrack.evaluation.overlay imports jaxtrack.trackers (line 3, inside a function): "
        "jaxtrack.evaluation holds metrics only"]
    assert layer_violations(imports) == [
        "jaxtrack.body.render imports jaxtrack.experiments (line 2, at module level): body "
        "(layer 1) may not import experiments (layer 7)",
        "jaxtrack.smc._filter imports jaxtrack.body (line 1, at module level): smc (layer 0) "
        "may not import body (layer 1)"]


def private_smc_uses(root: Path) -> list[str]:
    """Every place under ``root`` (outside ``jaxtrack/smc/`` itself) that imports a private
    module or name of ``jaxtrack.smc`` or reads a private attribute of ``smc``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        if "smc" in path.relative_to(root).parts[:2] and path.parent.name == "smc" and \
                path.parent.parent.name == "jaxtrack":
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and \
                    node.value.id == "smc" and node.attr.startswith("_"):
                names = [f"smc.{node.attr}"]
            for name in names:
                parts = name.split(".")
                if "smc" in parts and any(part.startswith("_") and not part.startswith("__")
                                          for part in parts[parts.index("smc") + 1:]):
                    found.append(f"{path.relative_to(root)}:{node.lineno} uses {name}")
    return found


def test_nothing_outside_smc_uses_its_private_names(tmp_path):
    """The engine's private modules are its own: the library and its benchmarks use
    ``jaxtrack.smc``'s public names only (the tests of ``smc`` itself may look inside)."""
    root = PACKAGE.parent
    assert [use for folder in ("jaxtrack", "benchmarks", "papers")
            for use in private_smc_uses(root / folder)] == []
    (tmp_path / "a.py").write_text("from jaxtrack.smc._resampling import x\nfrom jaxtrack import "
                                   "smc\nsmc._random.split\n")
    assert private_smc_uses(tmp_path) == ["a.py:1 uses jaxtrack.smc._resampling",
                                          "a.py:1 uses jaxtrack.smc._resampling.x",
                                          "a.py:3 uses smc._random"]


def test_the_published_trackers_run_on_the_engine_and_the_runner():
    """Neither the linear-combination nor the mixed-state tracker scans frames itself (the
    engine and ``track()`` do), and keypoints are never packed into an image channel."""
    trackers = PACKAGE / "trackers"
    for name in ("linear_combination.py", "mixed_state.py"):
        assert "lax.scan" not in (trackers / name).read_text(), name
    assert not [path for path in PACKAGE.rglob("*.py") if "pack_keypoints" in path.read_text()]
