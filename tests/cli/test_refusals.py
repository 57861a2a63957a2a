"""Bad input to every command is refused in one line (exit 2), within seconds, before any frame
is read or any training starts, leaving nothing behind: outputs that cannot be written, numbers
out of range (seeds included), training clips too short, manual markers outside the frame."""

import time
from pathlib import Path

import pytest

import jaxtrack.priors.train
from jaxtrack.cli import main
from jaxtrack.data import bundled_folder
from jaxtrack.data import path as data_path

VIDEO = data_path("pose2sim/videos/cam03_half.mp4")  # 544x960
WAVE_BVH = bundled_folder() / "animateddrawings_bvh" / "fair1_wave_hello.bvh"
WAVE = "animateddrawings/fair1_wave_hello"
HUGE_SEED = str(2**70)


def _refused(capsys, tmp_path, arguments, message):
    """Run the command: exit 2, one line naming ``message``, in seconds, nothing written."""
    before = sorted(tmp_path.rglob("*"))
    tick = time.perf_counter()
    code = main([str(argument).format(tmp=tmp_path) for argument in arguments])
    seconds = time.perf_counter() - tick
    error = capsys.readouterr().err
    assert code == 2, error
    assert error.count("\n") == 1 and "Traceback" not in error, error
    assert message.format(tmp=tmp_path) in error, error
    assert sorted(tmp_path.rglob("*")) == before
    assert seconds < 20, seconds
    return error


