"""Motion readers on every real clip: rigid bones, documented joint counts and rates, metres, Y up,
left/right, and forward kinematics against an independent SciPy reference."""

import functools
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxtrack.body._asf import parse_amc, parse_asf
from jaxtrack.body._bvh import parse_hierarchy
from jaxtrack.body.markers import marker_positions
from jaxtrack.body.motion import Motion, load_motion
from jaxtrack.data import bundled_folder, clip_files, shared_folder

TESTS_DATA = Path(__file__).parents[1] / "data"
BUNDLED = clip_files(bundled_folder())
TEST_ONLY = clip_files(TESTS_DATA)  # the non-commercial Bandai clips, never in the wheel
SHARED_FOLDER = shared_folder()
SHARED = clip_files(SHARED_FOLDER) if SHARED_FOLDER is not None else {}


def _clip_params():
    params = [pytest.param(file, id=f"bundled:{name}") for name, file in BUNDLED.items()]
    params += [pytest.param(file, id=f"tests:{name}") for name, file in TEST_ONLY.items()]
    if SHARED:
        params += [pytest.param(file, id=f"shared:{name}") for name, file in SHARED.items()]
    else:
        params.append(pytest.param(None, id="shared:absent"))
    return params


ALL_CLIPS = _clip_params()


@functools.cache
def load(file: Path) -> Motion:
    return load_motion(file)


def clip(file: Path | None) -> Motion:
    if file is None:
        pytest.skip("the shared/data collection is not beside this checkout")
    return load(file)


def documented(stem: str) -> tuple[int, float, int | None]:
    """(joints, fps, frames or None) as written in the folders' SOURCE.txt files."""
    frames = {"fair1_wave_hello": 839, "fair1_dab": 339, "fair1_jumping": 654, "fair1_zombie": 779,
              "cmu1_jumping_jacks": 125, "cmu_1006_wave_hello_1": 581,
              "cmu_1006_wave_hello_2": 551, "8yr_old_wave_hello": 964, "cmu_new_walk_point": 933,
              "cmu_new_walk_clap": 1074, "cmu_new_walk_raise_the_roof": 1237,
              "cmu_new_walk_side_punch": 943, "131_01": 994, "131_02": 1247, "131_03": 1102,
              "02_01": 343}.get(stem)
    if stem.startswith("dataset-2_"):
        return 22, 30.0, frames  # 21 body joints + the joint_Root ground projection
    if stem.startswith(("13", "cmu1_")):  # CMU BVH dialect, 31 joints
        return 31, 30.0 if stem.startswith("cmu1_") else 120.0, frames
    if stem[:2].isdigit():  # CMU ASF/AMC: root + 30 bones
        return 31, 120.0, frames
    return 27, 30.0 if stem in ("fair1_dab", "fair1_zombie") else 119.88, frames


def _bone_lengths(motion: Motion) -> np.ndarray:
    parents, children = np.array(motion.bones).T
    return np.linalg.norm(motion.positions[:, children] - motion.positions[:, parents], axis=-1)


@pytest.mark.parametrize("file", ALL_CLIPS)
def test_bones_are_rigid_and_counts_match_the_documentation(file):
    motion = clip(file)
    lengths = _bone_lengths(motion)
    assert np.ptp(lengths, axis=0).max() < 1e-3  # metres
    joints, fps, frames = documented(Path(file).stem)
    assert motion.num_joints == joints
    assert motion.fps == (fps if fps in (30.0, 120.0) else pytest.approx(fps, abs=0.005))
    if frames is not None:
        assert motion.num_frames == frames
    assert motion.positions.dtype == np.float64 and np.isfinite(motion.positions).all()


