"""The one overlay drawer and the videos made with it: per-method colours, hidden truth markers
hollow, frame count read back, refused input; a rendered sequence as video."""

from functools import cache

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12, frontal_camera, render_motion
from jaxtrack.data import load_clip
from jaxtrack.vision import (
    METHOD_COLOURS,
    TRUTH_COLOUR,
    draw_tracks,
    write_overlay_video,
    write_video,
)

cv2 = pytest.importorskip("cv2")

NUM_FRAMES, HEIGHT, WIDTH = 7, 72, 96


def frames_and_tracks():
    rng = np.random.default_rng(3)
    images = rng.integers(0, 60, size=(NUM_FRAMES, HEIGHT, WIDTH, 3), dtype=np.uint8)
    truth = np.tile(np.linspace((30.0, 20.0), (70.0, 60.0), len(UPPER_BODY_12)),
                    (NUM_FRAMES, 1, 1))
    truth += np.arange(NUM_FRAMES)[:, None, None]
    tracks = {"gplvm": truth + (2.0, 0.0), "baseline": truth - (0.0, 3.0)}
    return images, tracks, truth


def test_video_reads_back_with_the_right_frame_count_and_size(tmp_path):
    images, tracks, truth = frames_and_tracks()
    path = write_overlay_video(images, tracks, tmp_path / "overlay.mp4", fps=10.0,
                               marker_names=UPPER_BODY_12, truth=truth)
    assert [p.name for p in tmp_path.iterdir()] == ["overlay.mp4"]
    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    assert len(frames) == NUM_FRAMES
    assert frames[0].shape == (HEIGHT, WIDTH, 3)
    # the drawing survives encoding: frames differ from the dark noise they were drawn on
    assert np.abs(frames[0].astype(int) - images[0][..., ::-1]).max() > 100


def test_each_method_gets_its_colour_and_truth_is_white():
    images, tracks, truth = frames_and_tracks()
    tracks = {"gplvm": truth[0] + (0.0, 0.0), "baseline": truth[0] + (20.0, 0.0)}
    # truth alone where no method is drawn: move it away from both
    frame = draw_tracks(images[0], tracks, UPPER_BODY_12, truth=truth[0] - (20.0, 0.0),
                        label="frame 1/7")
    assert frame.dtype == np.uint8 and frame.shape == images[0].shape
    assert not np.array_equal(frame, images[0]) and images[0].max() < 60  # input untouched
    wrist = UPPER_BODY_12.index("left_wrist")  # the last marker: drawn on top of the skeleton
    x, y = (int(v) for v in np.round(truth[0, wrist]))
    assert tuple(frame[y, x]) == METHOD_COLOURS[0]
    assert tuple(frame[y, x + 20]) == METHOD_COLOURS[1]
    # the thin anti-aliased truth dot is blended at its centre by some OpenCV versions
    assert np.abs(frame[y, x - 20].astype(int) - TRUTH_COLOUR).max() <= 10
    recoloured = draw_tracks(images[0], tracks, UPPER_BODY_12,
                             colours={"baseline": (1, 2, 3)})
    assert tuple(recoloured[y, x + 20]) == (1, 2, 3)


def test_non_finite_points_are_skipped_not_drawn_at_the_corner():
    images, tracks, _ = frames_and_tracks()
    broken = np.full((len(UPPER_BODY_12), 2), np.nan)
    frame = draw_tracks(images[0], {"diverged": broken}, UPPER_BODY_12)
    # only the legend (top-left) changes the frame
    changed = np.argwhere((frame != images[0]).any(axis=-1))
    assert changed[:, 0].max() < HEIGHT // 2


