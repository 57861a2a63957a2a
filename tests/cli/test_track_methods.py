"""``jaxtrack track --method condensation|mht|latent``: the latent tracker and its baselines run
on the bundled Pose2Sim clip from a tiny ``jaxtrack train`` prior (the baselines' dynamics
learned from its training poses) and write ``overlay.mp4`` and ``track.json`` with a status
per frame; and every module of ``jaxtrack/cli`` stays short."""

import json
from pathlib import Path

import pytest

import jaxtrack.cli
from jaxtrack.cli import main
from jaxtrack.data import path as data_path
from jaxtrack.trackers.status import FrameStatus

VIDEO = data_path("pose2sim/videos/cam03_half.mp4")  # 544x960
FRAMES = 3
# an upright upper body in the middle of the 544 x 960 frame, x and y of head, neck, thorax,
# pelvis, right shoulder, elbow, wrist, hip, left shoulder, elbow, wrist, hip (video pixels)
POSE = (272, 200, 272, 260, 272, 340, 272, 480, 222, 270, 205, 360, 200, 440, 245, 480,
        322, 270, 340, 360, 345, 440, 300, 480)
MAX_LINES = 300


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """A tiny prior as ``jaxtrack train`` writes it (one view of the wave, 10 fps)."""
    from jaxtrack.priors.train import train_prior

    path = tmp_path_factory.mktemp("model") / "wave.npz"
    train_prior(["animateddrawings/fair1_wave_hello"], views=1, fps=10.0, active_size=8,
                iterations=1, active_steps=5, progress=False, cache=path)
    return path


@pytest.mark.slow  # about 30 s of CPU each (the prior's training and the tracker's compile)
@pytest.mark.parametrize("method, particles", [("condensation", 16), ("mht", 2), ("latent", 16)])
def test_the_image_trackers_track_a_video_and_write_a_status_per_frame(model, tmp_path, capsys,
                                                                  method, particles):
    out = tmp_path / "out"
    code = main(["track", "--method", method, "--model", str(model), "--video", str(VIDEO),
                 "--out", str(out), "--frames", f"0:{FRAMES}", "--max-size", "96",
                 "--particles", str(particles), "--refine-steps", "0", "--foreground", "none",
                 "--init", "manual:" + ",".join(str(value) for value in POSE)])
    assert code == 0, capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["overlay.mp4", "track.json"]
    record = json.loads((out / "track.json").read_text())
    assert record["method"] == method and record["options"]["method"] == method
    assert record["size"] == [544, 960] and record["init"]["method"] == "manual"
    assert [frame["frame"] for frame in record["frames"]] == list(range(FRAMES))
    statuses = {status.value for status in FrameStatus}
    assert all(frame["status"] in statuses for frame in record["frames"])
    assert sum(record["status_counts"].values()) == FRAMES
    assert record["initial_pose"]["head"] == [272, 200]


def test_every_cli_module_is_short():
    folder = Path(jaxtrack.cli.__file__).parent
    lengths = {path.name: len(path.read_text().splitlines()) for path in folder.glob("*.py")}
    assert lengths and all(lines <= MAX_LINES for lines in lengths.values()), {
        name: lines for name, lines in lengths.items() if lines > MAX_LINES}
