"""The scripted comparison (``python -m papers.tian2005.tracking``): statistics and a quick run."""

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

import papers.tian2005
from jaxtrack.data.splits import check_disjoint, split_of
from papers.tian2005 import tracking


def test_t_interval_is_the_students_t_half_width():
    values = [0.10, 0.12, 0.08, 0.11]
    expected = 3.182446 * np.std(values, ddof=1) / 2  # t(0.975, 3) × s / √4
    assert tracking.t_interval(values) == pytest.approx(expected, rel=1e-5)
    assert tracking.t_interval([0.1]) == 0.0


def test_summarise_groups_runs_by_configuration():
    def run(method, estimate, error, failed, seed):
        return {"method": method, "estimate": estimate, "likelihood": "limbs+edges",
                "particles": 200, "sequence": "s", "seed": seed, "mean_error_torso": error,
                "mean_error_px": 100 * error, "fraction_within_15": 1 - error, "failed": failed,
                "ms_per_frame": 10.0 + seed, "compile_seconds": 5.0 - seed}

    rows = tracking.summarise([run("latent", "own", 0.2, True, 0), run("latent", "own", 0.1,
                                                                      False, 1),
                               run("condensation", "refined", 0.05, False, 0)])
    assert [(row["method"], row["estimate"]) for row in rows] == [("latent", "own"),
                                                                   ("condensation", "refined")]
    latent = rows[0]
    assert latent["runs"] == 2 and latent["lost"] == "1/2"
    assert latent["error_torso"] == pytest.approx(0.15)
    assert latent["ms_per_frame"] == pytest.approx(10.5) and latent["compile_seconds"] == 5.0
    assert "| latent | own |" in tracking.markdown_table(rows)


@pytest.mark.slow  # a prior trained and two trackers compiled: about a minute on 2 cores
def test_quick_comparison_writes_every_output(tmp_path, monkeypatch):
    # automatically initialised, as a user without ground truth would run it
    monkeypatch.setattr(tracking, "RESULTS", tmp_path / "results")
    monkeypatch.setattr(papers.tian2005, "RUNS", tmp_path / "results")  # the prior's cache
    out = tmp_path / "quick"
    assert tracking.main(["--quick", "--init", "auto", "--particles", "latent=50",
                          "--out", str(out)]) == 0
    runs = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert len(runs) == 4 and {run["estimate"] for run in runs} == {"own", "refined"}
    assert {(run["method"], run["particles"]) for run in runs} == {("latent", 50),
                                                                   ("condensation", 1000)}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["split"] == "test" and summary["baseline_dynamics"] == "training"
    (found,) = summary["auto_init"]
    assert found["overlap"] > 0.35 and np.isfinite(found["error_torso"])
    assert "initialised automatically" in (out / "table.md").read_text()
    assert all(np.isfinite(row["error_torso"]) for row in summary["rows"])
    assert (out / "errors.png").stat().st_size > 1000
    assert "error/torso" in (out / "table.md").read_text()


def test_bad_arguments_are_refused_in_one_line(capsys):
    with pytest.raises(SystemExit):
        tracking.main(["--seeds", "0"])
    assert "--seeds must be at least 1" in capsys.readouterr().err


def test_a_setting_is_parsed_and_a_bad_one_refused_in_one_line(capsys):
    assert tracking._setting("edge_weight=0.5") == ("edge_weight", 0.5)
    for bad in ("edge_weight", "edge_weight=x", "sharpness=2", "edge_weight=nan"):
        with pytest.raises(SystemExit):
            tracking.main(["--set", bad])
        assert "--set takes NAME=VALUE" in capsys.readouterr().err


def test_a_particle_count_is_parsed_and_a_bad_one_refused_in_one_line(capsys):
    assert tracking._particles("latent=1000") == ("latent", 1000)
    for bad in ("latent", "latent=0", "latent=2.5", "kalman=10"):
        with pytest.raises(SystemExit):
            tracking.main(["--particles", bad])
        assert "--particles takes METHOD=N" in capsys.readouterr().err


def test_clips_of_another_split_or_of_no_subject_are_refused_in_one_line(capsys):
    for clip, message in (("animateddrawings/fair1_wave_hello", "is a training subject's clip"),
                          ("my/own_take", "belongs to no subject")):
        with pytest.raises(SystemExit):
            tracking.main(["--split", "validation", "--clips", clip])
        assert message in capsys.readouterr().err


