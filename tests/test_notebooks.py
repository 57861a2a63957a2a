"""Every notebook in ``notebooks/`` runs end to end, as a user without the shared data would run it.

Each jupytext ``.py`` notebook is converted to a notebook (jupytext), executed cell by cell in a
fresh Python kernel (nbclient) in an empty folder, with ``JAXTRACK_SMOKE=1`` so that it picks
its small sizes (a few frames, a few particles, a small prior, one variant of each comparison:
compile time dominates), and with XLA's cheap compile mode. A cell that raises fails the test
with the cell's traceback.

The project's full data collection (``shared/data``, found by ``jaxtrack.data`` in any folder
above the package or the working directory, or named by ``$JAXTRACK_DATA``) is hidden from the
kernel: ``$JAXTRACK_DATA`` is unset, ``JAXTRACK_NO_SHARED=1`` stops the catalogue from looking
above the package or the working directory, and a first cell (not part of the notebook) installs
a Python audit hook that refuses to open any file inside the collection, so a notebook that needs
more than the files bundled with jaxtrack fails here as it would on a user's machine.

The mixed-state notebook's posture clips are in the shared collection only: hidden, it shows a
bundled clip's frame and skips the rest, so it also runs once with the collection in view
(skipped where there is none) to check its Table 1.

Each ``.py`` has a rendered ``.ipynb`` beside it, committed with its outputs for the
documentation site (mkdocs-jupyter shows it, never runs it): its code must be the ``.py``'s and
every code cell must have run, without an error, with a figure among the outputs. Re-render after
changing a notebook's code (from the repository root, shared data in view; ``JAXTRACK_SMOKE=1``
where the full sizes are too slow, as the notebook's first cell then says)::

    .venv/bin/jupytext --to ipynb --execute --run-path . notebooks/NAME.py
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")
nbformat = pytest.importorskip("nbformat")
pytest.importorskip("ipykernel")

NOTEBOOKS = sorted((Path(__file__).parents[1] / "notebooks").glob("*.py"))
CELL_TIMEOUT = 900  # seconds; a hung cell fails instead of stalling the suite
LATENT_BOUND = 0.25  # torso lengths, 02's latent tracker from frame 0's truth: not lost
SKELETON_BOUND = 0.5  # mean 3-D skeleton error in metres, 04's tracker and baselines


def _hide_shared_data(shared: Path | None) -> str:
    """Code for the kernel's first cell: ``shared`` unreadable, only the bundled files found."""
    return f"""
import sys
from pathlib import Path

import jaxtrack.data

_SHARED = {str(shared.resolve()) if shared else None!r}


def _refuse_shared(event, arguments, shared=_SHARED, Path=Path):  # bound: globals go at exit
    if shared and event == "open" and isinstance(arguments[0], (str, bytes, Path)):
        opened = Path(arguments[0].decode() if isinstance(arguments[0], bytes) else arguments[0])
        if str(opened.resolve()).startswith(shared):
            raise FileNotFoundError(f"the notebook opened {{opened}}, inside the shared data "
                                    "folder a user does not have")


sys.addaudithook(_refuse_shared)
assert jaxtrack.data.shared_folder() is None  # JAXTRACK_NO_SHARED=1 reached the kernel
"""