def test_refused_input(tmp_path):
    images, tracks, truth = frames_and_tracks()
    path = tmp_path / "overlay.mp4"
    with pytest.raises(ValueError, match="tracks is empty"):
        write_overlay_video(images, {}, path, fps=10, marker_names=UPPER_BODY_12)
    with pytest.raises(ValueError, match=r"tracks\['gplvm'\] has shape \(6, 12, 2\)"):
        write_overlay_video(images, {"gplvm": tracks["gplvm"][:6]}, path, fps=10,
                            marker_names=UPPER_BODY_12)
    with pytest.raises(ValueError, match="truth has shape"):
        write_overlay_video(images, tracks, path, fps=10, marker_names=UPPER_BODY_12,
                            truth=truth[:, :5])
    with pytest.raises(ValueError, match=r"\(7, 12, 2\).*marker_names names 5 markers"):
        write_overlay_video(images, tracks, path, fps=10, marker_names=UPPER_BODY_12[:5])
    with pytest.raises(ValueError, match="uint8"):
        write_overlay_video(images.astype(float), tracks, path, fps=10,
                            marker_names=UPPER_BODY_12)
    with pytest.raises(OSError):
        write_overlay_video(images, tracks, tmp_path / "missing" / "overlay.mp4", fps=10,
                            marker_names=UPPER_BODY_12)
    assert list(tmp_path.iterdir()) == []


def test_hidden_truth_markers_are_drawn_hollow():
    image = np.zeros((720, 960, 3), np.uint8)
    head, wrist = UPPER_BODY_12.index("head"), UPPER_BODY_12.index("left_wrist")
    truth = np.full((len(UPPER_BODY_12), 2), np.nan)  # two unconnected markers: no limb lines
    truth[head], truth[wrist] = (300.0, 400.0), (600.0, 400.0)
    visible = np.zeros(len(UPPER_BODY_12), bool)
    visible[head] = True
    frame = draw_tracks(image, {}, UPPER_BODY_12, truth=truth, visible=visible)
    radius = 3  # the truth's dot radius at 720 rows
    assert np.abs(frame[400, 300].astype(int) - TRUTH_COLOUR).max() <= 10  # visible: filled
    assert frame[400, 600].max() == 0  # hidden: the centre stays as it was
    assert frame[400, 600 + radius].min() > 100  # ... inside a white ring
    with pytest.raises(ValueError, match="no truth"):
        draw_tracks(image, {}, UPPER_BODY_12, visible=visible)
    with pytest.raises(ValueError, match=r"visible has shape \(5,\)"):
        draw_tracks(image, {}, UPPER_BODY_12, truth=truth, visible=visible[:5])


@cache
def sequence():
    motion = load_clip("cmu_amc/07_01").resample(20.0).select(0, 6)
    return render_motion(motion, frontal_camera(motion, (96, 72)), background="clutter",
                         occluders=1, seed=5, progress=False)


def test_sequence_video_has_every_frame_and_fails_cleanly(tmp_path):
    video = write_video(sequence(), tmp_path / "walk.mp4", overlay=True)
    capture = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    assert len(frames) == sequence().num_frames and frames[0].shape == (72, 96, 3)
    with pytest.raises(OSError):
        write_video(sequence(), tmp_path / "missing" / "walk.mp4")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.mp4"]


def test_truth_stays_visible_where_an_estimate_lies_on_it():
    image = np.zeros((480, 640, 3), np.uint8)
    # a pose in the lower right, away from the legend (top left) and the frame counter
    truth = np.linspace((300.0, 250.0), (600.0, 450.0), len(UPPER_BODY_12))
    frame = draw_tracks(image, {"latent": truth, "condensation": truth + (0.5, 0.0)},
                        UPPER_BODY_12, truth=truth)
    skeleton = frame[200:, 250:].astype(int)
    white = (np.abs(skeleton - TRUTH_COLOUR).max(axis=-1) <= 10).sum()
    method = (np.abs(skeleton - METHOD_COLOURS[1]).max(axis=-1) <= 10).sum()
    assert white > 300  # the truth's limbs show along their length (about 400 px of limbs)
    assert method > 300  # ... and the estimate still shows beside them
