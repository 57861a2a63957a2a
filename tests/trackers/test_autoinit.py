"""Automatic initialisation: foreground, head boxes, the pose search, and `jaxtrack track`."""

import json

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12, frontal_camera, render_motion
from jaxtrack.cli import main
from jaxtrack.data import load_clip
from jaxtrack.priors.gplvm import save_gplvm
from jaxtrack.trackers import DEFAULT_ARM_GRID, DEFAULT_REFINE_STEPS
from jaxtrack.trackers.autoinit import AutoInitError, auto_initialise, search_poses
from jaxtrack.vision import foreground_mask, head_boxes, median_background, write_frames

HELD_OUT = "animateddrawings/history_c119d6b/cmu_1006_wave_hello_2"


def _torso(markers):
    return float(np.linalg.norm(markers[1] - markers[3]))


def test_median_background_and_foreground_find_a_moving_figure():
    rng = np.random.default_rng(0)
    background = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    frames = np.repeat(background[None], 9, axis=0)
    for t in range(9):  # a dark upright "person" 20 × 60 px walking left to right
        frames[t, 40:100, 10 + 15 * t:30 + 15 * t] = 20
    estimate = median_background(frames)
    assert np.mean(estimate != background) < 0.01
    mask = foreground_mask(frames[0], estimate)
    person = np.zeros(mask.shape, bool)
    person[40:100, 10:30] = True
    assert (mask & person).sum() / person.sum() > 0.9 and (mask & ~person).sum() < 20
    (box,) = head_boxes(mask)
    centre = box[:2] + box[2:] / 2
    assert abs(centre[0] - 20) < 3 and 40 <= centre[1] < 50  # at the top of the figure
    with pytest.raises(ValueError, match="at least 3 frames"):
        median_background(frames[:2])
    with pytest.raises(ValueError, match="differ in size"):
        foreground_mask(frames[0], estimate[:60])


@pytest.fixture(scope="module")
def rendered_frame():
    motion = load_clip(HELD_OUT).resample(15.0).select(20, 21)
    rendered = render_motion(motion, frontal_camera(motion, (320, 240)), image_size=(320, 240),
                             background="photo", markers=UPPER_BODY_12, progress=False)
    return rendered.images[0], rendered.silhouettes[0], np.asarray(rendered.markers_2d[0])


def test_pose_search_recovers_the_pose_under_the_face(prior, rendered_frame):
    image, silhouette, truth = rendered_frame
    torso = _torso(truth)
    face = np.r_[truth[0] - 0.14 * torso, 0.28 * torso, 0.28 * torso]
    decoy = np.array([10.0, 10.0, 0.28 * torso, 0.28 * torso])  # a "face" on the background
    found = search_poses(prior.model, prior.template, silhouette, np.stack([decoy, face]))
    assert np.array_equal(found.face, face.astype(np.int64))
    assert found.face_scores[1] > found.face_scores[0] + 0.3
    error = np.linalg.norm(found.markers - truth, axis=-1).mean() / torso
    assert error < 0.25, error
    assert 0.75 < found.torso / torso < 1.35
    # the foreground blob's top gives the head when no face box is given
    found = auto_initialise(prior.model, prior.template, image, silhouette,
                            faces=np.zeros((0, 4)))
    assert found.source == "foreground"
    assert np.linalg.norm(found.markers - truth, axis=-1).mean() / torso < 0.4


def test_auto_initialise_reports_no_person(prior, rendered_frame):
    image, silhouette, _ = rendered_frame
    with pytest.raises(AutoInitError, match="no foreground"):
        auto_initialise(prior.model, prior.template, image, np.zeros_like(silhouette))
    with pytest.raises(AutoInitError, match="no face .* and no person-sized foreground blob"):
        speck = np.zeros_like(silhouette)
        speck[5:7, 5:7] = True
        auto_initialise(prior.model, prior.template, image, speck, faces=np.zeros((0, 4)))


