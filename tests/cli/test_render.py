"""`jaxtrack render`: real clips to loadable sequences; bad input gives one line and exit 2."""

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.body.sequence import load_sequence
from jaxtrack.cli import main
from jaxtrack.data import path

WAVE = "animateddrawings/fair1_wave_hello"


def test_render_a_bundled_clip_with_video(tmp_path, capsys):
    out, video = tmp_path / "wave.npz", tmp_path / "wave.mp4"
    code = main(["render", "--mocap", WAVE, "--frames", "100:106", "--size", "160x120",
                 "--background", "photo", "--seed", "2", "--out", str(out),
                 "--video", str(video)])
    assert code == 0, capsys.readouterr().err
    sequence = load_sequence(out)
    assert sequence.images.shape == (6, 120, 160, 3) and sequence.seed == 2
    assert sequence.settings["background"] == "photo"
    assert sequence.visibility.mean() > 0.6
    assert video.stat().st_size > 1000
    assert "rendered 6 frames" in capsys.readouterr().out


def test_render_through_a_real_calibrated_camera(tmp_path):
    out = tmp_path / "lab.npz"
    code = main(["render", "--mocap", "cmu_amc/07_01", "--camera",
                 f"qca:{path('pose2sim/Calib.qca.txt')}:cam03", "--frames", "150:153",
                 "--size", "320x240", "--markers", "upper12", "--out", str(out)])
    assert code == 0
    sequence = load_sequence(out)
    assert sequence.camera.image_size == (136, 240)  # portrait camera scaled to fit, aspect kept
    assert sequence.camera.name == "cam03" and sequence.marker_names == UPPER_BODY_12
    assert sequence.visibility.mean() > 0.5  # the staged subject is in the lab cameras' view


def test_random_camera_and_resampling(tmp_path):
    out = tmp_path / "random.npz"
    assert main(["render", "--mocap", WAVE, "--camera", "random", "--frames", "0:60",
                 "--fps", "30", "--size", "96x72", "--out", str(out)]) == 0
    sequence = load_sequence(out)
    assert sequence.fps == 30.0 and sequence.num_frames == 15
    inside = (sequence.markers_2d >= 0) & (sequence.markers_2d < np.array([96, 72]))
    assert inside.all()  # the random viewpoint frames the whole motion


def damaged_bvh(folder):
    lines = path(WAVE).read_text().splitlines()
    damaged = folder / "damaged.bvh"
    damaged.write_text("\n".join(lines[: lines.index("MOTION") + 5] + ["0.0 1.0 oops"]))
    return damaged


@pytest.mark.parametrize("arguments, message", [
    (["--mocap", "{tmp}/missing.bvh"], "no motion file"),
    (["--mocap", "nothing/like_this"], "no motion file or clip"),
    (["--mocap", "{damaged}"], "damaged.bvh"),
    (["--camera", "orbit"], "--camera must be"),
    (["--camera", "qca:pose2sim/Calib.qca.txt:7"], "index 0-3"),
    (["--camera", "qca:{tmp}/none.qca.txt:0"], "no calibration file"),
    (["--frames", "50:10"], "cannot select frames"),
    (["--size", "big"], "--size must look like"),
    (["--seed", "x"], "--seed must be a whole number, got 'x'"),
    (["--out", "{tmp}/no/folder/seq.npz"], "does not exist"),
    (["--out", "{tmp}"], "is a folder"),
])
def test_bad_input_gives_one_line_exit_two_and_no_output(tmp_path, capsys, arguments, message):
    names = {"tmp": tmp_path, "damaged": damaged_bvh(tmp_path)}
    arguments = [argument.format(**names) for argument in arguments]
    defaults = {"--mocap": WAVE, "--frames": "0:3", "--size": "64x48",
                "--out": str(tmp_path / "seq.npz")}
    for option, value in defaults.items():
        if option not in arguments:
            arguments += [option, value]
    before = sorted(tmp_path.rglob("*"))
    assert main(["render", *arguments, "--video", str(tmp_path / "seq.mp4")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith("jaxtrack render: error:"), error
    assert message in error and "Traceback" not in error
    assert sorted(tmp_path.rglob("*")) == before


def test_help_explains_the_camera_choices(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["render", "--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    assert "qca:FILE:INDEX" in text and "--background" in text and "1088x1920" in text
