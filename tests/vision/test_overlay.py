"""The one overlay drawer and the videos made with it: per-method colours, hidden truth markers
hollow, frame count read back, refused input; a rendered sequence as video; the multi-view
panels (a contour drawn where it lies, ambiguity bars, the selected view framed)."""

from functools import cache

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12, frontal_camera, render_motion
from jaxtrack.data import load_clip
from jaxtrack.vision import (
    METHOD_COLOURS,
    TRUTH_COLOUR,
    compose_views,
    contour_panel,
    draw_contour,
    draw_tracks,
    read_video,
    skeleton_panel,
    write_overlay_video,
    write_video,
    write_views_video,
)
from jaxtrack.vision.panels import AMBIGUITY_COLOUR, SELECTED_COLOUR

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


# --- panels: a contour and markers on an enlarged view, views side by side --------------------


def _square(left, top, right, bottom):
    return np.array([(left, top), (right, top), (right, bottom), (left, bottom)], np.float64)


def test_draw_contour_closes_the_outline_two_pixels_wide_and_skips_a_broken_one():
    image = np.zeros((40, 50, 3), np.uint8)
    colour = (10, 200, 30)
    drawn = draw_contour(image, _square(10, 8, 30, 25), colour)
    assert image.max() == 0  # the input is untouched
    painted = (drawn == colour).all(axis=-1)
    # every side, the closing one (last point to first) included, one pixel right and below too
    assert painted[8, 10:31].all() and painted[25, 10:31].all()
    assert painted[8:26, 10].all() and painted[8:26, 30].all()
    assert painted[9, 12:29].all() and painted[10:24, 11].all()
    assert not painted[12:22, 14:27].any() and painted.sum() < 4 * (20 + 17) + 8
    # outside the image: clipped; a non-finite point: nothing drawn
    clipped = (draw_contour(image, _square(-5, 10, 80, 30), colour) == colour).all(axis=-1)
    assert clipped[10].all() and clipped[30].all() and not clipped[:, 0].all()
    broken = _square(10, 8, 30, 25)
    broken[2] = np.nan
    assert np.array_equal(draw_contour(image, broken, colour), image)


def test_contour_panel_enlarges_the_frame_and_draws_at_its_pixel_centres():
    image = np.zeros((60, 80, 3), np.uint8)
    image[10, 70] = (90, 91, 92)
    colour = METHOD_COLOURS[2]
    markers = np.array([[60.25, 40.25], [np.nan, np.nan], [50.25, 45.25]])
    panel = contour_panel(image, _square(20.0, 20.0, 40.0, 35.0), markers,
                          ("head", "hand", "other_hand"), name="view", colour=colour, zoom=2)
    assert panel.shape == (120, 160, 3)
    assert (panel[20:22, 140:142] == (90, 91, 92)).all()  # pixel (70, 10): a 2 x 2 block
    painted = (panel == colour).all(axis=-1)
    # the contour's top side at y = (20 + 0.5) * 2 - 0.5 = 40.5, from x = 40.5 to 80.5
    assert painted[40:42, 45:76].any(axis=0).all()
    assert not painted[50:65, 50:75].any()  # inside the contour, nothing
    # the markers at (x + 0.5) * 2 - 0.5: filled dots of the view's colour
    assert painted[81, 121] and painted[91, 101]
    with pytest.raises(ValueError, match="zoom"):
        contour_panel(image, _square(1, 1, 5, 5), markers, ("head", "hand", "other_hand"),
                      name="view", colour=colour, zoom=0)


