"""Renderer: ground truth agrees with the drawn pixels, on real clips from two rigs."""

import dataclasses
import subprocess
import sys
from functools import cache

import cv2
import numpy as np
import pytest

from jaxtrack.body import HUMANEVA_15, UPPER_BODY_12, look_at, project_with_depth, read_qca
from jaxtrack.body._backgrounds import photo_background
from jaxtrack.body._staging import project_numpy
from jaxtrack.body.render import (
    Lighting,
    fit_camera,
    frontal_camera,
    random_camera,
    render_motion,
    stage_for_cameras,
)
from jaxtrack.data import load_clip, path

SIZE = (320, 240)
WAVE = "animateddrawings/fair1_wave_hello"  # AnimatedDrawings rig, a child waving
WALK = "cmu_amc/07_01"  # CMU ASF/AMC rig, an adult walking
NAME = {name: i for i, name in enumerate(HUMANEVA_15)}


@cache
def clip(name: str, fps: float = 10.0):
    return load_clip(name).resample(fps)


@cache
def rendered(name: str, camera: str = "frontal", seed: int = 0, **options):
    motion = clip(name)
    view = frontal_camera(motion, SIZE) if camera == "frontal" else random_camera(1, motion, SIZE)
    return render_motion(motion, view, seed=seed, progress=False, **options)


def near_silhouette(sequence, radius: int = 2) -> np.ndarray:
    """For each marker, whether the silhouette lies within `radius` pixels: `(time, markers)`."""
    kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    result = np.zeros(sequence.visibility.shape, bool)
    for t, silhouette in enumerate(sequence.silhouettes):
        grown = cv2.dilate(silhouette.astype(np.uint8), kernel) > 0
        u, v = np.round(sequence.markers_2d[t]).astype(int).T
        inside = (u >= 0) & (u < grown.shape[1]) & (v >= 0) & (v < grown.shape[0])
        result[t, inside] = grown[v[inside], u[inside]]
    return result


@pytest.mark.parametrize("name", [WAVE, WALK])
@pytest.mark.parametrize("camera", ["frontal", "random"])
def test_visible_markers_lie_on_the_silhouette(name, camera):
    sequence = rendered(name, camera, occluders=2)
    assert sequence.visibility.mean() > 0.6  # most markers are seen, so the check means something
    assert near_silhouette(sequence)[sequence.visibility].all()
    assert sequence.silhouettes.any(axis=(1, 2)).all()


def test_silhouette_follows_the_pose_over_a_real_clip():
    sequence = rendered(WAVE)
    wrists = sequence.joints_3d[:, [NAME["right_wrist"], NAME["left_wrist"]]]
    span = np.linalg.norm(wrists[:, 0] - wrists[:, 1], axis=-1)
    widths, box_areas, areas = [], [], []
    for t in (int(np.argmax(span)), int(np.argmin(span))):  # arms spread vs arms by the sides
        columns = np.flatnonzero(sequence.silhouettes[t].any(axis=0))
        rows = np.flatnonzero(sequence.silhouettes[t].any(axis=1))
        widths.append(columns[-1] - columns[0])
        box_areas.append(widths[-1] * (rows[-1] - rows[0]))
        areas.append(sequence.silhouettes[t].sum())
    assert span.max() > 1.5 * span.min()
    assert widths[0] > 1.5 * widths[1] and box_areas[0] > 1.4 * box_areas[1]
    assert areas[0] > 1.05 * areas[1]  # the arms no longer overlap the torso


@pytest.mark.parametrize("name", [WAVE, WALK])
def test_frontal_camera_shows_the_subjects_left_on_the_viewers_right(name):
    markers = rendered(name).markers_2d
    for part in ("shoulder", "hip"):
        assert (markers[:, NAME[f"left_{part}"], 0] > markers[:, NAME[f"right_{part}"], 0]).all()
    wrists = markers[:, NAME["left_wrist"], 0] > markers[:, NAME["right_wrist"], 0]
    assert wrists.mean() > 0.9


