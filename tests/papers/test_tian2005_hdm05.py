"""``python -m papers.tian2005.hdm05``: the arm takes of each split are one split's actors, the
priors never see a validation or test actor, and the summary compares with CONDENSATION."""

import pytest

from jaxtrack.data.splits import check_disjoint, subject_of
from papers.tian2005 import hdm05


def test_each_split_holds_its_own_actors_arm_takes():
    actors = {split: {subject_of(clip) for clip in hdm05.arm_clips(split)}
              for split in ("training", "validation", "test")}
    assert actors == {"training": {"hdm05:bd", "hdm05:bk", "hdm05:dg"},
                      "validation": {"hdm05:mm"}, "test": {"hdm05:tr"}}
    for split in actors:
        kinds = {clip.split("/")[1] for clip in hdm05.arm_clips(split)}
        assert kinds == set(hdm05.KINDS)
    check_disjoint(hdm05.arm_clips("training"), hdm05.arm_clips("test"))  # raises if shared
    first = hdm05.arm_clips("test", takes_per_kind=1)
    assert len(first) == 3 and {clip.split("/")[1] for clip in first} == set(hdm05.KINDS)
    assert "HDM_tr_grabHighR_023_120" in " ".join(first)  # tr's first reach (takes 023-029)
    assert len(hdm05.arm_clips("training", takes_per_kind=2)) == 2 * 3 * 3  # kinds × actors


def test_the_summary_gives_each_configuration_its_ratio_to_condensation_over_takes():
    def run(configuration, clip, error):
        return {"configuration": configuration, "clip": f"hdm05_cut/grabHighR/{clip}",
                "mean_error_torso": error, "fraction_within_15": 0.5, "failed": error > 0.25}

    runs = [run("latent, whole body", "a", 0.10), run("latent, whole body", "a", 0.14),
            run("latent, whole body", "b", 0.30), run("condensation", "a", 0.20),
            run("condensation", "a", 0.28), run("condensation", "b", 0.36)]
    rows = hdm05.summarise(runs)
    assert set(rows) == {"latent, whole body", "condensation"}
    ratio = rows["latent, whole body"]["ratio_to_condensation"]
    # per take: 0.12 and 0.30 against 0.24 and 0.36; resampling the two takes spans 0.5-0.83
    assert ratio["ratio"] == pytest.approx(0.42 / 0.60)
    assert ratio["low"] == pytest.approx(0.5) and ratio["high"] == pytest.approx(0.30 / 0.36)
    assert rows["condensation"]["lost"] == 2 and "ratio_to_condensation" not in rows[
        "condensation"]
    assert rows["latent, whole body"]["by_kind"] == {"grabHighR": pytest.approx(0.18)}
    table = hdm05.markdown_table(rows)
    assert "| latent, whole body | 2 | 3 | 18.0% |" in table and "| condensation |" in table


def test_the_sampler_rule_keeps_one_step_unless_partitioned_is_clearly_lower():
    def runs(differences):
        return [record for index, difference in enumerate(differences) for record in (
            {"configuration": "latent, per part", "clip": f"take{index}",
             "mean_error_torso": 0.3},
            {"configuration": "latent, per part, partitioned", "clip": f"take{index}",
             "mean_error_torso": 0.3 + difference})]

    assert hdm05.choose_sampler(runs([-0.05, -0.06, -0.04]))[0] == (
        "latent, per part, partitioned")
    noisy, evidence = hdm05.choose_sampler(runs([-0.2, 0.1, -0.05]))
    assert noisy == "latent, per part" and evidence["takes"] == 3  # lower, within the noise
    assert hdm05.choose_sampler(runs([0.05, 0.06, 0.04]))[0] == "latent, per part"


def test_takes_all_or_first():
    assert hdm05.takes_of("test", "first") == hdm05.arm_clips("test", takes_per_kind=1)
    assert len(hdm05.takes_of("test", "all")) == len(hdm05.arm_clips("test")) > 3
    with pytest.raises(ValueError, match="takes must be one of all, first"):
        hdm05.takes_of("test", "some")


def test_bad_arguments_are_refused_in_one_line(capsys, tmp_path):
    with pytest.raises(SystemExit):
        hdm05.main(["--json", str(tmp_path / "out.txt")])
    assert "give a .json file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        hdm05.main(["--json", str(tmp_path / "out.json"), "--seeds", "0"])
    assert "--seeds and --validation-seeds must be at least 1" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        hdm05.main(["--json", str(tmp_path / "out.json"), "--takes", "some"])
    assert "invalid choice: 'some'" in capsys.readouterr().err