def _execute(text: str, folder: Path, monkeypatch, *, hide_shared: bool = True
             ) -> tuple[str | None, str]:
    """Run a py:percent notebook in smoke mode without the shared data (with it, named by
    ``$JAXTRACK_DATA``, when ``hide_shared`` is false), in ``folder``.

    Returns the error of the first failing cell (None if every cell ran) and what every
    cell printed to stdout."""
    from jaxtrack.data import shared_folder

    monkeypatch.delenv("JAXTRACK_DATA", raising=False)
    monkeypatch.delenv("JAXTRACK_NO_SHARED", raising=False)
    shared = shared_folder()
    if hide_shared:
        monkeypatch.setenv("JAXTRACK_NO_SHARED", "1")  # no shared/data nor tests/data
    elif shared is not None:
        monkeypatch.setenv("JAXTRACK_DATA", str(shared))
    monkeypatch.setenv("JAXTRACK_SMOKE", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    # compile time dominates at smoke sizes; XLA's cheap mode about halves it (measured on the
    # latent-tracker notebook: 349 s against 560 s of wall time on 2 busy cores)
    monkeypatch.setenv("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")
    document = jupytext.reads(text, fmt="py:percent")
    if hide_shared:
        document.cells.insert(0, nbformat.v4.new_code_cell(_hide_shared_data(shared)))
    client = nbclient.NotebookClient(document, timeout=CELL_TIMEOUT, kernel_name="python3",
                                     resources={"metadata": {"path": str(folder)}})
    try:
        client.execute()
        error = None
    except nbclient.exceptions.CellExecutionError as raised:
        error = str(raised)
    return error, _outputs_text(document)


def test_there_are_notebooks_to_run():
    assert [path.name for path in NOTEBOOKS][:2] == ["01_engine_tour.py", "02_latent_tracker.py"]


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=lambda path: path.stem)
def test_notebook_runs_in_smoke_mode_without_shared_data(notebook, tmp_path, monkeypatch):
    text = notebook.read_text()
    assert "shared/data" not in text and "../shared" not in text, (
        f"{notebook.name} names the shared data folder; read bundled files with "
        "jaxtrack.data.path(...) instead")
    assert 'os.environ.get("JAXTRACK_SMOKE")' in text, f"{notebook.name} has no smoke mode"
    start = time.perf_counter()
    error, printed = _execute(text, tmp_path, monkeypatch)
    if error is not None:
        pytest.fail(f"{notebook.name} failed in smoke mode:\n{error}", pytrace=False)
    print(f"{notebook.name}: {time.perf_counter() - start:.0f} s in smoke mode")
    _check_numbers(notebook.name, printed)


def _check_numbers(name: str, printed: str) -> None:
    """What each notebook prints, checked against what its method must give (smoke sizes or
    full: the bounds hold for both)."""
    if name.startswith("01_"):
        # the particle filter's log evidence against the Kalman filter's, 50 frames
        pairs = re.findall(r"PF\s+(\S+)\s+Kalman\s+(\S+)", printed)
        assert len(pairs) >= 2
        assert all(abs(float(pf) - float(kalman)) < 3.0 for pf, kalman in pairs), printed
        # the stop-gradient estimator is unbiased for the score: its mean over seeds is within
        # four of its standard errors of the Kalman filter's exact gradient
        exact = float(re.search(r"exact gradient (\S+);", printed).group(1))
        mean, error = map(float, re.search(
            r"StopGradient\s+mean\s+(\S+)\s+sd\s+\S+\s+standard error\s+(\S+)", printed).groups())
        assert abs(mean - exact) < 4 * error, printed
    elif name.startswith("02_"):
        # both trackers start from frame 0's truth on a held-out take: finite errors, the latent
        # tracker's (with its refinement) within LATENT_BOUND of the torso
        errors = dict(re.findall(r"^(latent|condensation)\s+(\S+) of torso", printed,
                                 flags=re.MULTILINE))
        assert set(errors) == {"latent", "condensation"}, printed
        assert all(np.isfinite(float(value)) for value in errors.values()), printed
        assert float(errors["latent"]) < LATENT_BOUND, printed
    elif name.startswith("04_"):
        errors = re.findall(r"^(\S+)\s+mean 3-D error (\S+) m", printed, flags=re.MULTILINE)
        assert len(errors) == 3, printed  # the tracker and its two baselines
        assert all(0 < float(value) < SKELETON_BOUND for _, value in errors), printed
        # the per-frame best view bounds any selection from below, the worst from above
        selected, best, worst = map(float, re.search(
            r"selected view (\S+) m, best view per frame \(oracle\) (\S+) m, worst view (\S+) m",
            printed).groups())
        assert best <= selected <= worst, printed


