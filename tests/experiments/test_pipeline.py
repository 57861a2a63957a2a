"""The video pipeline (``jaxtrack.experiments.pipeline.track_video``) on small video files
written here: every tracker it can build cheaply runs from the file, the overlay is at the
video's own size, ``track.json`` holds one status per frame in the video's pixels, an
unwritable output folder is refused before a frame is decoded, and decoding the video in
chunks tracks it as the whole video held in memory does."""

import json

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.experiments import pipeline
from jaxtrack.experiments.pipeline import track_video, video_background
from jaxtrack.trackers import Engine, FrameEstimate, Tracker, VideoChunk, frame_at, track
from jaxtrack.trackers.status import FrameStatus

from ..mixed_state._figures import draw, figure_postures

cv2 = pytest.importorskip("cv2")

FRAMES = 8
SCALE = 0.5
KEY = jr.PRNGKey(5)
STATUSES = {status.value for status in FrameStatus}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A held-out wave rendered at 320 x 240 over a photo, written as a video file; its
    true markers (video pixels) and an SPM template built from them."""
    from jaxtrack.body import build_template
    from jaxtrack.experiments.protocol import render_test_sequences
    from jaxtrack.vision import write_frames

    sequence = render_test_sequences(
        "animateddrawings/history_c119d6b/cmu_1006_wave_hello_2", views=1,
        backgrounds=("photo",), fps=15.0, image_size=(320, 240), max_frames=FRAMES)[0]
    path = write_frames(sequence.images, tmp_path_factory.mktemp("video") / "wave.mp4", 15.0,
                        (320, 240))
    return path, np.asarray(sequence.truth, np.float64), build_template(sequence.truth)


def _figure_mask() -> np.ndarray:
    """The standing stick figure drawn at twice its size (limbs 10 pixels thick, so that
    they survive the foreground's opening at half size), on a 400 x 200 scene."""
    mask = np.zeros((200, 400), bool)
    mask[:, :240] = np.kron(draw("standing")[0], np.ones((2, 2), bool))
    return mask


@pytest.fixture(scope="module")
def figure_video(tmp_path_factory):
    """The stick figure walking 20 pixels a frame across a dark scene: its masks are the
    foreground against the video's median background."""
    from jaxtrack.vision import write_frames

    mask = _figure_mask()
    images = []
    for t in range(FRAMES):
        image = np.full((200, 400, 3), 30, np.uint8)
        image[np.roll(mask, 20 * t, axis=1)] = (220, 180, 150)
        images.append(image)
    return write_frames(images, tmp_path_factory.mktemp("figure") / "figure.mp4", 10.0,
                        (400, 200))


class Centroid(Tracker):
    """A tracker of the person's mask's centroid (the mean of its pixels, one marker), exact
    and deterministic: what the pipeline writes can be checked against the drawn figure."""

    likelihood: None = None

    @property
    def reads(self):
        return ("masks",)

    def observe(self, chunk, out=None):
        masks = np.asarray(chunk.masks, np.float64)
        rows, columns = np.indices(masks.shape[1:])
        area = np.maximum(masks.sum(axis=(1, 2)), 1)
        return np.stack([(masks * columns).sum(axis=(1, 2)) / area,
                         (masks * rows).sum(axis=(1, 2)) / area], axis=-1)

    @property
    def num_particles(self):
        return 1

    def start(self, key, first_frame, initial_pose):
        return jnp.asarray(first_frame)

    def first_estimate(self, state):
        return FrameEstimate(state[None], state[None], jnp.asarray(1.0), jnp.asarray(0.0),
                             jnp.asarray(False))

    def update(self, key, state, frame):
        centroid = frame_at(frame)
        return centroid, self.first_estimate(centroid)

    def options(self):
        return {"method": "centroid"}


class Detected(Tracker):
    """A tracker that reports a detector's keypoints as they are given (12 markers)."""

    likelihood: None = None

    @property
    def reads(self):
        return ("keypoints",)

    def observe(self, chunk, out=None):
        return np.asarray(chunk.keypoints[0], np.float64)

    @property
    def num_particles(self):
        return 1

    def start(self, key, first_frame, initial_pose):
        return jnp.asarray(first_frame)

    def first_estimate(self, state):
        return FrameEstimate(state, state, jnp.asarray(1.0), jnp.asarray(0.0),
                             jnp.asarray(False))

    def update(self, key, state, frame):
        points = frame_at(frame)
        return points, self.first_estimate(points)

    def options(self):
        return {"method": "detected"}


def _case(name, rendered, figure_video):
    """``(tracker, video, initial pose in video pixels)``."""
    from jaxtrack.body import build_template, spm_initial_state
    from jaxtrack.trackers import Likelihood, condensation_tracker, mht_tracker
    from jaxtrack.trackers.mixed_state import MixedStateModel, MixedStateTracker

    if name == "centroid":
        return Centroid(), figure_video, None
    if name == "mixed-state":
        tracker = MixedStateTracker(MixedStateModel(figure_postures()), 16)
        try:
            assert tracker.reads
        except NotImplementedError:
            pytest.skip("the mixed-state tracker does not say what it reads yet")
        return tracker, figure_video, None
    path, truth, _ = rendered
    # the template and dynamics in tracking pixels, as the tracker sees the frames
    template = build_template(truth * SCALE)
    states = np.asarray(spm_initial_state(jnp.asarray(truth * SCALE), template))
    if name == "condensation":
        return condensation_tracker(template, states, engine=Engine(16),
                                    likelihood=Likelihood("limbs")), path, truth[0]
    return mht_tracker(template, states, num_modes=2, max_steps=2), path, truth[0]


def _whole(tracker, video, pose):
    """The result of ``track`` on the whole video decoded into memory at once (one chunk)."""
    from jaxtrack.vision import foreground_mask, read_video, to_grey

    frames = read_video(video, scale=SCALE).frames
    reads = tracker.reads
    masks = None
    if "masks" in reads:
        scene = video_background(video, scale=SCALE)
        masks = np.stack([foreground_mask(image, scene) for image in frames])
    chunk = VideoChunk(grey=to_grey(frames) if "grey" in reads else None, masks=masks)
    # an iterator (a stream of one chunk), whose frame keys are drawn as the pipeline's are;
    # scanned 3 frames at a time, as the pipeline's run, so that one compilation serves both
    return track(tracker, KEY, iter([chunk]), None if pose is None else pose * SCALE,
                 progress=False, chunk_size=3)


def _video_size(path):
    capture = cv2.VideoCapture(str(path))
    size = (int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)),
            int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
    capture.release()
    return size, count


