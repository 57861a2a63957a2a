"""``python -m papers.tian2005``: the paper's protocol trains on the same person, the held-out
one on other people; the ratio's interval is over seeds; bad arguments are refused in one line."""

import json

import numpy as np
import pytest

from jaxtrack.data.clip_sets import TRAINING_CLIPS
from jaxtrack.data.splits import check_disjoint, subject_of
from papers.tian2005 import protocols
from papers.tian2005.__main__ import main

HELLO_1, HELLO_2 = protocols.TEST_CLIPS


def test_the_papers_protocol_trains_on_the_same_persons_other_take():
    assert protocols.training_clips("paper", HELLO_2) == (HELLO_1,)
    assert protocols.training_clips("paper", HELLO_1) == (HELLO_2,)
    assert subject_of(HELLO_1) == subject_of(HELLO_2)
    with pytest.raises(ValueError, match="is in both"):  # what the held-out protocol refuses
        check_disjoint(protocols.training_clips("paper", HELLO_2), [HELLO_2])


def test_the_held_out_protocol_trains_on_other_people():
    clips = protocols.training_clips("held_out", HELLO_2)
    assert clips == TRAINING_CLIPS
    assert {subject_of(clip) for clip in clips}.isdisjoint({subject_of(HELLO_2)})


def test_unknown_protocols_and_clips_are_refused():
    with pytest.raises(ValueError, match="protocol must be one of"):
        protocols.training_clips("same_take", HELLO_1)
    with pytest.raises(ValueError, match="is not one of the test clips"):
        protocols.same_person_training(TRAINING_CLIPS[0])
    with pytest.raises(ValueError, match="has no other take"):
        protocols.same_person_training(HELLO_1, clips=(HELLO_1,))


def test_the_ratio_is_of_the_means_and_its_interval_is_over_seeds():
    latent = {"a": [0.10, 0.10, 0.10], "b": [0.20, 0.20, 0.20]}
    condensation = {"a": [0.30, 0.30, 0.30], "b": [0.30, 0.30, 0.30]}
    ratio, low, high = protocols.ratio_interval(latent, condensation)
    assert ratio == pytest.approx(0.5) and low == pytest.approx(0.5) and high == pytest.approx(0.5)
    noisy = {"a": [0.05, 0.10, 0.15], "b": [0.10, 0.20, 0.30]}
    ratio, low, high = protocols.ratio_interval(noisy, condensation)
    assert ratio == pytest.approx(0.5) and low < 0.45 and high > 0.55
    with pytest.raises(ValueError, match="same sequences"):
        protocols.ratio_interval({"a": [0.1]}, {"b": [0.1]})


def test_the_summary_says_whether_the_target_is_met():
    def run(method, sequence, error, failed=False):
        return {"method": method, "sequence": sequence, "particles": protocols.PARTICLES[method],
                "mean_error_torso": error, "mean_error_px": 100 * error,
                "fraction_within_15": 1.0, "failed": failed}

    runs = [run("latent", "s", 0.10), run("latent", "s", 0.12),
            run("condensation", "s", 0.30), run("condensation", "s", 0.20, failed=True)]
    summary = protocols.summarise(runs)
    assert summary["rows"]["latent"]["error_torso"] == pytest.approx(0.11)
    assert summary["rows"]["condensation"]["lost"] == 1
    ratio = summary["ratio_latent_over_condensation"]
    assert ratio["ratio"] == pytest.approx(0.44) and ratio["met"]
    runs[0]["mean_error_torso"] = 0.30
    assert not protocols.summarise(runs)["ratio_latent_over_condensation"]["met"]
    results = {"protocols": {"paper": summary}}
    assert "| paper | latent | 200 | 2 | 11.0% |" in protocols.markdown_table(results)


@pytest.mark.parametrize("argv, message", [
    (["--json", "out.txt"], "must end in .json"),
    (["--json", "no/such/folder/out.json"], "does not exist"),
    (["--json", "out.json", "--seeds", "1"], "--seeds must be at least 2"),
    (["--json", "out.json", "--max-frames", "20"], "at least 31"),
])
def test_bad_arguments_are_refused_in_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit):
        main(argv)
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_a_small_run_writes_the_table_and_the_json(tmp_path, monkeypatch):
    import papers.tian2005
    from jaxtrack.priors import train

    original = train.train_prior

    def small(clips, **options):  # tiny priors, the same for every protocol
        return original(clips, views=1, fps=10.0, active_size=30, iterations=1,
                                 progress=False)

    monkeypatch.setattr(train, "train_prior", small)
    monkeypatch.setattr(papers.tian2005, "candidate_prior",
                        lambda name: small(TRAINING_CLIPS))
    out = tmp_path / "tian.json"
    assert main(["--json", str(out), "--seeds", "2", "--views", "1", "--max-frames", "32"]) == 0
    found = json.loads(out.read_text())
    assert set(found["protocols"]) == {"paper", "held_out"}
    assert found["protocols"]["paper"]["training_clips"][HELLO_2] == [HELLO_1]
    assert len(found["runs"]) == 2 * 2 * 3 * 2  # protocols × clips × methods × seeds
    assert all(np.isfinite(run["mean_error_torso"]) for run in found["runs"])
    assert out.with_suffix(".md").read_text().count("| paper |") == 4  # 3 methods + the ratio
    assert out.with_suffix(".png").stat().st_size > 1000
