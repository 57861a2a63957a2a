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


def test_the_summary_gives_each_latent_configuration_its_ratio_to_condensation():
    def run(configuration, sequence, error):
        return {"configuration": configuration, "sequence": sequence, "mean_error_torso": error,
                "fraction_within_15": 0.5, "failed": error > 0.25}

    runs = [run("latent, whole body", "a", 0.10), run("latent, whole body", "a", 0.14),
            run("condensation", "a", 0.20), run("condensation", "a", 0.28)]
    rows = hdm05.summarise(runs)
    assert set(rows) == {"latent, whole body", "condensation"}
    assert rows["latent, whole body"]["ratio_to_condensation"]["ratio"] == pytest.approx(0.5)
    assert rows["condensation"]["lost"] == 1 and "ratio_to_condensation" not in rows[
        "condensation"]
    table = hdm05.markdown_table(rows)
    assert "| latent, whole body | 2 | 12.0% |" in table and "| condensation |" in table


def test_bad_arguments_are_refused_in_one_line(capsys, tmp_path):
    with pytest.raises(SystemExit):
        hdm05.main(["--json", str(tmp_path / "out.txt")])
    assert "give a .json file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        hdm05.main(["--json", str(tmp_path / "out.json"), "--seeds", "1"])
    assert "--seeds must be at least 2" in capsys.readouterr().err
