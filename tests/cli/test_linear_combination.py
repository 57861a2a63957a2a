"""``jaxtrack train|track|evaluate --method linear-combination``: a tiny model trained from the
command line tracks rendered video written to mp4 (one calibrated full-frame view; two views
with view selection), is evaluated on a held-out subject, and bad input is refused in one line
with nothing written.

Bundled clips only (no ``../shared``); tiny settings (30 training frames, 3 clusters, 20
particles, 2 iterations, 11-frame videos) so that every tracker shares one compiled scan.
"""

import json
import math

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12, Camera, render_motion
from jaxtrack.cli import main
from jaxtrack.data import path as data_path
from jaxtrack.data import resolve_clip
from jaxtrack.experiments import linear_combination as lc
from jaxtrack.vision import median_background, read_video, write_frames, write_masks

TRAIN = "animateddrawings/fair1_wave_hello"
TEST = "animateddrawings/history_c119d6b/cmu_1006_wave_hello_1"
EMPTY, PERSON = 6, 5  # frames of empty scene, then of the person: the median is the scene
FULL_SIZE = (724, 1280)  # a Pose2Sim camera's 1088 x 1920 image at 2/3 (twice the model's)
SHIFT = np.array([-120.0, 100.0])  # the figure's upper body is this far from the frame's centre
TINY = ("--particles", "20", "--iterations", "2")


def _strict_json(path):
    def refuse(constant):
        raise AssertionError(f"{path} holds {constant}")

    return json.loads(path.read_text(), parse_constant=refuse)


def _with_empty_scene(images, background):
    return np.concatenate([np.repeat(background[None], EMPTY, axis=0), images])


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("linear_combination")


@pytest.fixture(scope="module")
def model(folder):
    path = folder / "model.npz"
    code = main(["train", "--method", "linear-combination", "--clips", TRAIN, "--cameras", "0",
                 "1", "--clusters", "3", "--max-frames", "30", "--out", str(path)])
    assert code == 0 and path.is_file()
    trained = lc.load(path)
    assert trained.model.num_clusters == 3 and trained.description["views"] == [0, 1]
    return path


@pytest.fixture(scope="module")
def crop_videos(folder):
    """The test subject through cameras 0 and 1, rendered at the model's scale and crop."""
    sequences = lc.render_hybrid_sequences(TEST, views=(0, 1), max_frames=PERSON, seed=3,
                                           keep_images=True)
    return [write_frames(_with_empty_scene(s.images, s.background), folder / f"{s.name}.mp4",
                         30.0, lc.CROP_SIZE) for s in sequences]


@pytest.fixture(scope="module")
def full_video(folder):
    """The test subject in a whole frame of Pose2Sim camera 2 at twice the model's scale, off
    its centre."""
    motion = resolve_clip(TEST).load().resample(30.0).select(0, PERSON)
    staged, cameras = lc.pose2sim_cameras(motion, scale=2 * lc.CAMERA_SCALE, crop=FULL_SIZE)
    camera = cameras[2]
    camera = Camera(camera.focal_length, camera.principal_point + SHIFT, camera.rotation,
                    camera.translation, camera.distortion, camera.image_size, name=camera.name)
    rendered = render_motion(staged, camera, background="photo", markers=UPPER_BODY_12,
                             seed=5, progress=False)
    background = lc._background_of(rendered, camera.image_size)
    return write_frames(_with_empty_scene(rendered.images, background), folder / "full.mp4",
                        30.0, FULL_SIZE)


def _track(out, model, *videos, extra=()):
    return main(["track", "--method", "linear-combination", "--model", str(model), "--video",
                 *map(str, videos), "--out", str(out), *TINY, *extra])