def _outputs_text(document) -> str:
    """What the code cells printed to stdout (stderr holds progress bars, without newlines)."""
    return "".join(output.get("text", "") for cell in document.cells if cell.cell_type == "code"
                   for output in cell.get("outputs", [])
                   if output.get("output_type") == "stream" and output.get("name") == "stdout")


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=lambda path: path.stem)
def test_the_rendered_notebook_is_its_source_run(notebook):
    """The ``.ipynb`` the documentation shows is the ``.py`` run: same code, every cell run
    without an error, a figure among its outputs and its printed numbers within the bounds the
    smoke runs are held to."""
    rendered = notebook.with_suffix(".ipynb")
    assert rendered.is_file(), f"{rendered.name} is missing: render it (module docstring)"
    source = jupytext.read(notebook)
    document = nbformat.read(rendered, as_version=4)
    code = [cell for cell in document.cells if cell.cell_type == "code"]
    assert [cell.source for cell in code] == [
        cell.source for cell in source.cells if cell.cell_type == "code"], (
        f"{rendered.name} was run from other code than {notebook.name}: render it again")
    assert all(cell.execution_count is not None for cell in code), (
        f"{rendered.name}: a cell never ran")
    outputs = [output for cell in code for output in cell.get("outputs", [])]
    assert not [output for output in outputs if output.get("output_type") == "error"]
    assert any("image/png" in output.get("data", {}) for output in outputs), (
        f"{rendered.name} has no figure: run it with matplotlib's inline backend")
    _check_numbers(notebook.name, _outputs_text(document))


def test_the_mixed_state_notebook_reproduces_table_1_from_the_shared_posture_clips(
        tmp_path, monkeypatch):
    """03 without the posture clips shows a bundled frame only; with them (the shared data,
    skipped where there is none) it trains, prints Table 1 with every estimate's row finite,
    and re-tracks one sequence to the scores ``evaluate`` gave it (checked in the notebook)."""
    from jaxtrack.data import list_clips

    monkeypatch.delenv("JAXTRACK_NO_SHARED", raising=False)
    if "cmu_posture_bvh/139_16" not in list_clips():
        pytest.skip("the posture clips are in the project's shared data, not found here")
    notebook = NOTEBOOKS[0].with_name("03_mixed_state.py")
    start = time.perf_counter()
    error, printed = _execute(notebook.read_text(), tmp_path, monkeypatch, hide_shared=False)
    if error is not None:
        pytest.fail(f"{notebook.name} failed with the shared data:\n{error}", pytrace=False)
    print(f"{notebook.name}: {time.perf_counter() - start:.0f} s in smoke mode, shared data")
    rows = re.findall(r"^\| (instantaneous|filtered|smoothed|fixed-lag)[^|\n]*((?:\|[^|\n]*)+)\|$",
                      printed, flags=re.MULTILINE)
    assert [name for name, _ in rows] == ["instantaneous", "filtered", "smoothed",
                                          "fixed-lag"] * 2, printed
    for _, cells in rows:
        values = [np.nan if cell.strip() == "n/a" else float(cell)
                  for cell in cells.strip("|").split("|")]
        assert len(values) == 6 and all(np.isfinite(values)) and min(values) >= 0, printed
    assert "(evaluate: " in printed, printed


def test_the_smoke_runs_cannot_read_the_shared_data(tmp_path, monkeypatch):
    """The hiding itself: a notebook that reads the shared collection fails here."""
    from jaxtrack.data import shared_folder

    monkeypatch.delenv("JAXTRACK_DATA", raising=False)
    monkeypatch.delenv("JAXTRACK_NO_SHARED", raising=False)
    shared = shared_folder()
    if shared is None:
        pytest.skip("no shared data folder on this machine: nothing to hide")
    readme = next(path for path in sorted(shared.rglob("*")) if path.is_file())
    for cell in (f"open({str(readme)!r}).read()",
                 "import jaxtrack.data\njaxtrack.data.path('pose2sim/videos/cam03.mp4')"):
        error, _ = _execute(f"# %%\n{cell}\n", tmp_path, monkeypatch)
        assert error is not None and "FileNotFoundError" in error, cell