def test_compose_views_puts_bars_under_views_and_frames_the_selected_one():
    rng = np.random.default_rng(0)
    panels = [rng.integers(0, 50, (40, 50, 3), dtype=np.uint8) for _ in range(3)]
    assert np.array_equal(compose_views(panels), np.concatenate(panels, axis=1))
    composed = compose_views(panels, ambiguity=[1.0, np.nan, 2.0], full_scale=2.0, selected=1)
    assert composed.shape == (40 + 18, 150, 3)
    bars = composed[40:]
    ambiguous = (bars == AMBIGUITY_COLOUR).all(axis=-1)
    # view 0: half its width (1 of 2); view 1 observed nothing: no bar; view 2: all of it
    assert ambiguous[3:15, :25].all() and not ambiguous[:, 25:50].any()
    assert not ambiguous[3:15, 54:96].any() and ambiguous[3:15, 100:150].all()
    assert not ambiguous[:3].any() and not ambiguous[15:].any()
    framed = (composed == SELECTED_COLOUR).all(axis=-1)
    assert framed[:4, 50:100].all() and framed[-4:, 50:100].all()
    assert framed[:, 50:54].all() and framed[:, 96:100].all()
    assert not framed[4:-4, 54:96].any() and not framed[:, :50].any()
    assert not framed[:, 100:].any()
    assert np.array_equal(composed[4:40, 54:96], panels[1][4:, 4:46])  # inside: the view
    with pytest.raises(ValueError, match="one size"):
        compose_views([panels[0], panels[1][:30]])
    with pytest.raises(ValueError, match="2 values for 3 panels"):
        compose_views(panels, ambiguity=[1.0, 2.0])
    with pytest.raises(ValueError, match="selected"):
        compose_views(panels, selected=3)


def test_views_video_has_every_frame_side_by_side(tmp_path):
    rng = np.random.default_rng(1)
    images = [rng.integers(0, 60, (4, 30, 20, 3), dtype=np.uint8) for _ in range(2)]
    contours = [np.tile(_square(5.0, 5.0, 15.0, 25.0), (4, 1, 1))] * 2
    markers = [np.tile([[10.0, 8.0], [6.0, 20.0], [14.0, 20.0]], (4, 1, 1))] * 2
    ambiguity = np.array([[0.1, 0.2], [np.nan, 0.3], [0.4, 0.4], [0.0, 0.1]])
    path = write_views_video(images, contours, markers, tmp_path / "views.mp4", fps=10.0,
                             names=["left", "right"], marker_names=("head", "hand", "other_hand"),
                             labels=[[f"{t}" for t in range(4)]] * 2, ambiguity=ambiguity,
                             selected=[0, 1, None, 1], zoom=2)
    frames = read_video(path).frames
    assert frames.shape == (4, 2 * 30 + 18, 2 * 2 * 20, 3)
    with pytest.raises(ValueError, match="one name per view"):
        write_views_video(images, contours, markers, tmp_path / "no.mp4", fps=10.0,
                          names=["left"], marker_names=("head", "hand", "other_hand"))
    assert [p.name for p in tmp_path.iterdir()] == ["views.mp4"]