def test_track_one_calibrated_view_in_video_pixels(folder, model, full_video):
    video = full_video
    out = folder / "one"
    assert _track(out, model, video, extra=("--calibration", str(data_path(
        "pose2sim/Calib.qca.txt")), "--cameras", "2")) == 0
    record = _strict_json(out / "track.json")
    frames = record["frames"]
    assert len(frames) == EMPTY + PERSON == read_video(out / "overlay.mp4").num_frames
    # decoded at the model's scale (half this video's), cut near where training puts its
    # window, around the upper body's middle (SHIFT from the frame's centre); estimated from
    # silhouettes, whose legs the floor partly hides
    view = record["views"][0]
    assert view["camera"] == "cam03" and view["size"] == list(FULL_SIZE)
    assert view["scale"] == [0.5, 0.5]
    expected = (np.asarray(FULL_SIZE) / 2 + SHIFT) / 2 - np.asarray(lc.CROP_SIZE) / 2
    assert np.abs(np.asarray(view["crop_origin"]) - expected).max() < 32, view["crop_origin"]
    # the head the tracker saw in its window, back in the video's own pixels
    frames_half = read_video(video, scale=0.5).frames
    x0, y0 = (int(v) for v in view["crop_origin"])
    window = np.s_[..., y0:y0 + lc.CROP_SIZE[1], x0:x0 + lc.CROP_SIZE[0], :]
    seen, _ = lc.observe(frames_half[window], median_background(frames_half)[window])
    for t, frame in enumerate(frames):
        entry = frame["views"][0]
        if t < EMPTY:
            assert entry["status"].startswith("no silhouette") and entry["head"] is None
            assert frame["selected_view"] is None
            assert frame["status"] == entry["frame_status"] == "no person"
            continue
        assert entry["observed"] and frame["selected_view"] == 0
        assert frame["status"] == entry["frame_status"] and frame["status"] in record["statuses"]
        head = (seen.head[t] + (x0, y0) + 0.5) / 0.5 - 0.5
        np.testing.assert_allclose(entry["head"], head, atol=0.01)
        hands = (np.asarray(entry["hands"]) + 0.5) * 0.5 - 0.5 - (x0, y0)
        assert np.all((hands >= 0) & (hands < lc.CROP_SIZE)), hands
        skeleton = np.array([entry["skeleton_m"][joint] for joint in UPPER_BODY_12])
        world = np.array([entry["skeleton_world_m"][joint] for joint in UPPER_BODY_12])
        assert np.all(np.abs(skeleton) < 2.0) and skeleton[1].tolist() == [0.0, 0.0, 0.0]
        # a rotation: the same distances from the neck in the world's axes
        np.testing.assert_allclose(np.linalg.norm(world, axis=1),
                                   np.linalg.norm(skeleton, axis=1), atol=2e-4)
    # the 3-D track as a .trc: the selected view's world skeleton per frame, blank before
    from jaxtrack.vision import read_trc

    positions, names, _ = read_trc(out / "track.trc")
    assert list(names) == list(record["joints"]) and len(positions) == len(frames)
    assert np.isnan(positions[:EMPTY]).all()
    world = np.array([[frame["views"][0]["skeleton_world_m"][joint]
                       for joint in record["joints"]] for frame in frames[EMPTY:]])
    np.testing.assert_allclose(positions[EMPTY:], world, atol=1e-4)


def test_track_takes_the_silhouettes_from_masks_the_user_brings(folder, model, full_video):
    from jaxtrack.vision import foreground_mask

    frames = read_video(full_video).frames
    masks = np.stack([foreground_mask(frame, frames[0]) for frame in frames])
    masks[EMPTY + 2] = False  # a segmenter that missed the person in one frame
    path = write_masks(folder / "masks.npz", masks)
    out = folder / "masked"
    assert _track(out, model, full_video, extra=("--calibration", str(data_path(
        "pose2sim/Calib.qca.txt")), "--cameras", "2", "--masks", str(path))) == 0
    record = _strict_json(out / "track.json")
    assert record["views"][0]["silhouettes"] == f"masks {path}"
    for t, frame in enumerate(record["frames"]):
        entry = frame["views"][0]
        if t < EMPTY or t == EMPTY + 2:
            assert entry["status"] == "no silhouette (the mask is empty)", (t, entry)
            assert entry["head"] is None
        else:
            assert entry["observed"], (t, entry)