def _run(name, rendered, figure_video, out):
    """Track case ``name`` through the pipeline into ``out``; check what every run must
    write; return ``(record, track.json, tracker, video, pose)``."""
    tracker, video, pose = _case(name, rendered, figure_video)
    record = track_video(tracker, video, out, key=KEY, initial_pose=pose, scale=SCALE,
                         chunk_frames=3, progress=False, seed=5,
                         extra_record={"command": "test"})
    assert sorted(p.name for p in out.iterdir()) == ["overlay.mp4", "track.json"]
    saved = json.loads((out / "track.json").read_text())
    assert saved["command"] == "test" and saved["seed"] == 5
    (size, count), (video_size, _) = _video_size(out / "overlay.mp4"), _video_size(video)
    assert size == video_size == tuple(saved["size"]) and count == FRAMES
    assert saved["tracked_size"] == [round(video_size[0] * SCALE), round(video_size[1] * SCALE)]
    assert len(saved["frames"]) == FRAMES
    assert all(frame["status"] in STATUSES for frame in saved["frames"])
    assert set(saved["statuses"]) == STATUSES and saved["lost_rule"]
    assert saved["method"] == tracker.options()["method"]
    assert saved["timings"]["seconds_per_frame"] > 0
    # markers in video pixels: the tracker's, scaled back
    names = saved["marker_names"]
    written = np.array([[frame["markers"][n] for n in names] for frame in saved["frames"]],
                       np.float64)
    np.testing.assert_allclose(written, record["result"].markers / SCALE, atol=0.006)
    # decoding in chunks of 3 tracks as the whole video in memory does
    whole = _whole(tracker, video, pose)
    np.testing.assert_allclose(record["result"].markers, whole.markers, rtol=1e-5, atol=1e-3)
    return record, saved, written, pose