def test_far_side_is_hidden_in_a_side_view():
    motion = clip(WALK)
    joints = rendered(WALK).joints_3d
    centre = joints.reshape(-1, 3).mean(axis=0)
    left = (joints[:, NAME["left_hip"]] - joints[:, NAME["right_hip"]]).mean(axis=0)
    left[1] = 0.0
    eye = centre - 8.0 * left / np.linalg.norm(left)  # on the subject's right
    camera = look_at(eye, centre, np.array([0.0, 1.0, 0.0]), 300.0, SIZE)
    visible = render_motion(motion, camera, progress=False).visibility.mean(axis=0)
    # the near hip is sometimes behind the swinging arm; the far side is behind the body
    assert visible[NAME["right_shoulder"]] > 0.9 and visible[NAME["left_shoulder"]] < 0.3
    assert visible[NAME["right_hip"]] > 0.75 and visible[NAME["left_hip"]] < 0.3


def test_same_seed_same_bytes_other_seed_other_figure():
    first = rendered(WAVE, seed=3, background="clutter", noise_std=4.0, occluders=1)
    again = render_motion(clip(WAVE), frontal_camera(clip(WAVE), SIZE), seed=3, progress=False,
                          background="clutter", noise_std=4.0, occluders=1)
    assert first.images.tobytes() == again.images.tobytes()
    assert np.array_equal(first.silhouettes, again.silhouettes)
    assert np.array_equal(first.visibility, again.visibility)
    other = rendered(WAVE, seed=4, background="clutter", noise_std=4.0, occluders=1)
    assert np.abs(first.images.astype(int) - other.images).mean() > 10
    assert np.array_equal(first.markers_2d, other.markers_2d)  # same motion, same camera


def ncc(first: np.ndarray, second: np.ndarray) -> float:
    first, second = first - first.mean(), second - second.mean()
    return float((first * second).sum() / np.sqrt((first * first).sum() * (second * second).sum()))


def test_clothing_texture_moves_with_the_body():
    # the same pose twice, the second moved 5 pixels to the right: the fabric must come along,
    # or a template tracker locks onto the pattern left behind on the screen
    motion = clip(WAVE).select(0, 1)
    camera = frontal_camera(motion, SIZE)
    rotation, translation = np.asarray(camera.rotation), np.asarray(camera.translation)
    depth = (motion.positions[0] @ rotation.T + translation)[:, 2].mean()
    shift = rotation[0] * 5.0 * depth / float(camera.focal_length[0])
    moved = dataclasses.replace(motion, positions=np.concatenate(
        [motion.positions, motion.positions + shift]))
    sequence = render_motion(moved, camera, background="photo", progress=False)
    grey = sequence.images.astype(float).mean(axis=-1)

    def patch(t, centre, half=4):
        u, v = np.round(centre).astype(int)
        return grey[t, v - half:v + half + 1, u - half:u + half + 1]

    for joint in ("pelvis", "right_hip", "left_hip"):  # on the trousers, inside the silhouette
        before, after = sequence.markers_2d[:, NAME[joint]]
        np.testing.assert_allclose(after - before, (5.0, 0.0), atol=0.1)
        template = patch(0, before)
        following, staying = ncc(template, patch(1, after)), ncc(template, patch(1, before))
        assert following > 0.95, (joint, following, staying)
        assert staying < following - 0.15, (joint, following, staying)