def test_track_two_views_selects_a_view_per_frame_by_the_chosen_rule(folder, model,
                                                                    crop_videos):
    out = folder / "two"
    assert _track(out, model, *crop_videos) == 0
    record = _strict_json(out / "track.json")
    assert record["view_selection"] == lc.DEFAULT_VIEW_SELECTION == "ambiguity"
    assert record["skeleton_estimate"] == lc.DEFAULT_SKELETON_ESTIMATE == "mean"
    observed = np.array([[view["observed"] for view in frame["views"]]
                         for frame in record["frames"]])
    ambiguity = np.array([[view["ambiguity"] if view["observed"] else 0.0
                           for view in frame["views"]] for frame in record["frames"]])
    # the default from the file's own numbers: each view's mean −log(ambiguity + 10⁻³) over
    # ±5 frames of those it observed (select_views' floor)
    means = np.full(ambiguity.shape, -np.inf)
    for t, v in zip(*np.nonzero(observed), strict=True):
        near = slice(max(0, t - 5), t + 6)
        means[t, v] = -np.log(ambiguity[near, v][observed[near, v]] + 1e-3).mean()
    selected = []
    for t, frame in enumerate(record["frames"]):
        if not observed[t].any():
            assert frame["selected_view"] is None
            continue
        assert frame["selected_view"] == int(np.argmax(means[t]))
        assert frame["selected"] == record["views"][frame["selected_view"]]["camera"]
        selected.append(frame["selected_view"])
    assert len(selected) == PERSON
    # the paper's rule, fitness × 1/ambiguity (select_views' floor 1e-3), on request
    paper = folder / "two_paper"
    assert _track(paper, model, *crop_videos, extra=("--view-selection", "paper")) == 0
    record = _strict_json(paper / "track.json")
    assert record["view_selection"] == "paper"
    for frame in record["frames"]:
        if frame["selected_view"] is None:
            continue
        score = [view["log_fitness"] - math.log(view["ambiguity"] + 1e-3)
                 if view["observed"] else -math.inf for view in frame["views"]]
        assert frame["selected_view"] == int(np.argmax(score))
    overlay = read_video(out / "overlay.mp4").frames
    width, height = 2 * np.asarray(lc.CROP_SIZE)
    drawing = round(0.8 * (height + 18))  # the 3-D skeleton from the front and the side
    assert overlay.shape[1:3] == (height + 18, 2 * width + 2 * drawing)
    # the selected view's skeleton is drawn where a view observed the frame, not before
    body = np.s_[(height + 18) // 4:, 2 * width + 8:2 * width + drawing - 8]
    yellow = lambda image: np.sum(np.abs(image.astype(int) - (255, 224, 0)).max(-1) < 60)  # noqa: E731
    assert yellow(overlay[EMPTY + 2][body]) > 50
    assert yellow(overlay[0][body]) == 0
    # the selected view is framed in yellow
    t = EMPTY + 2
    border = overlay[t, 1, selected[2] * width + 20: (selected[2] + 1) * width - 20]
    other = overlay[t, 1, (1 - selected[2]) * width + 20: (2 - selected[2]) * width - 20]
    assert np.abs(border.mean(axis=0) - (255, 224, 0)).max() < 40
    assert np.abs(other.mean(axis=0) - (255, 224, 0)).max() > 60


@pytest.mark.slow  # renders and tracks the test clips with three methods
def test_evaluate_scores_three_methods_with_the_cached_model(folder, model, capsys):
    out = folder / "evaluation"
    out.mkdir()
    cache = out / "lc_cache.npz"
    cache.write_bytes(model.read_bytes())  # trained on TRAIN through cameras 0 1: reused
    before = cache.stat().st_mtime_ns
    capsys.readouterr()
    code = main(["evaluate", "--method", "linear-combination", "--train", TRAIN, "--test", TEST,
                 "--cameras", "0", "1", "--max-frames", str(EMPTY + PERSON), *TINY,
                 "--json", str(out / "metrics.json"), "--plots", str(out / "plots")])
    printed = capsys.readouterr().out
    assert code == 0 and "reusing" in printed and cache.stat().st_mtime_ns == before
    assert "| method | 3-D error (mm) |" in printed
    record = _strict_json(out / "metrics.json")
    assert [row["method"] for row in record["summary"]] == list(lc.METHODS)
    sequences = record["results"]["sequences"]
    assert len(sequences) == 2
    for row in record["summary"]:
        assert 0 < row["error_mm"] <= row["worst_sequence_mm"] < 2000
        assert row["frames"] == 2 * (EMPTY + PERSON) and row["compile_seconds"] >= 0
        assert f"| {row['method']} | {row['error_mm']:.1f} |" in printed
    assert record["skeleton_estimate"] == lc.DEFAULT_SKELETON_ESTIMATE
    assert f"the filters' {lc.DEFAULT_SKELETON_ESTIMATE} skeleton" in printed
    for entry in sequences.values():
        for method in lc.METHODS:
            errors = entry[method]["errors_m"]
            assert len(errors) == EMPTY + PERSON
            assert np.mean(errors) == pytest.approx(entry[method]["error_m"], abs=1e-5)
        for method in ("linear-combination", "global-pca"):  # both estimates, the default's
            assert entry[method]["error_m"] == entry[method][
                f"{lc.DEFAULT_SKELETON_ESTIMATE}_error_m"]
            assert entry[method]["best_error_m"] != entry[method]["mean_error_m"]
        assert "best_error_m" not in entry["nearest-neighbour"]
    plots = sorted(path.name for path in (out / "plots").iterdir())
    assert plots == sorted([f"{name}_errors.png" for name in sequences]
                           + [f"{next(iter(sequences))}_linear-combination.mp4"])


def _fake_model(path, kind):
    from jaxtrack._files import write_npz_atomically

    write_npz_atomically(path, {"x": np.zeros(2)}, {"format": kind, "format_version": 1})
    return path


CALIBRATION = str(data_path("pose2sim/Calib.qca.txt"))


@pytest.mark.parametrize("arguments, message", [
    (["track", "--model", "{gplvm}", "--video", "{crop}"],
     "--model {gplvm}: a GPLVM pose prior (the latent tracker's), not a linear-combination"),
    (["track", "--model", "{postures}", "--video", "{crop}"],
     "--model {postures}: a posture model (the mixed-state tracker's), not a linear-combination"),
    (["track", "--model", "{model}", "--video", "{crop}", "--calibration", CALIBRATION],
     "--video: 1 video(s) but 4 camera(s) (cam01, cam02, cam03, cam04) of --calibration"),
    (["track", "--model", "{model}", "--video", "{crop}", "{crop}", "--calibration",
      CALIBRATION, "--cameras", "1", "7"], "--cameras must be distinct indices 0-3"),
    (["track", "--model", "{model}", "--video", "{crop}", "--calibration", "{inputs}/no.txt"],
     "--calibration {inputs}/no.txt: no such file"),
    (["track", "--model", "{model}", "--video", "{full}"],
     "--calibration is required for --video {full} (724x1280)"),
    (["track", "--model", "{model}", "--video", "{crop}", "--skin", "300,1,1"],
     "--skin must be R,G,B"),
    (["track", "--model", "{model}", "--video", "{inputs}/none.mp4"],
     "--video {inputs}/none.mp4: no such file"),
    (["track", "--model", "{model}", "--video", "{crop}", "--keypoints", "{model}"],
     "--calibration is required with --keypoints for --method linear-combination"),
    (["track", "--model", "{model}", "--video", "{crop}", "--detector", "mediapipe"],
     "--detector does not apply to --method linear-combination"),
    (["track", "--model", "{model}", "--video", "{crop}", "--no-fit"],
     "--no-fit applies to --method linear-combination only with --keypoints"),
    (["track", "--model", "{model}", "--video", "{crop}", "--coverage-weight", "5"],
     "--coverage-weight does not apply to --method linear-combination"),
    (["track", "--model", "{model}", "--video", "{crop}", "--masks", "{inputs}/short.npz",
      "{inputs}/short.npz"], "--masks: one file per --video, got 2 for 1"),
    (["track", "--model", "{model}", "--video", "{crop}", "--masks", "{model}"],
     "--masks {model}: no array 'masks'"),
    (["track", "--model", "{model}", "--video", "{crop}", "--masks", "{inputs}/short.npz"],
     "--masks {inputs}/short.npz: holds 3 masks, but video frame 10 is tracked"),
    (["train", "--clips", TEST], "--clips " + TEST + ": subject animateddrawings:cmu_1006 is a "
     "test subject"),
    (["train", "--clips", TRAIN, "--cameras", "0", "4"], "--cameras must be Pose2Sim camera "
     "indices 0-3, got 4"),
    (["train", "--clips", TRAIN, "--cameras", "1", "1"], "--cameras names a camera twice"),
    (["train", "--clips", TRAIN, "--clusters", "1"], "--clusters must be at least 2"),
    (["train", "--clips", TRAIN, "--out", "{gplvm}"], "--out {gplvm}: a GPLVM pose prior"),
    (["evaluate", "--train", "cmu_amc/07_01", "--test", "cmu_amc/07_02"],
     "--test: subject cmu:07 is in both the training clips"),
    (["evaluate", "--train", TRAIN, "--test", TEST, "--cameras", "5"],
     "--cameras must be Pose2Sim camera indices 0-3, got 5"),
    (["evaluate", "--train", TRAIN, "--test", TEST, "--json", "{inputs}/damaged/out.json"],
     "the model cached beside --json: {inputs}/damaged/lc_cache.npz: damaged or truncated"),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, model, crop_videos,
                                                         full_video, arguments, message):
    inputs = tmp_path / "inputs"
    (inputs / "damaged").mkdir(parents=True)
    (inputs / "damaged" / "lc_cache.npz").write_bytes(model.read_bytes()[:500])
    write_masks(inputs / "short.npz", np.zeros((3, *lc.CROP_SIZE[::-1]), bool))
    names = {"gplvm": _fake_model(inputs / "gplvm.npz", "jaxtrack.gplvm"),
             "postures": _fake_model(inputs / "postures.npz", "jaxtrack.postures"),
             "model": model, "crop": crop_videos[0], "full": full_video, "inputs": inputs}
    contents = sorted(inputs.rglob("*"))
    command, *rest = arguments
    defaults = {"track": ["--out", str(tmp_path / "out")],
                "train": ["--out", str(tmp_path / "out" / "model.npz")],
                "evaluate": ["--json", str(tmp_path / "out" / "metrics.json")]}[command]
    rest = [argument.format(**names) for argument in rest]
    if rest.count("--out") or rest.count("--json"):
        defaults = []
    code = main([command, "--method", "linear-combination", *rest, *defaults])
    error = capsys.readouterr().err
    assert code == 2, error
    assert error.count("\n") == 1 and message.format(**names) in error, error
    assert sorted(inputs.rglob("*")) == contents and not (tmp_path / "out").exists()


def test_the_overlay_draws_the_selected_views_skeleton_in_one_frame_of_axes():
    from types import SimpleNamespace

    from jaxtrack.experiments.linear_combination import shown_skeletons as _shown_skeletons

    skeletons = [np.arange(12, dtype=float).reshape(2, 2, 3) + 100 * v for v in range(2)]
    turn = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    cameras = [SimpleNamespace(rotation=np.eye(3)), SimpleNamespace(rotation=turn)]
    shown = _shown_skeletons(skeletons, [1, None], cameras)
    np.testing.assert_allclose(shown[0], skeletons[1][0] @ turn)  # world = Rᵀ x, as rows
    assert np.all(np.isnan(shown[1]))
    # without a calibration, the camera's y (down) and z (forward) turned up and to the viewer
    alone = _shown_skeletons(skeletons[:1], [0, 0], None)
    np.testing.assert_allclose(alone, skeletons[0] * [1.0, -1.0, -1.0])


def test_the_skeleton_option_picks_the_weighted_mean_or_the_best_particle():
    from types import SimpleNamespace

    estimates = SimpleNamespace(skeleton_3d=np.zeros((2, 12, 3)),
                                best_skeleton_3d=np.ones((2, 12, 3)))
    assert lc.DEFAULT_SKELETON_ESTIMATE == "mean"
    assert np.all(lc.skeleton_estimates(estimates, "mean") == 0)
    assert np.all(lc.skeleton_estimates(estimates, "best") == 1)
    with pytest.raises(ValueError, match="skeleton_estimate must be one of"):
        lc.skeleton_estimates(estimates, "median")


def test_each_frame_not_observed_carries_its_reason_code():
    """The tracker's observation gives each frame's reason (OBSERVATION_REASONS), which the
    pipeline turns into 'no person' and the record's per-view status."""
    from jaxtrack.trackers.linear_combination import (
        OBSERVATION_REASONS,
        observe_contours,
        reason_codes,
    )

    scene = np.full((40, 30, 3), 90, np.uint8)
    frames = np.stack([scene, scene.copy()])
    frames[1, 10:30, 10:20] = (20, 200, 20)  # a green person: a silhouette without skin
    _, status = observe_contours(frames, scene)
    codes = reason_codes(status)
    assert [OBSERVATION_REASONS[code] for code in codes] == [
        "no silhouette (nothing differs from the background)",
        "no skin blobs: too few skin pixels for a head and two hands"]
    assert status[1].startswith("no skin blobs: 0 skin pixels")
    _, status = observe_contours(frames, None, masks=np.zeros((2, 40, 30), bool))
    assert reason_codes(status).tolist() == [2, 2]
    assert reason_codes(["", "no skin blobs: the skin pixels form fewer than three blobs"]
                        ).tolist() == [0, 4]


# ---- --keypoints: the calibrated views scored by their detections ----------------------------

KEYPOINT_VIDEO = (68, 120)  # a Pose2Sim camera's 1088 x 1920 image at 1/16


@pytest.fixture(scope="module")
def keypoint_views(tmp_path_factory):
    """Two Pose2Sim views of a skeleton the bundled model holds: 3-frame videos (blank: the
    tracker reads only their size and rate) and each view's exact projections as keypoints."""
    import jax.numpy as jnp

    from jaxtrack.body import read_qca
    from jaxtrack.body.camera import project
    from jaxtrack.data.models import default_model
    from jaxtrack.trackers.linear_combination_views import world_skeleton
    from jaxtrack.vision.keypoints import write_keypoints

    folder = tmp_path_factory.mktemp("keypoint_views")
    model = lc.load(default_model("linear-combination")).model.astype(jnp.float32)
    cameras = read_qca(CALIBRATION)[:2]
    shape = model.constrain(model.training_coefficients[100], model.training_clusters[100])
    truth = np.asarray(world_skeleton(
        model, jnp.asarray(cameras[0].rotation, jnp.float32), jnp.asarray([0.0, 0.0, 1.0]),
        {"coefficients": shape, "yaw": jnp.asarray(0.7), "scale": jnp.asarray(1.3),
         "translation": jnp.asarray([0.4, 0.9, 1.2])}), np.float64)
    videos, keypoints = [], []
    for camera in cameras:
        pixels = np.asarray(project(camera, jnp.asarray(truth)), np.float64) / 16
        videos.append(folder / f"{camera.name}.mp4")
        write_frames(np.zeros((3, KEYPOINT_VIDEO[1], KEYPOINT_VIDEO[0], 3), np.uint8), videos[-1],
                     60.0, KEYPOINT_VIDEO)
        keypoints.append(folder / "keypoints" / f"{camera.name}.npz")
        keypoints[-1].parent.mkdir(exist_ok=True)
        write_keypoints(keypoints[-1], np.repeat(pixels[None], 3, 0))
    return {"videos": videos,
            "folder": folder / "keypoints", "files": keypoints, "truth": truth}


def _one_line_refusal(arguments, out, capsys):
    code = main(["track", "--method", "linear-combination", *map(str, arguments),
                 "--out", str(out)])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1, error
    assert not out.exists()
    return error


def test_keypoints_refused_in_one_line(keypoint_views, tmp_path, capsys):
    from jaxtrack.vision.keypoints import write_keypoints

    videos, folder = keypoint_views["videos"], keypoint_views["folder"]
    views = ["--video", *videos, "--calibration", CALIBRATION, "--cameras", "0", "1"]
    out = tmp_path / "out"
    # a folder without the second camera's keypoints
    lacking = tmp_path / "lacking"
    lacking.mkdir()
    (lacking / "cam01.npz").write_bytes(keypoint_views["files"][0].read_bytes())
    error = _one_line_refusal([*views, "--keypoints", lacking], out, capsys)
    assert f"--keypoints {lacking}: no keypoints of camera cam02 there" in error
    # a damaged keypoint file
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    (damaged / "cam01.npz").write_bytes(keypoint_views["files"][0].read_bytes())
    (damaged / "cam02.npz").write_bytes(keypoint_views["files"][1].read_bytes()[:40])
    error = _one_line_refusal([*views, "--keypoints", damaged], out, capsys)
    assert "--keypoints: " in error and "cam02.npz" in error
    # the first frame's neck seen by one view only
    blind = tmp_path / "blind"
    blind.mkdir()
    (blind / "cam01.npz").write_bytes(keypoint_views["files"][0].read_bytes())
    write_keypoints(blind / "cam02.npz", np.full((3, 12, 2), np.nan), np.zeros((3, 12)))
    error = _one_line_refusal([*views, "--keypoints", blind], out, capsys)
    assert "the neck is found in fewer than 2 views" in error
    # no calibration, and an option of the video tracker
    error = _one_line_refusal(["--video", *videos, "--keypoints", folder], out, capsys)
    assert "--calibration is required with --keypoints" in error
    error = _one_line_refusal([*views, "--keypoints", folder, "--skin", "1,2,3"], out, capsys)
    assert "--skin does not apply to --method linear-combination with --keypoints" in error


@pytest.mark.slow
def test_keypoints_of_two_views_give_the_skeleton_in_track_json_and_trc(keypoint_views,
                                                                         tmp_path):
    from jaxtrack.evaluation.reference import read_trc

    out = tmp_path / "out"
    code = main(["track", "--method", "linear-combination", "--video",
                 *map(str, keypoint_views["videos"]), "--calibration", CALIBRATION,
                 "--cameras", "0", "1", "--keypoints", str(keypoint_views["folder"]),
                 "--particles", "100", "--out", str(out)])
    assert code == 0
    record = _strict_json(out / "track.json")
    truth = keypoint_views["truth"]
    joints = record["joints"]
    assert [frame["frame"] for frame in record["frames"]] == [0, 1, 2]
    world = np.array([[frame["skeleton_world_m"][joint] for joint in joints]
                      for frame in record["frames"]])
    # placed in the world where the views see it: the hand-set density (a spread of about a
    # third of the torso) and two views leave ~0.1 m; a wrong axis or camera is metres off
    assert np.linalg.norm(world - truth, axis=-1).mean(-1).max() < 0.2
    names, positions, rate = read_trc(out / "track.trc")
    assert rate == 60.0
    np.testing.assert_allclose(positions[:, :, [2, 0, 1]], world, atol=1e-4)