@pytest.mark.parametrize("file", ALL_CLIPS)
def test_metres_and_y_up(file):
    motion = clip(file)
    markers = marker_positions(motion, ("head", "left_ankle", "right_ankle", "pelvis"))
    first = markers[0]
    assert first[0, 1] > first[1, 1] + 0.5 and first[0, 1] > first[2, 1] + 0.5  # head over feet
    assert first[3, 1] > max(first[1, 1], first[2, 1])
    # head joint (base of the skull) over the lowest joint: stature minus about 0.2 m; the fair1
    # rig (shared by the 8yr_old clip) is a child's
    head_over_floor = (motion.positions[:, motion.joint_index(_head(motion)), 1]
                       - motion.positions[:, :, 1].min(axis=1)).max()
    child = Path(file).stem.startswith(("fair1_", "8yr_old"))
    low, high = (0.85, 1.3) if child else (1.2, 1.95)
    assert low < head_over_floor < high


def _head(motion: Motion) -> str:
    return "head" if motion.rig == "cmu_asf" else "Head"


def frontal_image_x(motion: Motion, frame: int = 0) -> tuple[dict[str, float], float]:
    """Image x (pixels, +right) of markers seen by a camera in front of the subject, and how far
    the left toe points towards that camera (metres)."""
    names = ("left_hip", "right_hip", "left_shoulder", "right_shoulder", "left_wrist",
             "right_wrist", "left_ankle")
    points = dict(zip(names, marker_positions(motion, names)[frame], strict=True))
    up = np.array([0.0, 1.0, 0.0])
    across = (points["left_hip"] - points["right_hip"]
              + points["left_shoulder"] - points["right_shoulder"])
    forward = np.cross(across, up)  # right-handed, Y up: a subject facing +Z has its left at +X
    forward /= np.linalg.norm(forward)
    centre = 0.5 * (points["left_hip"] + points["right_hip"])
    camera = centre + 4.0 * forward
    view = -forward  # OpenCV camera axes: z along the view, y down, x = y cross z
    y_axis = -up
    x_axis = np.cross(y_axis, view)
    image_x = {name: 1000.0 * np.dot(p - camera, x_axis) / np.dot(p - camera, view) + 500.0
               for name, p in points.items()}
    toe_file = motion.positions[frame, motion.joint_index(_toe(motion))]
    toe_forward = float(np.dot(toe_file - points["left_ankle"], forward))
    return image_x, toe_forward


def _toe(motion: Motion) -> str:
    return {"cmu_asf": "ltoes", "cmu_bvh": "LeftToe", "bandai": "Toes_L",
            "animateddrawings": "LeftToeBase"}[motion.rig]


@pytest.mark.parametrize("file", ALL_CLIPS)
def test_subject_left_is_viewer_right_and_mirror_keeps_it(file):
    motion = clip(file)
    for candidate in (motion, motion.mirror()):
        image_x, toe_forward = frontal_image_x(candidate)
        assert toe_forward > 0.03  # toes point at the camera: not mirrored back to front
        assert image_x["left_wrist"] > 500.0 > image_x["right_wrist"]
        assert image_x["left_shoulder"] > image_x["right_shoulder"]


def test_mirror_reflects_and_swaps_sides():
    motion = load(BUNDLED["cmu_bvh/131_01"])
    mirrored = motion.mirror()
    left, right = motion.joint_index("LeftWrist"), motion.joint_index("RightWrist")
    spine = motion.joint_index("Chest2")
    # the mirrored left wrist is the original right wrist reflected: same height, same distance
    # from the (unswapped) spine
    np.testing.assert_allclose(mirrored.positions[:, left, 1], motion.positions[:, right, 1])
    np.testing.assert_allclose(
        np.linalg.norm(mirrored.positions[:, left] - mirrored.positions[:, spine], axis=-1),
        np.linalg.norm(motion.positions[:, right] - motion.positions[:, spine], axis=-1))
    np.testing.assert_allclose(mirrored.mirror().positions, motion.positions, atol=1e-9)
    assert np.ptp(_bone_lengths(mirrored), axis=0).max() < 1e-9


def _wrist_rise(motion: Motion) -> float:
    """How much higher the right wrist gets than the left over the clip (metres)."""
    wrists = marker_positions(motion, ("right_wrist", "left_wrist"))[..., 1]
    return float(wrists[:, 0].max() - wrists[:, 1].max())


