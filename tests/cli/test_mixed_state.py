"""`jaxtrack train | track | evaluate --method mixed-state`: a posture model trained from the
shared posture clips, a rendered walk tracked from its own video (parts back in the video's
pixels, on the walker), Table 1 from one held-out clip, and bad input refused in one line with
nothing written.

Tiny settings throughout (160x120 images, a few frames, tens of particles): these check the
commands, not the tracker's accuracy (tests/mixed_state/ and `jaxtrack evaluate` do that)."""

import json
import math
import shutil

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.experiments.mixed_state import TRAINING_CLIPS
from jaxtrack.priors.postures import NUM_POSTURES, POSTURE_NAMES, PostureModel

SIZE = (160, 120)
TRAIN = ("--clips", *TRAINING_CLIPS, "--max-frames", "45", "--size", "160x120", "--azimuths",
         "90", "-90")  # the experiment's clips (the bundled model's default has no DeepMimic)
ESTIMATES = ("instantaneous", "filtered", "smoothed", "fixed_lag")


def run(capsys, *arguments):
    code = main([str(argument) for argument in arguments])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _needs_posture_clips():
    from jaxtrack.data import list_clips

    if "cmu_posture_bvh/75_20" not in list_clips():
        pytest.skip("the posture clips are in the project's shared data, not found here")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A posture model from the default training clips, 45 frames each (75_19 sits from its
    35th), two profile views."""
    pytest.importorskip("cv2")
    _needs_posture_clips()
    path = tmp_path_factory.mktemp("trained") / "postures.npz"
    assert main(["train", "--method", "mixed-state", "--out", str(path), *TRAIN]) == 0
    return path


@pytest.fixture(scope="module")
def bundled():
    """The posture model the package ships (trained on training subjects' CMU clips): what
    ``track`` uses without ``--model``."""
    from jaxtrack.data.models import default_model

    return default_model("mixed-state")


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """A 30-frame side view of a real walk (CMU 07_01, bundled) as an mp4, its true markers
    and its drawn silhouettes: the walker crosses the image, so the median background is the
    empty scene."""
    pytest.importorskip("cv2")
    from jaxtrack.body._backgrounds import make_background
    from jaxtrack.body._staging import frontal_camera
    from jaxtrack.body.markers import HUMANEVA_15
    from jaxtrack.body.render import render_motion
    from jaxtrack.data import load_clip
    from jaxtrack.vision import write_frames

    motion = load_clip("cmu_amc/07_01").resample(30.0)
    motion = motion.select(0, 30)
    camera = frontal_camera(motion, SIZE, azimuth=np.pi / 2, elevation=0.1)
    scene, _ = make_background("photo", SIZE, np.random.default_rng(0))
    rendered = render_motion(motion, camera, image_size=SIZE, background=scene,
                             markers=HUMANEVA_15, seed=0, progress=False)
    path = write_frames(rendered.images, tmp_path_factory.mktemp("walk") / "walk.mp4", 30.0,
                        SIZE)
    return path, np.asarray(rendered.markers_2d), np.asarray(rendered.silhouettes, bool)


@pytest.fixture
def posture_file(tmp_path):
    """A hand-made posture model (no shared data needed): checks that fail before tracking."""
    from jaxtrack.priors.postures import save_posture_model

    dimension = 2 * 4 + 1
    model = PostureModel(jnp.zeros((NUM_POSTURES, dimension)),
                         jnp.broadcast_to(jnp.eye(dimension), (NUM_POSTURES, dimension,
                                                               dimension)),
                         jnp.zeros(NUM_POSTURES),
                         jnp.full((NUM_POSTURES, NUM_POSTURES), -math.log(NUM_POSTURES)),
                         jnp.full(NUM_POSTURES, -math.log(NUM_POSTURES)), jnp.asarray(20.0))
    return save_posture_model(tmp_path / "postures.npz", model)


@pytest.mark.slow  # trains a posture model from the shared clips
def test_train_reuses_a_model_of_the_same_settings(trained, capsys, tmp_path):
    from jaxtrack.priors.postures import load_posture_model

    saved = load_posture_model(trained)
    counts = saved.description["label_counts"]
    assert saved.model.num_features == 33 and all(counts[name] >= 2 for name in POSTURE_NAMES)
    assert saved.description["frames"] == sum(counts.values()) <= 5 * 2 * 45
    assert saved.description["pose2sim_cameras"] == []  # the library's: level views only
    assert saved.description["components"] == 1 and saved.model.num_components == 1
    copy = shutil.copy(trained, tmp_path / "copy.npz")
    before = (tmp_path / "copy.npz").stat().st_mtime_ns
    code, out, _ = run(capsys, "train", "--method", "mixed-state", "--out", copy, *TRAIN)
    assert code == 0 and out.count("\n") == 1 and "(reused)" in out
    assert (tmp_path / "copy.npz").stat().st_mtime_ns == before


def test_track_writes_an_overlay_and_postures_in_video_pixels(bundled, walk, tmp_path, capsys):
    from jaxtrack.vision import read_video

    video, markers, _ = walk
    out = tmp_path / "out"
    # tracked at 80x60: every position must come back in the 160x120 video's pixels
    code, stdout, error = run(capsys, "track", "--method", "mixed-state", "--model", bundled,
                              "--video", video, "--out", out, "--particles", 64, "--max-size",
                              80, "--seed", 3)
    assert code == 0, error
    assert "tracked 30 frames (30 with a silhouette)" in stdout
    assert sorted(path.name for path in out.iterdir()) == ["overlay.mp4", "track.json"]
    overlay = read_video(out / "overlay.mp4")
    assert overlay.frames.shape == (30, 120, 160, 3)  # the video's own size, not the tracked
    record = json.loads((out / "track.json").read_text())
    assert record["size"] == [160, 120] and record["tracked_size"] == [80, 60]
    assert record["particles"] == 64 and record["num_bins"] == 16
    assert record["timings"]["compile_seconds"] > 0 and record["timings"]["smooth_seconds"] > 0
    assert record["estimate"].startswith("smoothed")
    assert len(record["frames"]) == 30
    low, high = markers.min(axis=1) - 12, markers.max(axis=1) + 12  # the walker, in video px
    for t, frame in enumerate(record["frames"]):
        assert frame["frame"] == t and frame["status"] == "ok"
        assert 1.0 - 1e-3 <= frame["ess"] <= 64.0 + 1e-3
        for kind in ("instantaneous", "filtered", "smoothed"):
            assert frame["posture"][kind] in POSTURE_NAMES
            parts = np.array(list(frame["parts"][kind].values()))
            assert parts.shape == (5, 2) and np.all(np.isfinite(parts))
            # projected into the silhouette: on the walker, not in the 80x60 tracking frame
            assert np.all((parts >= low[t]) & (parts <= high[t])), (t, kind, parts)
        for kind in ("filtered", "smoothed"):
            assert 0.0 < frame["posture_probability"][kind] <= 1.0
    assert max(np.array(list(frame["parts"]["smoothed"].values()))[:, 0].max()
               for frame in record["frames"]) > 80


def test_track_takes_the_silhouettes_from_masks_the_user_brings(bundled, walk, tmp_path,
                                                                 capsys):
    from jaxtrack.vision import write_masks

    video, _, silhouettes = walk
    masks = silhouettes.copy()
    masks[10:15] = False  # a segmenter that missed the person in five frames
    path = write_masks(tmp_path / "masks.npz", masks)
    out = tmp_path / "out"
    code, stdout, error = run(capsys, "track", "--method", "mixed-state", "--model", bundled,
                              "--video", video, "--masks", path, "--out", out, "--particles",
                              64, "--max-size", 80, "--seed", 3)
    assert code == 0, error
    assert "tracked 30 frames (25 with a silhouette)" in stdout
    record = json.loads((out / "track.json").read_text())
    assert record["silhouettes"] == f"masks {path}"
    statuses = [frame["status"] for frame in record["frames"]]
    assert statuses == ["ok"] * 10 + ["no person"] * 5 + ["ok"] * 15
    silhouettes = [frame["silhouette"] for frame in record["frames"]]
    assert silhouettes == ["ok"] * 10 + ["empty silhouette"] * 5 + ["ok"] * 15
    assert record["method"] == "mixed-state" and record["options"]["seed"] == 3
    assert record["status_counts"] == {"ok": 25, "degenerate": 0, "no person": 5, "lost": 0}
    # masks for fewer frames than the video: refused in one line, nothing written
    write_masks(tmp_path / "short.npz", masks[:12])
    code, _, error = run(capsys, "track", "--method", "mixed-state", "--model", bundled,
                         "--video", video, "--masks", tmp_path / "short.npz", "--out",
                         tmp_path / "short", "--max-size", 80)
    assert code == 2 and error.count("\n") == 1
    assert (f"--masks {tmp_path}/short.npz: holds 12 masks, but video frame 29 is tracked"
            in error)
    assert not (tmp_path / "short").exists()


def test_track_takes_a_detectors_keypoints_as_part_hypotheses(bundled, walk, tmp_path, capsys):
    from jaxtrack.body.markers import HUMANEVA_15
    from jaxtrack.vision.detections import Detections, write_detections

    video, markers, _ = walk
    names = ("head", "right_wrist", "left_wrist", "right_ankle", "left_ankle")
    points = markers[:, [HUMANEVA_15.index(name) for name in names]]
    confidence = np.full(points.shape[:2], 0.9)
    confidence[5:8, 1] = 0.2  # the right wrist unsure for three frames: the silhouette's there
    path = write_detections(tmp_path / "detections.npz", Detections(
        points[:, None], confidence[:, None], np.ones(len(points), int), names, "markers",
        SIZE, np.arange(len(points))))
    out = tmp_path / "out"
    code, stdout, error = run(capsys, "track", "--method", "mixed-state", "--model", bundled,
                              "--video", video, "--keypoints", path, "--out", out,
                              "--particles", 64, "--max-size", 80, "--seed", 3)
    assert code == 0, error
    assert "tracked 30 frames (30 with a silhouette)" in stdout
    record = json.loads((out / "track.json").read_text())
    assert record["detections"]["markers"] == list(names)
    assert record["detections"]["file"] == str(path)
    # the instantaneous hands are the confident wrists, in each posture's own slots
    for t, frame in enumerate(record["frames"]):
        hands = np.array([frame["parts"]["instantaneous"][name] for name in ("hand_1",
                                                                           "hand_2")])
        truth = points[t, 1:3]
        error = np.minimum(np.abs(hands - truth).sum(), np.abs(hands[::-1] - truth).sum())
        if t not in (5, 6, 7):
            assert error < 2.0, (t, hands, truth)
    # the smoothed parts on the walker (the silhouette and the keypoints hold them there)
    low, high = markers.min(axis=1) - 12, markers.max(axis=1) + 12
    for t, frame in enumerate(record["frames"]):
        parts = np.array(list(frame["parts"]["smoothed"].values()))
        assert np.all((parts >= low[t]) & (parts <= high[t])), (t, parts)


@pytest.mark.slow  # trains a posture model, renders and tracks the test clips
def test_evaluate_prints_table_1_and_writes_json_and_plots(trained, tmp_path, capsys):
    folder = tmp_path / "evaluation"
    folder.mkdir()
    shutil.copy(trained, folder / "posture_cache.npz")  # the same settings: reused
    code, out, error = run(capsys, "evaluate", "--method", "mixed-state", "--test",
                           "cmu_posture_bvh/75_20", "--max-frames", 12, "--train-max-frames",
                           45, "--size", "160x120", "--azimuths", 90, -90, "--cameras", 2,
                           "--backgrounds", "plain", "--particles", 32, "--lag", 3, "--json",
                           folder / "metrics.json", "--plots", tmp_path / "plots")
    assert code == 0, error
    assert "reused" in out.splitlines()[0]
    rows = [line for line in out.splitlines() if line.startswith("| ")]
    assert [row.split(" | ")[0] for row in rows] == [
        "| estimate", "| instantaneous (extended Ghost)", "| filtered",
        "| smoothed (whole sequence)", "| fixed-lag (3 frames)"]
    record = json.loads((folder / "metrics.json").read_text())
    assert record["train"][0] == "cmu_posture_bvh/75_19"
    assert record["test"] == ["cmu_posture_bvh/75_20"] and record["lag"] == 3
    # two azimuths and the real Pose2Sim camera 3 (its portrait frame at a third)
    assert len(record["sequences"]) == 3 and record["pose2sim_cameras"] == [2]
    assert sorted(name.split("_")[2] for name in record["sequences"]) == [
        "az-90", "az90", "cam03"]
    for kind in ESTIMATES:
        score = record["overall"][kind]
        assert score["frames"] == 36
        assert set(score["mse"]) == {"head", "hands", "feet", "all"}
        assert all(value >= 0 and math.isfinite(value) for value in score["mse"].values())
        assert 0 <= score["posture_error"] <= 1 and score["max_head_error"] >= 0
        assert set(score["within"]["head"]) == {"10", "20", "30", "50"}
    assert np.sum(record["smoothed_confusion"]) == 36
    assert sorted(path.name for path in (tmp_path / "plots").iterdir()) == [
        "fraction_within.png", "posture_confusion.png"]
    assert sorted(path.name for path in folder.iterdir()) == ["metrics.json",
                                                              "posture_cache.npz"]


def _gplvm_file(path):
    from jaxtrack.priors.gplvm import GPLVM, save_gplvm
    from jaxtrack.priors.gplvm._kernel import KernelParameters

    latents = np.linspace(-1, 1, 8)[:, None] * [1.0, 0.5]
    model = GPLVM.from_active_set(KernelParameters.create(1.0, 100.0, 1.0), np.sin(latents),
                                  np.zeros(2), latents, np.arange(4))
    return save_gplvm(path, model)


@pytest.mark.parametrize("case, message", [
    ("gplvm", "--model {tmp}/gplvm.npz: a GPLVM pose prior (for --method latent), not a posture "
              "model; --method mixed-state needs a posture model from jaxtrack train --method "
              "mixed-state"),
    ("plain npz", "--model {tmp}/plain.npz: not a jaxtrack posture-model file (no metadata)"),
    ("two videos", "--video: --method mixed-state tracks one video, got 2"),
    ("missing video", "--video {tmp}/missing.mp4: no such video file"),
    ("not a video", "--video: {tmp}/v.mp4: OpenCV cannot open it as a video"),
    ("manual init", "--init does not apply to --method mixed-state"),
    ("no particles", "--particles must be at least 1, got 0"),
    ("out is a file", "--out {tmp}/v.mp4 is a file; give a folder"),
    ("two masks", "--masks: one file per --video, got 2 for 1"),
    ("not masks", "--masks {tmp}/v.mp4: not a .npz or .npy file"),
    ("keypoints", "--keypoints: {tmp}/v.mp4: not a detections file"),
    ("person", "--person: it picks the person in --keypoints; give --keypoints FILE_OR_FOLDER"),
    ("detector", "--detector does not apply to --method mixed-state"),
])
def test_track_refuses_bad_input_in_one_line(tmp_path, capsys, posture_file, case, message):
    (tmp_path / "v.mp4").write_text("not a video")
    model, videos, extra, out = posture_file, [tmp_path / "v.mp4"], [], tmp_path / "out"
    if case == "gplvm":
        model = _gplvm_file(tmp_path / "gplvm.npz")
    elif case == "plain npz":
        model = tmp_path / "plain.npz"
        np.savez(model, means=np.zeros(3))
    elif case == "two videos":
        videos = videos * 2
    elif case == "missing video":
        videos = [tmp_path / "missing.mp4"]
    elif case == "manual init":
        extra = ["--init", "manual:" + ",".join(["1"] * 24)]
    elif case == "no particles":
        extra = ["--particles", "0"]
    elif case == "out is a file":
        out = tmp_path / "v.mp4"
    elif case == "two masks":
        extra = ["--masks", tmp_path / "v.mp4", tmp_path / "v.mp4"]
    elif case == "not masks":
        extra = ["--masks", tmp_path / "v.mp4"]
    elif case == "keypoints":
        extra = ["--keypoints", tmp_path / "v.mp4"]
    elif case == "person":
        extra = ["--person", "1,1,5,5"]
    elif case == "detector":
        extra = ["--detector", "mediapipe"]
    before = sorted(tmp_path.iterdir())
    code, _, error = run(capsys, "track", "--method", "mixed-state", "--model", model,
                         "--video", *videos, "--out", out, *extra)
    assert code == 2 and error.count("\n") == 1
    assert message.format(tmp=tmp_path) in error
    assert "Traceback" not in error
    assert sorted(tmp_path.iterdir()) == before


@pytest.mark.parametrize("arguments, message", [
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/model.txt"],
     "--out {tmp}/model.txt: must be a .npz path"),
    (["train", "--clips", "cmu_bvh/131_01", "--out", "{tmp}/m.npz"],
     "--clips cmu_bvh/131_01: subject cmu:131 is a test subject (jaxtrack.data.splits)"),
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/m.npz", "--size", "10x10"],
     "--size must be WIDTHxHEIGHT with each side from 32 to 4096 pixels, got '10x10'"),
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/m.npz", "--azimuths", "nan"],
     "--azimuths must be between -180 and 180 degrees, got nan"),
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/m.npz", "--max-frames", "1"],
     "--max-frames must be at least 2, got 1"),
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/m.npz", "--views", "3"],
     "--views does not apply to --method mixed-state (use --azimuths)"),
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/m.npz", "--cameras", "1"],
     "--cameras does not apply to --method mixed-state"),
    (["evaluate", "--test", "cmu_amc/07_02", "--json", "{tmp}/out.json", "--cameras", "4"],
     "--cameras must be Pose2Sim camera indices 0-3, got 4"),
    (["evaluate", "--train", "cmu_amc/07_01", "--test", "cmu_amc/07_01", "--json",
      "{tmp}/out.json"], "--test clips must be held out, but cmu_amc/07_01 is also in --train"),
    (["evaluate", "--train", "cmu_bvh/131_01", "--test", "cmu_amc/07_01", "--json",
      "{tmp}/out.json"], "--train cmu_bvh/131_01: subject cmu:131 is a test subject"),
    (["evaluate", "--train", "cmu_amc/07_01", "--test", "cmu_amc/07_02", "--json",
      "{tmp}/out.json", "--lag", "-1"], "--lag must be at least 0, got -1"),
    (["evaluate", "--train", "cmu_amc/07_01", "--test", "cmu_amc/07_02", "--json",
      "{tmp}/out.txt"], "--json {tmp}/out.txt: must be a .json path"),
])
def test_train_and_evaluate_refuse_bad_input_in_one_line(tmp_path, capsys, arguments, message):
    arguments = [arguments[0], "--method", "mixed-state", *arguments[1:]]
    code, _, error = run(capsys, *(argument.format(tmp=tmp_path) for argument in arguments))
    assert code == 2 and error.count("\n") == 1
    assert message.format(tmp=tmp_path) in error
    assert list(tmp_path.iterdir()) == []


def test_evaluate_names_a_damaged_cache_and_leaves_it(tmp_path, capsys):
    cache = tmp_path / "posture_cache.npz"
    cache.write_bytes(b"PK\x03\x04 cut short")
    code, _, error = run(capsys, "evaluate", "--method", "mixed-state", "--train",
                         "cmu_amc/07_01", "--test", "cmu_amc/07_02", "--json",
                         tmp_path / "out.json")
    assert code == 2 and error.count("\n") == 1
    assert (f"the posture model cached beside --json: {cache} is damaged or not a posture model "
            f"(damaged or truncated posture-model file") in error
    assert "delete it (it is retrained and rewritten) or write --json elsewhere" in error
    assert list(tmp_path.iterdir()) == [cache]
    assert cache.read_bytes() == b"PK\x03\x04 cut short"
