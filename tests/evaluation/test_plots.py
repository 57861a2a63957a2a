"""Plots: PNG files are written, a failed save leaves nothing behind, bad input is refused."""

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from matplotlib.figure import Figure  # noqa: E402
from matplotlib.image import imread  # noqa: E402

from jaxtrack.evaluation import (  # noqa: E402
    plot_errors_over_time,
    plot_fraction_within,
    plot_particle_sweep,
)

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

ERRORS = {"gplvm": np.linspace(0.0, 0.4, 50), "baseline": np.full(30, 0.2)}
CURVES = {"gplvm": {"0.05": 0.1, "0.1": 0.4, "0.15": 0.7, "0.5": 1.0},
          "baseline": {0.05: 0.0, 0.5: 0.6, 0.1: 0.2}}
SWEEP = [{"method": method, "particles": n, "mean_error_torso": 1 / np.log(n + 1),
          "ms_per_frame": None if n == 1 else 0.01 * n}
         for method in ("gplvm", "baseline") for n in (1, 10, 100, 1000)]


def write_all(folder):
    return [plot_errors_over_time(ERRORS, folder / "errors.png", title="walk", fps=30),
            plot_fraction_within(CURVES, folder / "within.png"),
            plot_particle_sweep(SWEEP, folder / "sweep.png")]


def test_plots_write_png_files_and_nothing_else(tmp_path):
    paths = write_all(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["errors.png", "sweep.png", "within.png"]
    for path in paths:
        assert path.read_bytes()[:8] == PNG_SIGNATURE
        pixels = imread(path)
        assert pixels.ndim == 3 and pixels.shape[0] > 100 and pixels.shape[1] > 100
        assert pixels[..., :3].std() > 0.01  # something was drawn, not a blank canvas
    sweep = imread(paths[2])
    assert sweep.shape[1] > 1.8 * sweep.shape[0]  # two panels side by side


def test_fraction_within_accepts_whole_results(tmp_path):
    path = plot_fraction_within({"gplvm": {"fraction_within": CURVES["gplvm"], "failed": False}},
                                tmp_path / "within.png")
    assert path.read_bytes()[:8] == PNG_SIGNATURE


def test_a_failing_save_leaves_no_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    old = tmp_path / "errors.png"
    old.write_bytes(b"previous figure")

    def broken_savefig(self, file, **kwargs):
        file.write(PNG_SIGNATURE + b"half a figure")
        raise RuntimeError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken_savefig)
    with pytest.raises(RuntimeError, match="disk full"):
        plot_errors_over_time(ERRORS, old)
    with pytest.raises(RuntimeError, match="disk full"):
        plot_particle_sweep(SWEEP, tmp_path / "sweep.png")
    assert [p.name for p in tmp_path.iterdir()] == ["errors.png"]
    assert old.read_bytes() == b"previous figure"


def test_unknown_format_leaves_no_file(tmp_path):
    with pytest.raises(ValueError, match="xyz"):
        plot_fraction_within(CURVES, tmp_path / "within.xyz")
    assert list(tmp_path.iterdir()) == []


def test_bad_input_is_refused(tmp_path):
    with pytest.raises(ValueError, match="empty"):
        plot_errors_over_time({}, tmp_path / "e.png")
    with pytest.raises(ValueError, match=r"errors_torso\['gplvm'\]"):
        plot_errors_over_time({"gplvm": np.zeros((3, 2))}, tmp_path / "e.png")
    with pytest.raises(ValueError, match=r"curves\['gplvm'\]"):
        plot_fraction_within({"gplvm": {"tight": 0.5}}, tmp_path / "f.png")
    with pytest.raises(ValueError, match=r"rows\[0\] lacks \['ms_per_frame'\]"):
        plot_particle_sweep([{"method": "a", "particles": 10, "mean_error_torso": 0.1}],
                            tmp_path / "s.png")
    assert list(tmp_path.iterdir()) == []


def test_error_surface_draws_a_line_per_cluster_count_and_refuses_incomplete_rows(tmp_path):
    from jaxtrack.evaluation import plot_error_surface

    rows = [{"clusters": clusters, "samples": samples, "training_m": 0.1 / clusters,
             "test_m": 0.25 + 0.001 * samples}
            for clusters in (10, 40) for samples in (20, 100, 300)]
    path = plot_error_surface(rows, tmp_path / "surface.png", title="grid")
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert imread(path)[..., :3].std() > 0.01
    with pytest.raises(ValueError, match="rows is empty"):
        plot_error_surface([], tmp_path / "empty.png")
    with pytest.raises(ValueError, match=r"rows\[1\] lacks \['test_m'\]"):
        plot_error_surface([rows[0], {"clusters": 10, "samples": 50, "training_m": 0.1}],
                           tmp_path / "bad.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["surface.png"]