def test_the_wide_validation_set_is_the_validation_subjects_gestures(capsys):
    clips = tracking.WIDE_VALIDATION_CLIPS
    assert clips[:3] == tracking.GESTURE_CLIPS["validation"] and len(set(clips)) == 9
    assert {split_of(clip) for clip in clips} == {"validation"}
    check_disjoint(tracking.PRIOR_CLIPS["gestures"], clips)
    with pytest.raises(SystemExit):
        tracking.main(["--split", "test", "--clips", "wide"])
    assert "--clips wide names validation clips, and --split is test" in capsys.readouterr().err


def test_partitioned_sampling_needs_the_part_priors(capsys):
    for argv in (["--set", "partitioned=1"], ["--parts", "--set", "partitioned=2"]):
        with pytest.raises(SystemExit):
            tracking.main(argv)
        assert "--set partitioned=1 needs --parts" in capsys.readouterr().err


def test_a_setting_reaches_the_tracker_it_belongs_to(monkeypatch):
    built = []

    def fake_build(method, prior, sequence, particles, likelihood, **options):
        built.append((method, likelihood, options["latent_options"], options["mht_options"]))
        raise RuntimeError("stop")

    monkeypatch.setattr(tracking, "build_tracker", fake_build)
    settings = {"edge_weight": 2.0, "jump_probability": 0.1, "prior_scale": 2.0}
    for method, kind in (("latent", "limbs+edges"), ("condensation", "markers"),
                         ("mht", "limbs+edges")):
        with pytest.raises(RuntimeError, match="stop"):
            tracking.run_one(None, None, {"method": method, "estimate": "own",
                                          "likelihood": kind}, 0, 10, "training",
                             settings=settings)
    latent, condensation, mht = built
    assert latent[1].edge_weight == 2.0 and latent[2] == {"jump_probability": 0.1}
    assert latent[3] is None
    assert condensation[1].edge_weight is None and condensation[2:] == (None, None)
    assert mht[1].edge_weight == 2.0 and mht[2] is None and mht[3] == {"prior_scale": 2.0}


def test_the_test_grid_tracks_the_real_videos_with_the_same_methods(tmp_path, monkeypatch):
    from papers.tian2005 import real_video

    called = []

    def fake_real_video(argv):
        called.append(argv)
        out = argv[argv.index("--out") + 1]
        Path(out).write_text(json.dumps({"frames": None, "table": "| latent | own | x |"}))
        return 0

    monkeypatch.setattr(real_video, "main", fake_real_video)
    text = tracking.real_video_table(tmp_path, ("latent", "mht"), ("refined",))
    (argv,) = called
    assert argv[argv.index("--methods") + 1:argv.index("--estimates")] == ["latent", "mht"]
    assert argv[argv.index("--estimates") + 1] == "refined"
    assert "Real video" in text and "| latent | own | x |" in text

    def parsed(*extra):
        namespace = argparse.Namespace(no_real_video=False, quick=False, split="test",
                                       baseline_dynamics="training", keypoints="none")
        for name, value in extra:
            setattr(namespace, name, value)
        return namespace

    assert tracking.wants_real_video(parsed(), "waves", {})
    assert not tracking.wants_real_video(parsed(("quick", True)), "waves", {})
    assert not tracking.wants_real_video(parsed(("split", "validation")), "waves", {})
    assert not tracking.wants_real_video(parsed(("no_real_video", True)), "waves", {})
    assert not tracking.wants_real_video(parsed(), "gestures", {})
    assert not tracking.wants_real_video(parsed(), "waves", {"edge_weight": 2.0})
    assert not tracking.wants_real_video(parsed(("keypoints", "mediapipe")), "waves", {})


def test_a_failed_real_video_run_is_not_reported_as_a_table(tmp_path, monkeypatch):
    from papers.tian2005 import real_video

    monkeypatch.setattr(real_video, "main", lambda argv: 2)
    with pytest.raises(RuntimeError, match="papers.tian2005.real_video failed"):
        tracking.real_video_table(tmp_path, ("latent",), ("own",))