def test_real_waves_use_the_hand_their_name_says():
    right = load(TEST_ONLY["bandai/dataset-2_wave-right-hand_normal_001"])
    left = load(TEST_ONLY["bandai/dataset-2_wave-left-hand_normal_001"])
    assert _wrist_rise(right) > 0.5 and _wrist_rise(left) < -0.5
    assert _wrist_rise(right.mirror()) < -0.5
    # fair1_wave_hello is documented as a right-hand wave
    assert _wrist_rise(load(BUNDLED["animateddrawings/fair1_wave_hello"])) > 0.1


def test_resample_round_trip_and_select():
    motion = load(BUNDLED["cmu_amc/07_01"])
    doubled = motion.resample(2 * motion.fps)
    assert doubled.num_frames == 2 * motion.num_frames - 1
    np.testing.assert_allclose(doubled.positions[1::2],
                               0.5 * (motion.positions[:-1] + motion.positions[1:]))
    np.testing.assert_allclose(doubled.resample(motion.fps).positions, motion.positions,
                               atol=1e-12)
    quarter = motion.resample(30.0)
    np.testing.assert_allclose(quarter.positions, motion.positions[::4][: quarter.num_frames])
    seconds = motion.select(0.5, 1.5, unit="seconds")
    np.testing.assert_array_equal(seconds.positions, motion.positions[60:180])
    assert seconds.duration == pytest.approx(119 / 120)
    np.testing.assert_array_equal(motion.select(10, 20).positions, motion.positions[10:20])
    with pytest.raises(ValueError, match="cannot select"):
        motion.select(2.0, 10.0, unit="seconds")


def _reference_bvh(file: Path, frames: int) -> tuple[np.ndarray, list[str]]:
    """Forward kinematics one frame and one joint at a time with SciPy rotations."""
    lines = file.read_text().splitlines()
    motion_line = next(n for n, line in enumerate(lines) if line.strip() == "MOTION")
    skeleton = parse_hierarchy(file, lines, motion_line)
    values = np.array([line.split() for line in lines[motion_line + 3:motion_line + 3 + frames]],
                      dtype=float)
    positions = np.zeros((frames, len(skeleton.names), 3))
    for t in range(frames):
        column, world = 0, {}
        for joint, channels in enumerate(skeleton.channels):
            translation = skeleton.offsets[joint].copy()
            axes, angles = "", []
            for name in channels:
                if name.endswith("position"):
                    translation["XYZ".index(name[0])] = values[t, column]
                else:
                    axes, angles = axes + name[0], angles + [values[t, column]]
                column += 1
            local = Rotation.from_euler(axes, angles, degrees=True)  # upper case: intrinsic
            parent = skeleton.parents[joint]
            if parent < 0:
                world[joint] = (local, translation)
            else:
                parent_rotation, parent_position = world[parent]
                world[joint] = (parent_rotation * local,
                                parent_position + parent_rotation.apply(translation))
            positions[t, joint] = world[joint][1]
    return positions, skeleton.names


@pytest.mark.parametrize(("name", "unit", "z_up"), [
    ("cmu_bvh/131_01", 0.0254 / 0.45, False),
    ("animateddrawings/fair1_wave_hello", 0.0254, True),
    ("bandai/dataset-2_wave-right-hand_normal_001", 0.01, False),
])
def test_bvh_forward_kinematics_matches_scipy(name, unit, z_up):
    file = {**BUNDLED, **TEST_ONLY}[name]
    reference, names = _reference_bvh(file, frames=4)
    if z_up:
        reference = np.stack([reference[..., 0], reference[..., 2], -reference[..., 1]], -1)
    motion = load(file)
    assert list(motion.joint_names) == names
    np.testing.assert_allclose(motion.positions[:4], reference * unit, atol=1e-9)


