"""What ``pip install jaxtrack`` gives, without the project's data collection
(``JAXTRACK_NO_SHARED=1``) and in an empty folder: ``jaxtrack train --method M`` learns from the
clips bundled with the package, and ``jaxtrack track --method M`` runs every tracker with no
``--model`` on the bundled Pose2Sim clip, from the models bundled in ``jaxtrack.data.models``."""

import json

import pytest

from jaxtrack.cli import main
from jaxtrack.data import bundled_folder
from jaxtrack.data.models import default_model, describe

VIDEO = bundled_folder() / "pose2sim_demo_singleperson" / "videos" / "cam03_half.mp4"
CALIBRATION = bundled_folder() / "pose2sim_demo_singleperson" / "Calib.qca.txt"
# an upright upper body in the middle of the 544 x 960 frame (tests/cli/test_track_methods.py)
POSE = (272, 200, 272, 260, 272, 340, 272, 480, 222, 270, 205, 360, 200, 440, 245, 480,
        322, 270, 340, 360, 345, 440, 300, 480)


@pytest.fixture(autouse=True)
def installed_package_only(monkeypatch, tmp_path):
    """No shared/data nor tests/data: what an installed package finds; run in an empty folder."""
    monkeypatch.setenv("JAXTRACK_NO_SHARED", "1")
    monkeypatch.delenv("JAXTRACK_DATA", raising=False)
    monkeypatch.chdir(tmp_path)


def _run(capsys, arguments) -> str:
    code = main([str(argument) for argument in arguments])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured.out


def test_train_linear_combination_learns_from_the_bundled_clips(tmp_path, capsys):
    from jaxtrack.experiments.linear_combination import load

    out = _run(capsys, ["train", "--method", "linear-combination", "--out", "lc.npz",
                        "--cameras", "2", "--max-frames", "3", "--clusters", "2"])
    assert "from 4 clip(s) x 1 camera(s)" in out, out
    trained = load(tmp_path / "lc.npz")
    assert trained.description["clips"] == describe("linear-combination")["clips"]
    assert trained.model.num_clusters == 2


@pytest.mark.slow  # about 10 s of CPU rendering, more on a loaded machine
def test_train_mixed_state_learns_every_posture_from_the_bundled_clips(tmp_path, capsys):
    from jaxtrack.priors.postures import POSTURE_NAMES, load_posture_model

    out = _run(capsys, ["train", "--method", "mixed-state", "--out", "postures.npz",
                        "--max-frames", "45", "--azimuths", "90", "-90", "--size", "160x120",
                        "--bins", "8"])
    saved = load_posture_model(tmp_path / "postures.npz")
    assert saved.description["clips"] == describe("mixed-state")["clips"]
    assert saved.description["laid_down"] == describe("mixed-state")["laid_down"]
    # sitting from CMU 75, lying from the laid-down waves: no posture is left untrained
    assert set(saved.description["label_counts"]) == set(POSTURE_NAMES)
    assert min(saved.description["label_counts"].values()) >= 2, out


def _track_arguments(method: str) -> list:
    arguments = ["track", "--method", method, "--video", VIDEO, "--out", "out"]
    if method in ("latent", "condensation", "mht"):
        return arguments + ["--frames", "0:3", "--max-size", "96", "--particles", "8",
                            "--refine-steps", "0", "--foreground", "none",
                            "--init", "manual:" + ",".join(map(str, POSE))]
    if method == "linear-combination":  # camera 3 of the bundled calibration (index 2)
        return arguments + ["--frames", "0:12", "--particles", "16", "--iterations", "1",
                            "--calibration", CALIBRATION, "--cameras", "2"]
    # the median background of 40 frames leaves the man's silhouette
    return arguments + ["--frames", "0:40", "--max-size", "128", "--particles", "32"]


@pytest.mark.slow  # 10-30 s each: decoding, compiling the tracker
@pytest.mark.parametrize("method", ["latent", "condensation", "mht", "linear-combination",
                                    "mixed-state"])
def test_track_runs_every_method_with_the_bundled_model(tmp_path, capsys, method):
    _run(capsys, _track_arguments(method))
    assert sorted(path.name for path in (tmp_path / "out").iterdir()) == ["overlay.mp4",
                                                                          "track.json"]
    record = json.loads((tmp_path / "out" / "track.json").read_text())
    assert record["model"] == str(default_model(method))
    assert record["frames"], record.keys()
