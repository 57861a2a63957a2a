"""``python -m papers.ong2002``'s reading of the Fig. 10/12 surfaces and of the test table (the
runs themselves track many clips and are scripts, not tests)."""

import numpy as np
import pytest

from papers.ong2002 import __main__ as ong2002
from papers.ong2002.surface import grid, heat_map, trends

CLUSTERS, SAMPLES = (10, 40, 100), (20, 100, 300)


def _rows(error_mm, noise_mm=0.0, seed=0):
    """Surface rows whose ``training_m`` is ``error_mm(clusters, samples)`` plus noise."""
    rng = np.random.default_rng(seed)
    return [{"clusters": c, "samples": s,
             "training_m": 1e-3 * (error_mm(c, s) + noise_mm * rng.standard_normal())}
            for c in CLUSTERS for s in SAMPLES]


def test_a_surface_falling_with_samples_and_clusters_reads_so_and_one_that_overfits_too():
    falling = trends(_rows(lambda c, s: 200 - 0.5 * c - 0.1 * s, noise_mm=1.0), "training_m")
    assert falling["falls_with_samples"] and falling["falls_with_clusters"]
    assert not falling["overfits_with_clusters"] and falling["best_clusters"] == 100
    assert falling["best_point"] == {"clusters": 100, "samples": 300,
                                     "error_mm": pytest.approx(120, abs=5)}
    overfitting = trends(_rows(lambda c, s: 200 + abs(c - 40)), "training_m")
    assert overfitting["overfits_with_clusters"] and overfitting["falls_with_clusters"]
    assert overfitting["best_clusters"] == 40 and not overfitting["falls_with_samples"]


def test_a_difference_within_the_noise_is_not_called_a_trend():
    flat = trends(_rows(lambda c, s: 200.0 + (5.0 if s == 20 else 0.0), noise_mm=20.0),
                  "training_m")
    assert flat["noise_mm"] > 5 and not flat["falls_with_samples"]
    assert not flat["falls_with_clusters"] and not flat["overfits_with_clusters"]


def test_a_grid_with_a_hole_is_refused_and_the_heat_map_is_written(tmp_path):
    rows = _rows(lambda c, s: 100.0 + c)
    clusters, samples, errors = grid(rows, "training_m")
    assert clusters == list(CLUSTERS) and samples == list(SAMPLES)
    np.testing.assert_allclose(errors[:, 0], [110, 140, 200])
    with pytest.raises(ValueError, match="holes"):
        trends(rows[1:], "training_m")
    path = heat_map(rows, "training_m", tmp_path / "surface.png", title="t",
                    reference=("a constant", 150.0))
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_every_row_below_the_tracker_is_named_per_score():
    tracker = {"method": "linear-combination", "estimate": "mean", "error_m": 0.25,
               "aligned_m": 0.15}
    rows = [tracker,
            {"method": "nearest-neighbour", "estimate": "-", "error_m": 0.27, "aligned_m": 0.12},
            {"method": "constant", "estimate": "-", "error_m": 0.24, "aligned_m": 0.23}]
    found = ong2002.beats(rows, tracker)
    assert [row["method"] for row in found["error_m"]] == ["constant"]
    assert found["aligned_m"] == [{"method": "nearest-neighbour", "estimate": "-",
                                   "below_tracker_mm": 30.0}]


def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys):
    for argv in (["--json", str(tmp_path / "out.txt")],
                 ["--json", str(tmp_path / "missing" / "out.json")],
                 ["--json", str(tmp_path / "out.json"), "--clusters", "1"],
                 ["--json", str(tmp_path / "out.json"), "--view-frames", "5"]):
        with pytest.raises(SystemExit):
            ong2002.main(argv)
        assert "--" in capsys.readouterr().err.strip().splitlines()[-1]
    assert not list(tmp_path.iterdir())