@pytest.fixture(scope="module")
def model_file(prior, tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "prior.npz"
    return save_gplvm(path, prior.model, arrays={
        "reference_lengths": np.asarray(prior.template.reference_lengths),
        "reference_angles": np.asarray(prior.template.reference_angles)})


def test_track_cli_with_manual_init_writes_overlay_and_json(model_file, sequence, tmp_path,
                                                            capsys):
    video = write_frames(sequence.images[:10], tmp_path / "clip.mp4", sequence.fps, (320, 240))
    numbers = ",".join(f"{value:.2f}" for value in sequence.truth[0].ravel())
    out = tmp_path / "out"
    assert main(["track", "--model", str(model_file), "--video", str(video), "--init",
                 f"manual:{numbers}", "--out", str(out), "--particles", "50",
                 "--max-size", "160"]) == 0
    record = json.loads((out / "track.json").read_text())
    assert len(record["frames"]) == 10 and record["tracked_size"] == [160, 120]
    # the default refinement with the default likelihood, recorded as it ran
    refinement = record["tracker"]["refinement"]
    assert refinement["steps"] == DEFAULT_REFINE_STEPS
    assert refinement["arm_search"]["grid"] == DEFAULT_ARM_GRID
    assert record["tracker"]["method"] == "latent" and record["tracker"]["particles"] == 50
    markers = np.array([[frame["markers"][name] for name in UPPER_BODY_12]
                        for frame in record["frames"]])
    assert np.all(np.isfinite(markers))
    # reported in the video's own pixels (tracked at half size)
    torso = _torso(sequence.truth[0])
    errors = np.linalg.norm(markers - sequence.truth[:10], axis=-1).mean(axis=-1) / torso
    assert errors[0] < 0.25 and errors.mean() < 0.5, errors
    # the overlay at the video's own size, not the tracked one
    from jaxtrack.vision import read_video

    overlay = read_video(out / "overlay.mp4")
    assert overlay.image_size == (320, 240) and overlay.num_frames == 10
    assert record["masks"] is None
    # what ran, and every frame's status by the one enum's names
    assert record["method"] == "latent" and record["options"]["particles"] == 50
    assert record["options"]["max_size"] == 160 and "lost_rule" in record
    assert set(record["statuses"]) == {"ok", "degenerate", "no person", "lost"}
    statuses = [frame["status"] for frame in record["frames"]]
    assert set(statuses) <= set(record["statuses"]) and statuses[0] == "ok"
    assert sum(record["status_counts"].values()) == 10
    # person masks as the likelihood's foreground: read, fitted to the tracked frames, recorded
    from jaxtrack.vision import write_masks

    masks = write_masks(tmp_path / "masks.npz", np.ones((10, 240, 320), bool))
    assert main(["track", "--model", str(model_file), "--video", str(video), "--init",
                 f"manual:{numbers}", "--out", str(tmp_path / "masked"), "--particles", "50",
                 "--max-size", "160", "--masks", str(masks), "--coverage-weight", "5"]) == 0
    masked = json.loads((tmp_path / "masked" / "track.json").read_text())
    assert masked["masks_file"] == str(masks) and len(masked["frames"]) == 10
    assert masked["tracker"]["likelihood"]["coverage_weight"] == 5.0
    assert main(["track", "--model", str(model_file), "--video", str(video), "--init",
                 f"manual:{numbers}", "--out", str(tmp_path / "bad"), "--likelihood", "limbs",
                 "--masks", str(masks)]) == 2
    assert "--masks: the 'limbs' likelihood has no foreground term" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    # a detector's keypoints (here the truth, in the video's pixels): read, scaled to the
    # tracked frames, scored by the keypoint term and the first frame's as the initial pose
    from jaxtrack.vision.keypoints import write_keypoints

    keypoints = write_keypoints(tmp_path / "keypoints.npz", sequence.truth[:10])
    assert main(["track", "--model", str(model_file), "--video", str(video), "--init",
                 "keypoints", "--out", str(tmp_path / "keyed"), "--particles", "50",
                 "--max-size", "160", "--keypoints", str(keypoints)]) == 0
    keyed = json.loads((tmp_path / "keyed" / "track.json").read_text())
    assert keyed["keypoints_file"] == str(keypoints) and keyed["init"]["method"] == "keypoints"
    assert keyed["tracker"]["likelihood"]["keypoint_weight"] == 1.5
    keyed_markers = np.array([[frame["markers"][name] for name in UPPER_BODY_12]
                              for frame in keyed["frames"]])
    initial = np.array([keyed["init"]["markers"][name] for name in UPPER_BODY_12])
    np.testing.assert_allclose(initial, sequence.truth[0], atol=0.05)
    keyed_errors = np.linalg.norm(keyed_markers - sequence.truth[:10], axis=-1).mean(-1) / torso
    assert keyed_errors.mean() < 0.1, keyed_errors
    short = write_keypoints(tmp_path / "short.npz", sequence.truth[:4])
    assert main(["track", "--model", str(model_file), "--video", str(video), "--init",
                 "keypoints", "--out", str(tmp_path / "bad"), "--keypoints", str(short),
                 "--max-size", "160"]) == 2
    assert "short.npz holds 4 frames; the video frames tracked run to frame 9" in (
        capsys.readouterr().err)
    unsure = np.ones((10, 12))
    unsure[0, 6] = 0.0
    gap = write_keypoints(tmp_path / "gap.npz", sequence.truth[:10], unsure)
    assert main(["track", "--model", str(model_file), "--video", str(video), "--init",
                 "keypoints", "--out", str(tmp_path / "bad"), "--keypoints", str(gap),
                 "--max-size", "160"]) == 2
    assert "--init keypoints: " in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def model_file_prior(path):
    from jaxtrack.priors.gplvm import load_gplvm

    return load_gplvm(path).model


def test_track_cli_bad_input_is_a_clear_error(model_file, sequence, tmp_path, capsys):
    def run(*arguments):
        code = main(["track", *arguments])
        return code, capsys.readouterr().err

    still = write_frames([sequence.images[0] * 0 + 90] * 5, tmp_path / "empty.mp4", 15.0,
                         (320, 240))
    out = tmp_path / "out"
    code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out))
    assert code == 2 and "--init face found nobody on" in error and str(still) in error
    # the message names what to give instead, with the markers' order
    assert ("give the first frame's pose instead: --init manual:x,y,... (24 numbers, x and y of "
            "head, neck, thorax, pelvis, right_shoulder") in error
    assert "or --init keypoints --keypoints FILE" in error and error.count("\n") == 1
    assert not out.exists()  # nothing written
    code, error = run("--model", str(model_file), "--video", str(tmp_path / "none.mp4"),
                      "--out", str(out))
    assert code == 2 and "none.mp4" in error
    code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                      "--refine-steps", "-1")
    assert code == 2 and "--refine-steps must be at least 0, got -1" in error
    code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                      "--arm-grid", "2")
    assert code == 2 and "--arm-grid must be an odd positive integer" in error
    assert error.strip().endswith("got 2")
    code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                      "--arm-momentum", "-0.5")
    assert code == 2 and "--arm-momentum must be between 0 and 1, got -0.5" in error
    corrupt = tmp_path / "corrupt.mp4"
    corrupt.write_bytes(b"not a video" * 100)
    code, error = run("--model", str(model_file), "--video", str(corrupt), "--out", str(out))
    assert code == 2 and "corrupt.mp4" in error
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, x=np.zeros(3))
    code, error = run("--model", str(wrong), "--video", str(still), "--out", str(out))
    assert code == 2 and "wrong.npz" in error
    bare = save_gplvm(tmp_path / "bare.npz", model_file_prior(model_file))
    code, error = run("--model", str(bare), "--video", str(still), "--out", str(out))
    assert code == 2 and "not a tracking prior" in error
    code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                      "--init", "manual:1,2,3")
    assert code == 2 and "24" in error
    code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                      "--coverage-weight", "5")
    assert code == 2 and "--coverage-weight: the coverage term reads the person's masks" in error
    for arguments, message in (
            (("--keypoint-weight", "2"), "--keypoint-weight: it reads a detector's keypoints"),
            (("--init", "keypoints"), "--init keypoints: it reads a detector's keypoints"),
            (("--keypoints", str(tmp_path / "none.npz")),
             "--keypoints: " + str(tmp_path / "none.npz") + ": no such file or folder")):
        code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                          *arguments)
        assert code == 2 and message in error, error
    for option, value in (("--calibration", "calib.txt"), ("--view-selection", "paper"),
                          ("--skeleton", "best"),
                          ("--skin", "200,150,120"), ("--cameras", "0"), ("--iterations", "5")):
        code, error = run("--model", str(model_file), "--video", str(still), "--out", str(out),
                          option, value)
        assert code == 2 and error.strip() == (f"jaxtrack track: error: {option} does not "
                                               f"apply to --method latent (it is a "
                                               f"linear-combination setting)")
    assert not out.exists()