def test_photo_background_comes_from_the_bundled_jpeg():
    sequence = rendered(WAVE, background="photo")
    jpeg = path("pose2sim/background_cam01.jpg")  # found through the data catalogue
    photo = cv2.cvtColor(cv2.imread(str(jpeg)), cv2.COLOR_BGR2RGB)
    assert photo.shape == (480, 640, 3) and np.array_equal(photo, photo_background())
    expected = cv2.resize(photo, SIZE, interpolation=cv2.INTER_AREA)
    grown = cv2.dilate(sequence.silhouettes[0].astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    assert np.array_equal(sequence.images[0][~grown], expected[~grown])
    assert not np.array_equal(sequence.images[0][grown], expected[grown])  # the figure is there


def test_occluders_hide_markers_and_silhouette_pixels():
    plain = rendered(WALK)
    occluded = rendered(WALK, occluders=3)
    assert occluded.visibility.sum() < plain.visibility.sum() - 10
    assert occluded.silhouettes.sum() < 0.95 * plain.silhouettes.sum()
    assert not (occluded.silhouettes & ~plain.silhouettes).any()
    assert np.array_equal(occluded.markers_2d, plain.markers_2d)


def test_image_effects_leave_ground_truth_alone():
    plain = rendered(WAVE)
    effects = rendered(WAVE, noise_std=8.0, blur=1.5, lighting=Lighting(40.0, 0.3, 2.0))
    assert np.array_equal(plain.silhouettes, effects.silhouettes)
    assert np.array_equal(plain.visibility, effects.visibility)
    brightness = effects.images.mean(axis=(1, 2, 3)) - plain.images.mean(axis=(1, 2, 3))
    assert np.ptp(brightness) > 20  # lighting varies over time
    residual = effects.images.astype(float) - cv2.GaussianBlur(effects.images[0], (0, 0), 3)
    assert residual[0].std() > 5  # noise is there


def test_upper_body_markers_and_unknown_markers():
    motion = clip(WAVE).select(0, 3)
    camera = frontal_camera(motion, SIZE)
    sequence = render_motion(motion, camera, markers=UPPER_BODY_12, progress=False)
    assert sequence.marker_names == UPPER_BODY_12 and sequence.markers_2d.shape == (3, 12, 2)
    with pytest.raises(ValueError, match="not drawn"):
        render_motion(motion, camera, markers=("head", "nose"), progress=False)


def test_calibrated_camera_sees_the_staged_subject_and_projection_matches_jax():
    cameras = read_qca(path("pose2sim/Calib.qca.txt"), world_up="y")
    motion = stage_for_cameras(clip(WAVE).select(0, 5), cameras)
    camera = fit_camera(cameras[0], SIZE)
    assert camera.image_size == (136, 240)  # portrait 1088x1920 scaled by 1/8, aspect kept
    sequence = render_motion(motion, camera, progress=False)
    assert sequence.visibility.mean() > 0.6
    points = sequence.joints_3d
    expected_pixels, expected_depth = project_with_depth(cameras[0], points)
    pixels, depth = project_numpy(cameras[0], points)
    np.testing.assert_allclose(pixels, expected_pixels, atol=1e-6)
    np.testing.assert_allclose(depth, expected_depth, atol=1e-9)
    np.testing.assert_allclose((sequence.markers_2d + 0.5) * 8, expected_pixels + 0.5, atol=1e-6)


def test_renderer_modules_import_without_opencv():
    code = ("import sys; sys.modules['cv2'] = None; import jaxtrack, jaxtrack.body.render, "
            "jaxtrack.body.sequence; print('ok')")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.stdout.strip() == "ok", result.stderr


def test_an_image_array_is_fitted_as_the_background():
    motion = clip(WAVE).select(0, 2)
    backdrop = np.zeros((60, 200, 3), np.uint8)
    backdrop[:, 40:160] = (10, 200, 30)  # the centred 4:3 crop is all green
    sequence = render_motion(motion, frontal_camera(motion, (80, 60)), background=backdrop,
                             progress=False)
    outside = ~sequence.silhouettes[0]
    assert (sequence.images[0][outside] == (10, 200, 30)).all()
    with pytest.raises(ValueError, match="uint8"):
        render_motion(motion, frontal_camera(motion, (80, 60)), background=backdrop * 1.0)