def test_a_video_file_is_tracked_in_chunks_in_the_video_pixels(figure_video, tmp_path):
    """The figure's centroid, found in half-size foreground masks against the video's
    median background, is written back in the video's pixels."""
    _, saved, written, _ = _run("centroid", None, figure_video, tmp_path / "run" / "in")
    rows, columns = np.nonzero(_figure_mask())
    truth = np.array([[columns.mean() + 20 * t, rows.mean()] for t in range(FRAMES)])
    np.testing.assert_allclose(written[:, 0], truth, atol=1.0)
    assert saved["masks"].startswith("foreground") and saved["background"]
    assert [frame["status"] for frame in saved["frames"]] == ["ok"] * FRAMES


@pytest.mark.parametrize("name", [pytest.param("condensation", marks=pytest.mark.slow),
                                  pytest.param("mht", marks=pytest.mark.slow),
                                  "mixed-state"])
def test_every_tracker_runs_from_a_video_file_in_chunks_as_from_memory(name, figure_video,
                                                                       tmp_path, request):
    rendered = None if name == "mixed-state" else request.getfixturevalue("rendered")
    _, saved, written, pose = _run(name, rendered, figure_video, tmp_path / "out")
    if pose is not None:  # frame 0 reports the initial pose, given and written in video pixels
        np.testing.assert_allclose(written[0], pose, atol=2.0)


def test_a_smoother_reports_every_frame_given_the_whole_video(figure_video, tmp_path):
    """With ``smooth``, the markers written and drawn are the tracker's smoother's, the
    filter's beside them, and ``annotate``'s entries replace the estimate's scalars; a tracker
    without a smoother is refused before a frame is decoded."""
    from jaxtrack.trackers.mixed_state import MixedStateModel, MixedStateTracker

    tracker = MixedStateTracker(MixedStateModel(figure_postures()), 16, keep_history=True)

    def annotate(result, smoothed, factors):
        assert factors.shape == (2,) and len(smoothed.posture) == len(result.markers)
        return ([{"posture": int(q)} for q in smoothed.posture],
                [f"posture {int(q)}" for q in smoothed.posture])

    record = track_video(tracker, figure_video, tmp_path / "out", key=KEY, scale=SCALE,
                         chunk_frames=3, progress=False, smooth=True, annotate=annotate)
    saved = json.loads((tmp_path / "out" / "track.json").read_text())
    assert saved["estimate"].startswith("smoothed") and saved["timings"]["smooth_seconds"] > 0
    smoothed = tracker.smooth(record["result"].estimates)
    names = saved["marker_names"]
    for key, expected in (("markers", smoothed.markers), ("filtered_markers",
                                                          record["result"].markers)):
        written = np.array([[frame[key][n] for n in names] for frame in saved["frames"]])
        np.testing.assert_allclose(written, expected / SCALE, atol=0.006)
    assert [frame["posture"] for frame in saved["frames"]] == smoothed.posture.tolist()
    assert "ess" in saved["frames"][0] and "silhouette" not in saved["frames"][0]
    with pytest.raises(ValueError, match="Centroid has no whole-sequence smoother"):
        track_video(Centroid(), figure_video, tmp_path / "none", key=KEY, progress=False,
                    smooth=True)
    assert not (tmp_path / "none").exists()


def test_a_frame_without_the_person_is_no_person(figure_video, tmp_path):
    """An empty frame (the figure gone) has an empty foreground mask: 'no person'."""
    from jaxtrack.vision import read_video, write_frames

    frames = read_video(figure_video).frames
    empty = np.full_like(frames[0], 30)
    video = write_frames([*frames[:5], empty, *frames[5:]], tmp_path / "gap.mp4", 10.0,
                         (400, 200))
    record = track_video(Centroid(), video, tmp_path / "out", key=KEY, progress=False)
    statuses = [frame["status"] for frame in record["frames"]]
    assert statuses[5] == FrameStatus.NO_PERSON.value
    assert statuses[:5] + statuses[6:] == ["ok"] * FRAMES