def test_asf_forward_kinematics_matches_scipy():
    asf, amc = BUNDLED["cmu_amc/07_01"].with_name("07.asf"), BUNDLED["cmu_amc/07_01"]
    skeleton = parse_asf(asf)
    root, dofs = parse_amc(amc, skeleton)
    motion = load(amc)
    unit = 0.0254 / 0.45  # CMU FAQ: multiply by (1/0.45) * 2.54 / 100 for metres
    for t in (0, 100):
        # Acclaim: world rotation = parent @ C @ M @ C^-1; lower-case SciPy orders are extrinsic,
        # i.e. "xyz" = Rz Ry Rx, the Acclaim reading of "XYZ"
        root_frame = Rotation.from_euler("xyz", skeleton.root_orientation, degrees=True)
        rotation = {-1: root_frame * Rotation.from_euler("xyz", root[t, 3:], degrees=True)
                    * root_frame.inv()}
        end = {-1: root[t, :3]}
        for index, bone in enumerate(skeleton.bones):  # CMU ASFs list parents first
            frame = Rotation.from_euler(bone.axis_order.lower(), bone.axis_angles, degrees=True)
            local = (Rotation.from_euler("".join(d[1] for d in bone.dofs), dofs[bone.name][t],
                                         degrees=True) if bone.dofs else Rotation.identity())
            rotation[index] = rotation[bone.parent] * frame * local * frame.inv()
            start = end[bone.parent]
            end[index] = start + bone.length * rotation[index].apply(bone.direction)
            np.testing.assert_allclose(motion.positions[t, motion.joint_index(bone.name)],
                                       start * unit, atol=1e-9)
    femur = np.linalg.norm(motion.positions[:, motion.joint_index("ltibia")]
                           - motion.positions[:, motion.joint_index("lfemur")], axis=-1)
    # 07.asf lfemur length; its direction is unit length to the 6 digits written
    np.testing.assert_allclose(femur, 6.92462 / 0.45 * 0.0254, rtol=1e-5)


def test_a_thousand_frame_bvh_loads_fast():
    file = BUNDLED["cmu_bvh/131_01"]  # 994 frames x 93 channels
    start = time.perf_counter()
    load_motion(file)
    assert time.perf_counter() - start < 1.0


def test_joint_index_and_validation():
    motion = load(BUNDLED["cmu_bvh/131_01"])
    assert motion.joint_names[motion.joint_index("LeftWrist")] == "LeftWrist"
    with pytest.raises(KeyError, match="no joint 'Nose'"):
        motion.joint_index("Nose")
    with pytest.raises(ValueError, match="NaN"):
        Motion(np.full((2, 1, 3), np.nan), ("a",), (-1,), 30.0, "test", "generic_bvh")
    with pytest.raises(ValueError, match="earlier joint"):
        Motion(np.zeros((2, 2, 3)), ("a", "b"), (1, -1), 30.0, "test", "generic_bvh")


def test_unknown_rig_is_read_y_up_with_a_unit_guessed_from_height(tmp_path):
    # Bandai's clip with its ground joint renamed is no longer recognised: read as a generic BVH,
    # its centimetres must be recognised from the body's height alone
    source = TEST_ONLY["bandai/dataset-2_wave-right-hand_normal_001"]
    renamed = tmp_path / "unknown_rig.bvh"
    renamed.write_text(source.read_text().replace("joint_Root", "Ground"))
    generic, bandai = load_motion(renamed), load(source)
    assert generic.rig == "generic_bvh" and bandai.rig == "bandai"
    np.testing.assert_allclose(generic.positions, bandai.positions)
    metres = tmp_path / "metres.bvh"
    text = source.read_text().replace("joint_Root", "Ground").splitlines()
    motion_line = text.index("MOTION")
    scaled = [" ".join(f"{float(v) / 100 if i % 6 < 3 else float(v):.6f}"
                       for i, v in enumerate(line.split())) for line in text[motion_line + 3:]]
    metres.write_text("\n".join(text[:motion_line + 3] + scaled))
    np.testing.assert_allclose(load_motion(metres).positions, bandai.positions, atol=1e-5)
