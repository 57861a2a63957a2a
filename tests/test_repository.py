"""The repository a researcher opens: a README of at most 150 lines whose paper tables are the
committed results (``python -m papers.tables``), and ``benchmarks/`` holding speed only, in at
most 12 modules (the papers' studies live in ``papers/``)."""

from pathlib import Path

from papers import tables

ROOT = Path(__file__).resolve().parents[1]


def test_the_readme_is_a_users_page_of_at_most_150_lines():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 150, f"README.md has {len(lines)} lines"


def test_the_readmes_paper_tables_are_the_committed_results():
    assert tables.main(["--check"]) == 0


def test_benchmarks_hold_at_most_12_modules():
    modules = sorted(path.name for path in (ROOT / "benchmarks").glob("*.py"))
    assert len(modules) <= 12, modules