@pytest.mark.parametrize("where", ["/proc/x", "file"])
def test_an_unwritable_output_folder_is_refused_before_a_frame_is_decoded(where, figure_video,
                                                                          tmp_path,
                                                                          monkeypatch):
    import jaxtrack.vision

    if where == "file":
        blocker = tmp_path / "a file"
        blocker.write_text("")
        where = blocker / "out"
    decoded = []
    for name in ("read_video", "iter_video_chunks"):
        monkeypatch.setattr(jaxtrack.vision, name, lambda *a, **k: decoded.append(a))
    with pytest.raises(ValueError) as error:
        track_video(Centroid(), figure_video, where, key=KEY, progress=False)
    assert str(where) in str(error.value) and "\n" not in str(error.value)
    assert decoded == []


def test_nothing_half_written_when_the_run_fails(figure_video, tmp_path, monkeypatch):
    """An interrupt after the overlay (here: while the JSON is written) leaves no file and
    removes the folder the run made."""
    def interrupt(*_, **__):
        raise KeyboardInterrupt

    monkeypatch.setattr("jaxtrack._files.write_json_atomically", interrupt)
    out = tmp_path / "new" / "folder"
    with pytest.raises(KeyboardInterrupt):
        track_video(Centroid(), figure_video, out, key=KEY, progress=False)
    assert list(tmp_path.iterdir()) == []


def _decoded_chunk_sizes(monkeypatch) -> list[int]:
    """From now on, the size of every chunk decoded (appended to the list returned); reading
    more than one frame at once with ``read_video`` fails the test."""
    import jaxtrack.vision

    sizes, chunks, read = [], jaxtrack.vision.iter_video_chunks, jaxtrack.vision.read_video

    def counted(*args, **kwargs):
        for chunk in chunks(*args, **kwargs):
            sizes.append(chunk.num_frames)
            yield chunk

    def first_only(*args, **kwargs):
        assert kwargs.get("max_frames") == 1
        return read(*args, **kwargs)

    monkeypatch.setattr(jaxtrack.vision, "iter_video_chunks", counted)
    monkeypatch.setattr(jaxtrack.vision, "read_video", first_only)
    return sizes


def test_the_video_is_never_decoded_whole(figure_video, tmp_path, monkeypatch):
    """Frames are read alone (the first) or in chunks of chunk_frames (the first chunk one
    more: frame 0, the tracker's set-up): never all at once."""
    sizes = _decoded_chunk_sizes(monkeypatch)
    record = track_video(Centroid(), figure_video, tmp_path, key=KEY, chunk_frames=4,
                         progress=False)
    assert sizes and max(sizes) <= 4 + 1 and sum(sizes) >= FRAMES
    assert record["frames_tracked"] == FRAMES


def test_marker_names_follow_the_tracker():
    assert pipeline.default_marker_names(5) == ("head", "hand_1", "hand_2", "foot_1", "foot_2")
    assert len(pipeline.default_marker_names(12)) == 12
    assert pipeline.default_marker_names(2) == ("marker_0", "marker_1")


def test_the_median_background_of_a_streamed_video_is_that_of_its_frames(figure_video):
    from jaxtrack.vision import (
        median_background,
        median_grey_background,
        read_video,
        to_grey,
    )

    frames = read_video(figure_video, scale=SCALE).frames
    np.testing.assert_array_equal(video_background(figure_video, scale=SCALE, chunk_frames=3),
                                  median_background(frames))
    np.testing.assert_allclose(video_background(figure_video, scale=SCALE, grey=True),
                               median_grey_background(to_grey(frames)), atol=1e-6)