def test_skeleton_panel_draws_the_skeleton_from_the_front_and_the_side():
    names = ("head", "neck", "hand")
    # the head 0.25 m above the neck; the hand 0.5 m to the right and 0.5 m toward the viewer
    skeleton = np.array([[0.0, 0.25, 0.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.5]])
    panel = skeleton_panel(skeleton, names, height=200, colour=(0, 255, 0))
    half = 160  # 0.8 of the height per drawing; 100 px per metre (SKELETON_REACH 1 m)
    assert panel.shape == (200, 2 * half, 3)

    def green(y, x):
        return bool(np.any(np.all(panel[y - 2:y + 3, x - 2:x + 3] == (0, 255, 0), axis=-1)))

    neck = (100, half // 2)
    assert green(*neck) and green(neck[0] - 25, neck[1])  # the head above the neck
    assert green(neck[0], neck[1] + 50)  # the hand, front: 0.5 m to the right
    assert green(neck[0], half + neck[1] + 50)  # side: 0.5 m toward the viewer, drawn right
    assert not green(neck[0], half + neck[1] - 50)
    empty = skeleton_panel(np.full((3, 3), np.nan), names, height=200, colour=(0, 255, 0))
    assert not np.any(np.all(empty[40:] == (0, 255, 0), axis=-1))  # only the legends
    with pytest.raises(ValueError, match="expected \\(3, 3\\)"):
        skeleton_panel(skeleton[:2], names, height=200)
    with pytest.raises(ValueError, match="height"):
        skeleton_panel(skeleton, names, height=8)


def test_views_video_with_skeletons_adds_their_panel(tmp_path):
    images = [np.zeros((2, 30, 20, 3), np.uint8)]
    contours = [np.tile(_square(5.0, 5.0, 15.0, 25.0), (2, 1, 1))]
    markers = [np.tile([[10.0, 8.0], [6.0, 20.0], [14.0, 20.0]], (2, 1, 1))]
    names = ("head", "neck", "hand")
    skeletons = np.array([[[0.0, 0.25, 0.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.5]]] * 2)
    path = write_views_video(images, contours, markers, tmp_path / "views.mp4", fps=10.0,
                             names=["one"], marker_names=names, skeletons=skeletons,
                             skeleton_names=names, zoom=2)
    assert read_video(path).frames.shape == (2, 60, 40 + 2 * 48, 3)
    with pytest.raises(ValueError, match="skeletons must be"):
        write_views_video(images, contours, markers, tmp_path / "no.mp4", fps=10.0,
                          names=["one"], marker_names=names, skeletons=skeletons[:, :2],
                          skeleton_names=names)
    assert [p.name for p in tmp_path.iterdir()] == ["views.mp4"]


def test_overlay_video_takes_a_label_per_frame(tmp_path):
    images, tracks, _ = frames_and_tracks()
    with pytest.raises(ValueError, match="labels has 2 texts for 7 frames"):
        write_overlay_video(images, tracks, tmp_path / "overlay.mp4", fps=10,
                            marker_names=UPPER_BODY_12, labels=["a", "b"])
    labelled = write_overlay_video(images[:1], {m: t[:1] for m, t in tracks.items()},
                                   tmp_path / "labelled.mp4", fps=10, marker_names=UPPER_BODY_12,
                                   labels=["sitting  1/1"])
    assert read_video(labelled).num_frames == 1


def test_overlay_from_a_file_is_drawn_on_its_own_frames_at_its_own_size(tmp_path):
    """A tracker that ran on frames downscaled by 4 gives its markers scaled back: they are
    drawn on the file's own 384x288 frames, where the marker lies, frames 2 to 5 of it."""
    from jaxtrack.vision import write_frames
    from jaxtrack.vision.overlay import write_overlay_video_from_file

    source = np.full((7, 4 * HEIGHT, 4 * WIDTH, 3), 40, np.uint8)
    video = write_frames(source, tmp_path / "source.mp4", 10.0, (4 * WIDTH, 4 * HEIGHT))
    tracked = np.tile(np.full((len(UPPER_BODY_12), 2), np.nan), (4, 1, 1))
    tracked[:, 0] = [[60.0, 40.0]]  # the head alone, tracking pixels (a quarter size)
    path = write_overlay_video_from_file(video, [2, 3, 4, 5], {"latent": tracked * 4},
                                         tmp_path / "overlay.mp4", fps=10.0,
                                         marker_names=UPPER_BODY_12)
    written = read_video(path)
    assert written.image_size == (4 * WIDTH, 4 * HEIGHT) and written.num_frames == 4
    colour = np.asarray(written.frames[0, 160, 240], int)  # the head, in the file's pixels
    assert np.abs(colour - METHOD_COLOURS[0]).max() < 60, colour
    assert np.abs(np.asarray(written.frames[0, 40, 300], int) - 40).max() < 20  # elsewhere
    with pytest.raises(ValueError, match="consecutive"):
        write_overlay_video_from_file(video, [2, 4], {"latent": tracked[:2] * 4},
                                      tmp_path / "gap.mp4", fps=10.0, marker_names=UPPER_BODY_12)
    with pytest.raises(Exception, match="2 frames from frame 5, but 4 were tracked"):
        write_overlay_video_from_file(video, [5, 6, 7, 8], {"latent": tracked * 4},
                                      tmp_path / "late.mp4", fps=10.0, marker_names=UPPER_BODY_12)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["overlay.mp4", "source.mp4"]