def _drawn_person(markers, shape, torso):
    """A person mask: the body drawn as thick segments between the true markers."""
    import cv2

    from jaxtrack.body import MARKER_EDGES

    mask = np.zeros(shape, np.uint8)
    torso_corners = [UPPER_BODY_12.index(name) for name in ("right_shoulder", "left_shoulder",
                                                              "left_hip", "right_hip")]
    cv2.fillPoly(mask, [np.round(markers[torso_corners]).astype(np.int32)], 1)
    for a, b in MARKER_EDGES[UPPER_BODY_12]:
        cv2.line(mask, tuple(int(v) for v in markers[a]), tuple(int(v) for v in markers[b]), 1,
                 max(2, int(0.25 * torso)))
    cv2.circle(mask, tuple(int(v) for v in markers[0]), max(2, int(0.2 * torso)), 1, -1)
    return mask.astype(bool)


def test_track_cli_initialises_from_the_first_frames_mask(model_file, sequence, tmp_path,
                                                          capsys):
    from jaxtrack.vision import write_masks

    frames = sequence.images[:6]
    video = write_frames(frames, tmp_path / "clip.mp4", sequence.fps, (320, 240))
    torso = _torso(sequence.truth[0])
    masks = np.stack([_drawn_person(markers, frames.shape[1:3], torso)
                      for markers in sequence.truth[:6]])
    path = write_masks(tmp_path / "masks.npz", masks)
    out = tmp_path / "out"
    assert main(["track", "--model", str(model_file), "--video", str(video), "--out", str(out),
                 "--particles", "20", "--refine-steps", "0", "--masks", str(path)]) == 0
    assert "against the masks" in capsys.readouterr().out
    record = json.loads((out / "track.json").read_text())
    assert record["init"]["method"] == "face" and record["init"]["foreground"] == "masks"
    first = np.array([record["frames"][0]["markers"][name] for name in UPPER_BODY_12])
    assert np.linalg.norm(first - sequence.truth[0], axis=-1).mean() / torso < 0.4
    # a first mask without the person is refused before anything is written
    masks[0] = False
    empty = write_masks(tmp_path / "empty.npz", masks)
    assert main(["track", "--model", str(model_file), "--video", str(video), "--out",
                 str(tmp_path / "bad"), "--masks", str(empty)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "the first frame's mask in" in error[0] and "empty" in error[0]
    assert not (tmp_path / "bad").exists()


def _small_person(image, x, y, height, colour):
    """A standing person-shaped figure ``height`` pixels tall, its head's top at (x, y)."""
    import cv2

    def point(dx, dy):
        return int(x + dx * height), int(y + dy * height)

    cv2.circle(image, point(0, 0.065), int(0.065 * height), colour, -1)
    cv2.rectangle(image, point(-0.11, 0.13), point(0.11, 0.52), colour, -1)
    for side in (-1, 1):
        cv2.line(image, point(0.11 * side, 0.16), point(0.16 * side, 0.5), colour,
                 max(2, int(0.05 * height)))
        cv2.line(image, point(0.05 * side, 0.52), point(0.07 * side, 1.0), colour,
                 max(2, int(0.06 * height)))


def test_auto_initialise_finds_people_80_pixels_tall_in_a_large_frame(prior):
    """A vtest.avi-like scene: two people about 80 px tall walking over a static 768x576
    background. Their blobs (1 500-2 500 px) are below 0.5 % of the frame, the least blob
    head_boxes takes by default; autoinit asks for blobs from MIN_PERSON_PIXELS instead."""
    import cv2

    from jaxtrack.trackers.autoinit import MIN_PERSON_PIXELS

    rng = np.random.default_rng(0)
    background = cv2.GaussianBlur(rng.integers(60, 200, (576, 768, 3), dtype=np.uint8),
                                  (0, 0), 3)
    frames = np.repeat(background[None], 5, axis=0)
    for t in range(5):
        _small_person(frames[t], 150 + 12 * t, 300, 80, (30, 40, 50))
        _small_person(frames[t], 500 - 10 * t, 200, 84, (220, 210, 200))
    foreground = foreground_mask(frames[0], median_background(frames))
    assert MIN_PERSON_PIXELS < foreground.sum() / 2 < 0.005 * foreground.size
    assert len(head_boxes(foreground)) == 0  # the default least blob misses both
    found = auto_initialise(prior.model, prior.template, frames[0], foreground,
                            faces=np.zeros((0, 4)), max_latents=150)
    assert found.source == "foreground" and found.score > 0.6
    head, pelvis = found.markers[UPPER_BODY_12.index("head")], found.markers[3]
    # on one of the two people: the head at its head, the pelvis at its hips
    assert (np.linalg.norm(head - [150, 305]) < 6 or np.linalg.norm(head - [500, 205]) < 6), head
    assert 20 < np.linalg.norm(pelvis - head) < 50