def test_keypoints_are_given_in_video_pixels_and_read_in_tracking_pixels(figure_video,
                                                                        tmp_path):
    """A detector's keypoints (video pixels) reach the tracker in tracking pixels and come
    back in video pixels; a tracker that does not read them refuses them in one line."""
    points = np.random.default_rng(0).uniform(10, 190, (FRAMES + 2, 12, 2))
    confidence = np.ones((FRAMES + 2, 12))
    record = track_video(Detected(), figure_video, tmp_path / "out", key=KEY, scale=SCALE,
                         keypoints=(points, confidence), chunk_frames=3, progress=False)
    np.testing.assert_allclose(record["result"].markers, points[:FRAMES] * SCALE)
    names = record["marker_names"]
    written = np.array([[frame["markers"][n] for n in names] for frame in record["frames"]])
    np.testing.assert_allclose(written, points[:FRAMES], atol=0.006)
    with pytest.raises(ValueError, match="does not read keypoints") as error:
        track_video(Centroid(), figure_video, tmp_path / "other", key=KEY,
                    keypoints=(points, confidence), progress=False)
    assert "\n" not in str(error.value) and not (tmp_path / "other").exists()
    with pytest.raises(ValueError, match="keypoints hold 3 frames"):
        track_video(Detected(), figure_video, tmp_path / "short", key=KEY,
                    keypoints=(points[:3], confidence[:3]), progress=False)


@pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")
def test_chunks_made_ahead_come_in_order_and_carry_their_errors():
    import threading

    from jaxtrack.experiments.pipeline import _ahead

    assert list(_ahead(iter(range(5)))) == list(range(5))

    def failing():
        yield 1
        raise ValueError("frame 2 is damaged")

    stream = _ahead(failing())
    assert next(stream) == 1
    with pytest.raises(ValueError, match="frame 2 is damaged"):
        next(stream)
    # a consumer that stops early (an error, Ctrl-C) stops the thread
    endless = _ahead(iter(int, 1))
    next(endless)
    endless.close()
    assert not any(thread.name == "jaxtrack-decoder" for thread in threading.enumerate())


SCENE = np.full((200, 400, 3), 30, np.uint8)  # the figure video's empty scene


def _figure_x(frames) -> np.ndarray:
    """The drawn figure's centroid x in the video's frames ``frames``."""
    columns = np.nonzero(_figure_mask())[1]
    return columns.mean() + 20 * np.asarray(frames)


def test_a_stride_tracks_and_draws_every_nth_frame(figure_video, tmp_path):
    out = tmp_path / "out"
    record = track_video(Centroid(), figure_video, out, key=KEY, stride=3, chunk_frames=2,
                         background=SCENE, progress=False)
    frames = record["frames"]
    assert [frame["frame"] for frame in frames] == [0, 3, 6] and record["stride"] == 3
    assert [frame["time_s"] for frame in frames] == pytest.approx([0.0, 0.3, 0.6])
    np.testing.assert_allclose([frame["markers"]["marker_0"][0] for frame in frames],
                               _figure_x([0, 3, 6]), atol=1.0)
    assert record["fps"] == pytest.approx(10.0 / 3)
    assert _video_size(out / "overlay.mp4") == ((400, 200), 3)


def test_a_window_is_cut_from_every_frame_and_markers_come_back_in_video_pixels(
        figure_video, tmp_path):
    """Where the window holds the whole figure, the centroid it gives, moved by the window's
    origin, is the figure's in the video; where it cuts the figure, it is not."""
    from jaxtrack.experiments.pipeline import Window

    record = track_video(Centroid(), figure_video, tmp_path / "out", key=KEY, progress=False,
                         background=SCENE, window=Window((300, 200), origin=(100, 0)))
    assert record["tracked_size"] == [300, 200]
    assert record["window"] == {"size": [300, 200], "origin": [100.0, 0.0],
                                "located_from": None}
    x = np.array([frame["markers"]["marker_0"][0] for frame in record["frames"]])
    columns = np.nonzero(_figure_mask())[1]
    moved = 20 * np.arange(FRAMES)
    inside = (columns.min() + moved >= 100) & (columns.max() + moved < 400)
    assert inside.any() and not inside.all()
    np.testing.assert_allclose(x[inside], _figure_x(np.nonzero(inside)[0]), atol=1.0)
    assert np.all(np.abs(x[~inside] - _figure_x(np.nonzero(~inside)[0])) > 1.0)
    with pytest.raises(ValueError, match="origin=.* or locate=..., one of them"):
        Window((360, 200))