@pytest.fixture(autouse=True)
def _no_training(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the command trained before refusing its arguments")

    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", refuse)


@pytest.fixture
def a_file(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("a file, not a folder\n")
    return path


TRACK = ["track", "--model", "{tmp}/notes.txt", "--video", str(VIDEO)]


@pytest.mark.parametrize("arguments, message", [
    # a folder that cannot take a file: /proc (os.access says yes to root; a probe file says no)
    (TRACK + ["--out", "/proc/x"], "--out /proc/x: cannot write into folder /proc"),
    (TRACK + ["--method", "mixed-state", "--out", "/proc/x"],
     "--out /proc/x: cannot write into folder /proc"),
    (TRACK + ["--method", "linear-combination", "--init", "face", "--out", "/proc/x"],
     "--out /proc/x: cannot write into folder /proc"),
    (["train", "--clips", WAVE, "--out", "/proc/m.npz"],
     "--out /proc/m.npz: cannot write into folder /proc"),
    (["train", "--method", "mixed-state", "--clips", WAVE, "--out", "/proc/m.npz"],
     "--out /proc/m.npz: cannot write into folder /proc"),
    (["train", "--method", "linear-combination", "--clips", WAVE, "--out", "/proc/m.npz"],
     "--out /proc/m.npz: cannot write into folder /proc"),
    (["evaluate", "--method", "latent", "--train", WAVE, "--test", "cmu_amc/07_01", "--json",
      "/proc/e.json"], "--json /proc/e.json: cannot write into folder /proc"),
    (["evaluate", "--method", "latent", "--train", WAVE, "--test", "cmu_amc/07_01", "--json",
      "{tmp}/e.json", "--plots", "/proc/plots"], "--plots /proc/plots: cannot write into"),
    (["render", "--mocap", WAVE, "--out", "/proc/r.npz"],
     "--out /proc/r.npz: cannot write into folder /proc"),
    (["render", "--mocap", WAVE, "--out", "{tmp}/r.npz", "--video", "/proc/r.mp4"],
     "--video /proc/r.mp4: cannot write into folder /proc"),
    # a path under an existing file
    (TRACK + ["--out", "{tmp}/notes.txt/out"],
     "--out {tmp}/notes.txt/out: cannot create folder {tmp}/notes.txt/out, {tmp}/notes.txt is "
     "a file"),
    (TRACK + ["--method", "mixed-state", "--out", "{tmp}/notes.txt/out"],
     "{tmp}/notes.txt is a file"),
    (["train", "--clips", WAVE, "--out", "{tmp}/notes.txt/m.npz"], "{tmp}/notes.txt is a file"),
    (["render", "--mocap", WAVE, "--out", "{tmp}/notes.txt/r.npz"],
     "cannot write --out {tmp}/notes.txt/r.npz: {tmp}/notes.txt is a file, not a folder"),
    (TRACK + ["--out", "{tmp}/notes.txt"], "--out {tmp}/notes.txt is a file; give a folder"),
])
def test_unwritable_outputs_are_refused_before_any_work(tmp_path, capsys, a_file, arguments,
                                                        message):
    _refused(capsys, tmp_path, arguments, message)


SEED_RULE = "--seed must be from 0 to 4294967295 (a 32-bit seed: jax.random.key keeps only " \
            "the low 32 bits), got"


@pytest.mark.parametrize("arguments", [
    TRACK + ["--out", "{tmp}/o"],
    TRACK + ["--method", "mixed-state", "--out", "{tmp}/o"],
    ["train", "--clips", WAVE, "--out", "{tmp}/m.npz"],
    ["train", "--method", "mixed-state", "--out", "{tmp}/m.npz"],
    ["evaluate", "--method", "latent", "--train", WAVE, "--test", "cmu_amc/07_01", "--json",
     "{tmp}/e.json"],
    ["render", "--mocap", WAVE, "--out", "{tmp}/r.npz"],
    ["demo"],
])
@pytest.mark.parametrize("seed", [HUGE_SEED, "-1", str(2**32)])
def test_seeds_are_range_checked_at_parse_time(tmp_path, capsys, arguments, seed):
    error = _refused(capsys, tmp_path, [*arguments, "--seed", seed], f"{SEED_RULE} {seed}")
    assert "OverflowError" not in error


@pytest.mark.parametrize("arguments, message", [
    (TRACK + ["--out", "{tmp}/o", "--particles", "0"], "--particles must be at least 1, got 0"),
    (TRACK + ["--out", "{tmp}/o", "--max-size", "8"], "--max-size must be at least 32, got 8"),
    (TRACK + ["--out", "{tmp}/o", "--arm-momentum", "nan"],
     "--arm-momentum must be between 0 and 1, got nan"),
    (TRACK + ["--out", "{tmp}/o", "--keypoint-weight", "-2"],
     "--keypoint-weight must be a number of at least 0, got -2"),
    (TRACK + ["--out", "{tmp}/o", "--particles", "many"],
     "--particles must be a whole number, got 'many'"),
    (["train", "--clips", WAVE, "--out", "{tmp}/m.npz", "--active", "0"],
     "--active must be at least 1, got 0"),
    (["train", "--method", "mixed-state", "--out", "{tmp}/m.npz", "--azimuths", "400"],
     "--azimuths must be between -180 and 180 degrees, got 400"),
    (["train", "--clips", WAVE, "--out", "{tmp}/m.npz", "--back-constraint", "inf"],
     "--back-constraint must be a positive width, got inf"),
    (["evaluate", "--method", "mixed-state", "--json", "{tmp}/e.json", "--lag", "-3"],
     "--lag must be at least 0, got -3"),
    (["render", "--mocap", WAVE, "--out", "{tmp}/r.npz", "--blur", "-1"],
     "--blur must be between 0 and 1000 pixels, got -1"),
    (["render", "--mocap", WAVE, "--out", "{tmp}/r.npz", "--occluders", "1e9"],
     "--occluders must be a whole number, got '1e9'"),
])
def test_numbers_are_range_checked_at_parse_time(tmp_path, capsys, arguments, message):
    error = _refused(capsys, tmp_path, arguments, message)
    assert error.startswith(f"jaxtrack {arguments[0]}: error: ")


def _short_bvh(target: Path, frames: int) -> Path:
    """The first ``frames`` frames of a real BVH file."""
    lines = WAVE_BVH.read_text().splitlines()
    motion = lines.index("MOTION")
    header = lines[:motion + 1] + [f"Frames: {frames}", lines[motion + 2]]
    target.write_text("\n".join(header + lines[motion + 3:motion + 3 + frames]) + "\n")
    return target


@pytest.mark.parametrize("method", ["latent", "linear-combination", "mixed-state"])
@pytest.mark.parametrize("frames", [1, 4])
def test_a_clip_too_short_to_train_on_is_named(tmp_path, capsys, method, frames):
    clip = _short_bvh(tmp_path / "one.bvh", frames)
    _refused(capsys, tmp_path, ["train", "--method", method, "--clips", clip, "--out",
                                "{tmp}/m.npz"],
             f"--clips {clip}: {frames} frame(s) at 119.875 fps give 1 at 30 fps, the rate clips "
             f"are trained on; the motion's dynamics need two consecutive frames: give at "
             f"least 5 frames")


def _manual(markers):
    return "manual:" + ",".join(f"{value:g}" for point in markers for value in point)


def test_manual_markers_outside_the_frame_are_named_with_the_frame_size(tmp_path, capsys):
    markers = [[200.0 + 5 * i, 300.0 + 20 * i] for i in range(12)]
    markers[0] = [600.0, 310.0]  # head right of the 544 px wide frame
    markers[11] = [250.0, -4.0]  # left hip above it
    (tmp_path / "notes.txt").write_text("never read: the pose is refused first")
    _refused(capsys, tmp_path, [*TRACK, "--out", "{tmp}/o", "--init", _manual(markers)],
             "--init manual: 2 marker(s) outside the 544x960 video (x 0-544, y 0-960, video "
             "pixels): head (600, 310), left_hip (250, -4)")
