"""The paper-setting camera keeps the whole body in the image through a lie-down, and the
command refuses bad arguments in one line."""

import numpy as np
import pytest

from papers.kwatra2002 import setting
from papers.kwatra2002.__main__ import main


@pytest.fixture(scope="module")
def motions():
    try:
        takes = {take.name: take for take in setting.actor_takes()}
    except FileNotFoundError as error:
        pytest.skip(str(error))
    names = ("lieDownFloor_001", "squat1Reps_001")
    return [setting.load_take(takes[name]) for name in names]


def test_every_extremity_stays_in_the_frame_through_lying_down(motions):
    from jaxtrack.body._staging import project_numpy

    camera = setting.side_camera(motions)
    width, height = camera.image_size
    for motion in motions:
        pixels, depth = project_numpy(camera, setting.extremity_points(motion))
        assert np.all(depth > 0)
        assert np.all((pixels >= 0) & (pixels <= [width - 1, height - 1]))
    # framed on the standing pose alone, the lying actor's head and hands leave the image
    standing = motions[0].select(0, 1)
    pixels, _ = project_numpy(setting.side_camera([standing]),
                              setting.extremity_points(motions[0]))
    assert not np.all((pixels >= 0) & (pixels <= [width - 1, height - 1]))


def test_staging_puts_the_first_pelvis_at_the_origin_facing_forward(motions):
    from jaxtrack.body._staging import _facing
    from jaxtrack.body.markers import HUMANEVA_15, marker_positions

    joints = marker_positions(motions[0], HUMANEVA_15)
    pelvis = joints[0, HUMANEVA_15.index("pelvis")]
    np.testing.assert_allclose(pelvis[[0, 2]], 0.0, atol=1e-9)
    np.testing.assert_allclose(_facing(joints[:10]), [0.0, 0.0, 1.0], atol=1e-9)


def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--json", str(tmp_path / "missing" / "out.json")])
    assert stop.value.code == 2
    assert "does not exist" in capsys.readouterr().err.strip().splitlines()[-1]
    with pytest.raises(SystemExit):
        main(["--json", str(tmp_path / "out.txt")])
    assert "must end in .json" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--json", str(tmp_path / "out.json"), "--skip-paper-setting"])
    assert "leaves nothing to compute" in capsys.readouterr().err