def test_a_window_is_located_from_frames_sampled_over_the_video(figure_video, tmp_path):
    from jaxtrack.experiments.pipeline import Window

    calls = []

    def locate(frames, background, masks):
        calls.append((frames.shape, None if background is None else background.shape, masks))
        return np.array([40.0, 10.0]), 7

    record = track_video(Centroid(), figure_video, tmp_path / "out", key=KEY, progress=False,
                         window=Window((240, 160), locate=locate))
    assert calls == [((FRAMES, 200, 400, 3), (200, 400, 3), None)]
    assert record["window"] == {"size": [240, 160], "origin": [40.0, 10.0], "located_from": 7}
    assert record["runs"][0].origin.tolist() == [40.0, 10.0]


def test_several_views_are_tracked_alike_cut_to_the_shortest_and_reported_together(
        figure_video, tmp_path, monkeypatch):
    """Each view tracked with the same key, cut to the shortest's 6 frames, decoded in
    chunks (never whole, the overlay's frames too), and reported by the hook."""
    from jaxtrack.experiments.pipeline import Window
    from jaxtrack.vision import read_video, write_frames

    frames = read_video(figure_video).frames
    shorter = write_frames(frames[:6, :, ::-1], tmp_path / "mirrored.mp4", 10.0, (400, 200))
    seen, sizes = {}, _decoded_chunk_sizes(monkeypatch)

    def report(runs, timings):
        seen["runs"], seen["timings"] = runs, timings

        def draw(views_frames, path, fps):
            seen["fps"] = fps
            images = [np.concatenate(views, axis=1) for views in views_frames]
            seen["drawn"] = len(images)
            return write_frames(images, path, fps, (images[0].shape[1], images[0].shape[0]))

        return {"views": [run.name for run in runs]}, draw

    out = tmp_path / "out"
    with pytest.raises(ValueError, match="report="):
        track_video(Centroid(), [figure_video, shorter], out, key=KEY, progress=False)
    record = track_video(Centroid(), [figure_video, shorter], out, key=KEY, progress=False,
                         stride=[1, 1], window=Window((400, 200), origin=(0, 0)),
                         background=[SCENE, SCENE],
                         view_names=["front", "mirror"], report=report, chunk_frames=4,
                         extra_record={"command": "test"})
    assert sizes and max(sizes) <= 4
    assert record["runs"] == seen["runs"]
    saved = json.loads((out / "track.json").read_text())
    assert saved == {"views": ["front", "mirror"], "command": "test"}
    runs = seen["runs"]
    assert [run.name for run in runs] == ["front", "mirror"]
    assert [run.frame_indices.tolist() for run in runs] == [list(range(6))] * 2
    x = [np.asarray(run.result.markers)[:, 0, 0] for run in runs]
    np.testing.assert_allclose(x[0], _figure_x(range(6)), atol=1.0)
    np.testing.assert_allclose(x[1], 399 - _figure_x(range(6)), atol=1.0)  # mirrored
    assert seen["timings"]["tracking_pass_seconds"] > 0 and seen["drawn"] == 6
    assert _video_size(out / "overlay.mp4") == ((800, 200), 6)


class Reasoned(FrameEstimate):
    reason: jnp.ndarray


class FarRight(Centroid):
    """The centroid tracker whose observation says the frame was not observed (reason 1)
    where the figure's centroid lies right of x = 170."""

    @property
    def observation_reasons(self):
        return ("", "too far right")

    def observe(self, chunk, out=None):
        centroid = super().observe(chunk)
        return np.concatenate([centroid, (centroid[:, :1] > 170).astype(np.float64)], axis=1)

    def first_estimate(self, state):
        point = state[None, :2]
        return Reasoned(point, point, jnp.asarray(1.0), jnp.asarray(0.0), jnp.asarray(False),
                        state[2].astype(jnp.int32))

    def update(self, key, state, frame):
        state = frame_at(frame)
        return state, self.first_estimate(state)


def test_the_observations_reasons_make_a_frame_no_person(figure_video, tmp_path):
    record = track_video(FarRight(), figure_video, tmp_path / "out", key=KEY, progress=False)
    far = _figure_x(range(FRAMES)) > 170
    assert far.any() and not far.all()
    assert [frame["status"] for frame in record["frames"]] == [
        "no person" if value else "ok" for value in far]
    assert [frame["observation"] for frame in record["frames"]] == [
        "too far right" if value else "observed" for value in far]
    assert record["runs"][0].reasons == ["too far right" if value else "" for value in far]
