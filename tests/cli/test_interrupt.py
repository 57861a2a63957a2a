"""Ctrl-C ends a command with exit status 130 and one line, ``jaxtrack COMMAND: interrupted``:
no traceback, no crash at exit (a KeyboardInterrupt inside XLA used to end some runs with a
segmentation fault, 139), and nothing left in the output folder, not even a temporary file."""

import os
import signal
import subprocess
import sys
import time

import pytest

import jaxtrack.vision.overlay
from jaxtrack.cli import INTERRUPTED, main
from jaxtrack.data import bundled_folder

WAVE_BVH = bundled_folder() / "animateddrawings_bvh" / "fair1_wave_hello.bvh"


def _interrupt_when(process: subprocess.Popen, started: str, timeout: float = 120.0) -> None:
    """Send SIGINT once ``started`` appears on the process's stdout (then a second more, so
    that the work has begun inside JAX)."""
    deadline = time.monotonic() + timeout
    line = ""
    while started not in line:
        line = process.stdout.readline()
        assert line or process.poll() is None, "the command ended before it started working"
        assert time.monotonic() < deadline, "the command did not start working in time"
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)


def test_ctrl_c_while_training_exits_130_in_one_line_leaving_nothing(tmp_path):
    out = tmp_path / "models"  # created by the command, removed again on Ctrl-C
    environment = dict(os.environ, PYTHONUNBUFFERED="1", TQDM_DISABLE="1")
    process = subprocess.Popen(
        [sys.executable, "-m", "jaxtrack.cli", "train", "--clips", str(WAVE_BVH), "--out",
         str(out / "m.npz")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=environment, cwd=tmp_path)
    try:
        _interrupt_when(process, "training on 1 clip(s)")
        _, error = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == INTERRUPTED, (process.returncode, error)
    # one line for the interruption (a slow machine may have drawn the fit's progress before)
    assert error.splitlines()[-1] == "jaxtrack train: interrupted", error
    assert "Traceback" not in error and error.count("interrupted") == 1, error
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_writing_removes_what_was_written(tmp_path, capsys, monkeypatch):
    """Ctrl-C after ``render`` has written ``--out`` and while it writes ``--video``: the
    finished sequence and the video's temporary file are both removed."""
    real_write_frames = jaxtrack.vision.overlay.write_frames

    def interrupted(frames, path, fps, size):
        def some_then_ctrl_c():
            yield next(iter(frames))
            raise KeyboardInterrupt

        return real_write_frames(some_then_ctrl_c(), path, fps, size)

    monkeypatch.setattr(jaxtrack.vision.overlay, "write_frames", interrupted)
    code = main(["render", "--mocap", "animateddrawings/fair1_wave_hello", "--frames", "0:3",
                 "--size", "64x48", "--out", str(tmp_path / "r.npz"), "--video",
                 str(tmp_path / "r.mp4")])
    assert code == INTERRUPTED
    error = capsys.readouterr().err
    assert error.splitlines()[-1] == "jaxtrack render: interrupted" and "Traceback" not in error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_ctrl_c_five_times_never_crashes(tmp_path):
    """The same Ctrl-C five times: always 130 (never 139, a crash at exit)."""
    codes = []
    for attempt in range(5):
        out = tmp_path / f"run{attempt}"
        process = subprocess.Popen(
            [sys.executable, "-m", "jaxtrack.cli", "train", "--clips", str(WAVE_BVH), "--out",
             str(out / "m.npz")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1", TQDM_DISABLE="1"))
        _interrupt_when(process, "training on 1 clip(s)")
        process.communicate(timeout=60)
        codes.append(process.returncode)
        assert not out.exists()
    assert codes == [INTERRUPTED] * 5


def test_a_ctrl_c_swallowed_on_its_way_still_stops_the_command_writing(tmp_path, capsys,
                                                                      monkeypatch):
    """A KeyboardInterrupt that something swallows (as a callback XLA runs can) leaves its
    record: the command's next output is not written, and it ends with 130 and one line."""
    import jaxtrack.body.sequence

    real = jaxtrack.body.sequence.save_sequence

    def after_a_swallowed_sigint(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)  # the handler runs here and raises
        except KeyboardInterrupt:
            pass  # swallowed, as inside an XLA callback
        return real(*args, **kwargs)

    monkeypatch.setattr(jaxtrack.body.sequence, "save_sequence", after_a_swallowed_sigint)
    code = main(["render", "--mocap", str(WAVE_BVH), "--frames", "0:3", "--size", "64x48",
                 "--out", str(tmp_path / "wave.npz")])
    assert code == INTERRUPTED
    error = capsys.readouterr().err
    assert error.splitlines()[-1] == "jaxtrack render: interrupted" and "Traceback" not in error
    assert list(tmp_path.iterdir()) == []
