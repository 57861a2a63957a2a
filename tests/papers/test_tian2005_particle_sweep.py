"""The trackers' particle-count sweep (``python -m papers.tian2005.particle_sweep``) runs."""

import json

import pytest

from jaxtrack.priors.train import train_prior
from papers.tian2005 import particle_sweep


@pytest.mark.slow  # a prior trained and three trackers compiled
def test_the_sweep_runs_every_method_and_writes_json(tmp_path, monkeypatch):
    def small_prior(clips, **options):  # the demo's clips, tiny settings
        return train_prior(clips, views=1, fps=5.0, active_size=30, iterations=1,
                           progress=False)

    monkeypatch.setattr(particle_sweep, "train_prior", small_prior)
    out = tmp_path / "sweep.json"
    arguments = ["--particles", "10", "--seeds", "1", "--frames", "4", "--json", str(out),
                 "--plot", str(tmp_path / "sweep.png")]
    assert particle_sweep.main(arguments) == 0
    rows = json.loads(out.read_text())["rows"]
    assert {row["method"] for row in rows} == {"latent", "condensation", "mht"}
    assert all(row["particles"] == 10 for row in rows)
