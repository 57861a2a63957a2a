"""Bad input to `jaxtrack render` and `jaxtrack track` is refused in one line, before anything is
allocated, tracked or written: memory estimates against what the machine has, frame rates, manual
initialisations, model files, outputs larger than the limit."""

import numpy as np
import pytest

import jaxtrack._files as files
from jaxtrack.body import UPPER_BODY_12
from jaxtrack.cli import main
from jaxtrack.data import path as data_path

WAVE = "animateddrawings/fair1_wave_hello"


def run(capsys, *arguments):
    code = main(list(arguments))
    captured = capsys.readouterr()
    return code, captured.err


@pytest.fixture
def eight_gigabytes(monkeypatch):
    monkeypatch.setattr(files, "available_memory", lambda: 8_000_000_000)


def test_available_memory_reads_the_machine():
    available = files.available_memory()
    assert available is None or 0 < available < 1 << 50
    assert files.format_bytes(2.06e9) == "2.1 GB" and files.format_bytes(35e12) == "35 TB"


@pytest.mark.parametrize("fps", ["0.001", "1e9", "nan", "-3"])
def test_render_refuses_frame_rates_out_of_range(tmp_path, capsys, fps):
    code, error = run(capsys, "render", "--mocap", WAVE, "--fps", fps, "--size", "64x48",
                      "--out", str(tmp_path / "r.npz"), "--video", str(tmp_path / "r.mp4"))
    assert code == 2 and error.count("\n") == 1
    assert f"--fps must be between 0.1 and 10000 frames per second, got {fps}" in error
    assert "OpenCV" not in error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("arguments, needed", [
    (["--fps", "10000"], "rendering 69906 frames of 640x480 needs about 89 GB"),
    (["--size", "100000x100000"], "rendering 839 frames of 100000x100000 needs about 35 TB"),
    (["--size", "100000x100000", "--frames", "0:2"], "rendering 2 frames of 100000x100000"),
])
def test_render_refuses_what_does_not_fit_in_memory(tmp_path, capsys, eight_gigabytes,
                                                    arguments, needed):
    code, error = run(capsys, "render", "--mocap", WAVE, *arguments,
                      "--out", str(tmp_path / "r.npz"))
    assert code == 2 and error.count("\n") == 1
    assert needed in error and "but this machine has 8.0 GB available" in error
    assert list(tmp_path.iterdir()) == []


def test_render_states_its_output_size_and_refuses_a_large_one_unless_asked(tmp_path, capsys,
                                                                            monkeypatch):
    monkeypatch.setattr(files, "LARGE_OUTPUT_BYTES", 10_000)
    out = tmp_path / "r.npz"
    arguments = ("render", "--mocap", WAVE, "--frames", "0:2", "--size", "64x48", "--out",
                 str(out))
    estimate = 2 * 48 * (3 * 64 + 8)
    code, error = run(capsys, *arguments)
    assert code == 2 and error.count("\n") == 1
    assert (f"--out {out} would be about {files.format_bytes(estimate)} (2 frames of 64x48, "
            "uncompressed), more than 10 kB;") in error and "--allow-large" in error
    assert list(tmp_path.iterdir()) == []
    code, error = run(capsys, *arguments, "--allow-large")
    assert code == 0
    assert f"rendering 2 frames of 64x48 -> {out} (about {files.format_bytes(estimate)})" in error
    assert estimate <= out.stat().st_size < 1.5 * estimate


def test_render_refuses_the_whole_wave_clip_at_640x480_before_rendering(tmp_path, capsys):
    code, error = run(capsys, "render", "--mocap", WAVE, "--out", str(tmp_path / "r.npz"))
    assert code == 2 and error.count("\n") == 1
    assert "would be about 805 MB (839 frames of 640x480, uncompressed), more than 300 MB" in error
    assert list(tmp_path.iterdir()) == []


VIDEO = data_path("pose2sim/videos/cam03_half.mp4")  # 544x960


def _track(tmp_path, capsys, *arguments, model=None, video=None):
    model = model or tmp_path / "missing.npz"
    return run(capsys, "track", "--model", str(model), "--video", str(video or tmp_path / "v.mp4"),
               "--out", str(tmp_path / "out"), *arguments)


def test_track_refuses_more_particles_than_fit_in_memory(tmp_path, capsys, eight_gigabytes):
    code, error = _track(tmp_path, capsys, "--particles", "2000000")
    assert code == 2 and error.count("\n") == 1
    assert "--particles: tracking with 2000000 particles needs about 34 GB of memory, but this " \
           "machine has 8.0 GB available; at most about 406250 particles fit" in error
    assert list(tmp_path.iterdir()) == []


def _numbers(values):
    return "manual:" + ",".join(values)


def test_track_names_the_manual_values_that_are_not_finite(tmp_path, capsys):
    values = [str(10 + i) for i in range(24)]
    values[0], values[23] = "nan", "inf"
    code, error = _track(tmp_path, capsys, "--init", _numbers(values))
    assert code == 2 and error.count("\n") == 1
    assert "not finite: head x (nan), left_hip y (inf)" in error and "got 24" not in error


@pytest.mark.parametrize("case", ["all equal", "zero torso"])
def test_track_refuses_a_degenerate_manual_pose_before_anything_is_loaded(tmp_path, capsys,
                                                                           case):
    markers = np.tile([[100.0, 80.0]], (12, 1))
    if case == "zero torso":
        markers += np.arange(12)[:, None] * [3.0, 5.0]
        markers[UPPER_BODY_12.index("pelvis")] = markers[UPPER_BODY_12.index("neck")]
    model = tmp_path / "model.npz"
    model.write_bytes(b"not read")
    code, error = _track(tmp_path, capsys, "--init",
                         _numbers(f"{value:g}" for value in markers.ravel()), model=model,
                         video=VIDEO)
    # the model is damaged too: the pose is refused first, before the model is read
    assert code == 2 and error.count("\n") == 1
    assert "the torso (neck to pelvis) is 0.0 px long" in error
    assert sorted(tmp_path.iterdir()) == [model]


@pytest.mark.parametrize("content", [b"hello\nworld\n", b"\x93NUMPY not really"])
def test_track_names_a_model_that_is_not_a_gplvm_file(tmp_path, capsys, content):
    model = tmp_path / "model.txt"
    model.write_bytes(content)
    code, error = _track(tmp_path, capsys, model=model, video=VIDEO)
    assert code == 2 and error.count("\n") == 1
    assert "--model" in error and "model.txt" in error and "not a .npz archive" in error
    assert "allow_pickle" not in error and "pickle" not in error
    assert not (tmp_path / "out").exists()
