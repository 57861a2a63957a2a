"""``python -m benchmarks.real_video``: the frames it tracks and its refusals."""

import numpy as np
import pytest

from benchmarks import real_video
from jaxtrack.data import shared_folder

SHARED = shared_folder()
FOLDER = None if SHARED is None else SHARED / "pose2sim_demo_singleperson"
needs_data = pytest.mark.skipif(
    FOLDER is None or not (FOLDER / "reference" / "pose-3d").is_dir(),
    reason="the shared/data collection (pose2sim_demo_singleperson) is not beside this checkout")


@needs_data
def test_a_stride_tracks_every_other_frame_at_the_rate_it_tracks():
    every = real_video.View(FOLDER, "cam02", 9, 120)
    second = real_video.View(FOLDER, "cam02", 9, 120, stride=2)
    assert list(second.frame_indices) == list(every.frame_indices[::2])
    assert second.fps == pytest.approx(every.fps / 2)
    np.testing.assert_array_equal(second.truth, every.truth[::2])
    assert second.frames.shape[0] == 5 and second.images.shape[0] == 5


def test_bad_arguments_are_refused_in_one_line(capsys):
    for argv, message in ((["--stride", "0"], "--stride must be at least 1"),
                          (["--frames", "1"], "--frames must be at least 2")):
        with pytest.raises(SystemExit):
            real_video.main(argv)
        assert message in capsys.readouterr().err
