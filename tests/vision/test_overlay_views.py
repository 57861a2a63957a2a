"""``jaxtrack.vision.overlay_views.write_views_stream``: several views drawn side by side as
their frames arrive; the same video as the whole-clip writer, and a stream of another length
leaves no file."""

import numpy as np
import pytest

from jaxtrack.vision import read_video, write_views_video
from jaxtrack.vision.overlay_views import write_views_stream

MARKERS = ("head", "hand", "other_hand")


def _square(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], np.float64)


def _views(frames: int = 3):
    rng = np.random.default_rng(2)
    images = [rng.integers(0, 60, (frames, 30, 20, 3), dtype=np.uint8) for _ in range(2)]
    contours = [np.tile(_square(5.0, 5.0, 15.0, 25.0), (frames, 1, 1))] * 2
    markers = [np.tile([[10.0, 8.0], [6.0, 20.0], [14.0, 20.0]], (frames, 1, 1))] * 2
    ambiguity = np.array([[0.1, 0.2], [np.nan, 0.3], [0.4, 0.1]])[:frames]
    names = ("head", "neck", "hand")
    skeletons = np.array([[[0.0, 0.25, 0.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.5]]] * frames)
    options = dict(fps=10.0, names=["left", "right"], marker_names=MARKERS,
                   labels=[[f"{t}" for t in range(frames)]] * 2, ambiguity=ambiguity,
                   selected=[0, 1, None][:frames], zoom=2, skeletons=skeletons,
                   skeleton_names=names)
    return images, contours, markers, options


def test_a_stream_of_views_is_the_video_the_whole_clip_writer_makes(tmp_path):
    images, contours, markers, options = _views()
    pulled = []

    def stream():
        for t in range(3):
            pulled.append(t)
            yield [images[0][t], images[1][t]]

    path = write_views_stream(stream(), contours, markers, tmp_path / "stream.mp4", **options)
    whole = write_views_video(images, contours, markers, tmp_path / "whole.mp4", **options)
    assert pulled == [0, 1, 2]
    np.testing.assert_array_equal(read_video(path).frames, read_video(whole).frames)


@pytest.mark.parametrize("frames", [2, 4])
def test_a_stream_of_another_length_is_refused_and_leaves_no_file(tmp_path, frames):
    images, contours, markers, options = _views()
    stream = ([images[0][t % 3], images[1][t % 3]] for t in range(frames))
    with pytest.raises(ValueError, match="3 frames"):
        write_views_stream(stream, contours, markers, tmp_path / "views.mp4", **options)
    assert list(tmp_path.iterdir()) == []
