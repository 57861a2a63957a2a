"""Marker sets: every rig maps onto them with anatomically sensible segment lengths; a rig that
cannot be mapped says which markers and joints are missing."""

import functools
from pathlib import Path

import numpy as np
import pytest
from _clips import one_take_per_hdm05_actor, shared_clip_params, upright_frame

from jaxtrack.body.markers import (
    HUMANEVA_15,
    MARKER_EDGES,
    RIG_MARKER_MAPS,
    UPPER_BODY_12,
    MarkerMapError,
    marker_edges,
    marker_joint_indices,
    marker_positions,
)
from jaxtrack.body.motion import RIGS, Motion, load_motion
from jaxtrack.data import bundled_folder, clip_files, shared_folder

TESTS_DATA = Path(__file__).parents[1] / "data"
LOCAL = {**clip_files(bundled_folder()), **clip_files(TESTS_DATA)}
SHARED_FOLDER = shared_folder()
SHARED = clip_files(SHARED_FOLDER) if SHARED_FOLDER is not None else {}
CLIPS = [pytest.param(file, id=f"local:{name}") for name, file in LOCAL.items()] + (
    shared_clip_params(SHARED) if SHARED
    else [pytest.param(None, id="shared:absent")])


@functools.cache
def load(file: Path) -> Motion:
    return load_motion(file)


def test_marker_sets_are_as_published():
    assert len(HUMANEVA_15) == 15 and len(UPPER_BODY_12) == 12
    assert HUMANEVA_15[:3] == ("head", "neck", "right_shoulder") and HUMANEVA_15[8] == "pelvis"
    assert UPPER_BODY_12[:4] == ("head", "neck", "thorax", "pelvis")
    assert set(RIG_MARKER_MAPS) == set(RIGS)  # every rig a reader can report has a map
    for rig_map in RIG_MARKER_MAPS.values():
        assert set(HUMANEVA_15) | set(UPPER_BODY_12) <= set(rig_map)


@pytest.mark.parametrize("names", [HUMANEVA_15, UPPER_BODY_12], ids=["humaneva", "upper_body"])
def test_edges_form_one_tree(names):
    edges = MARKER_EDGES[names]
    assert edges == marker_edges(names)
    assert len(edges) == len(names) - 1
    reached, frontier = {0}, [0]
    while frontier:
        node = frontier.pop()
        for a, b in edges:
            for here, there in ((a, b), (b, a)):
                if here == node and there not in reached:
                    reached.add(there)
                    frontier.append(there)
    assert reached == set(range(len(names)))


def _segment(markers: np.ndarray, names, first: str, second: str) -> np.ndarray:
    return np.linalg.norm(markers[:, names.index(first)] - markers[:, names.index(second)], axis=-1)


@pytest.mark.parametrize("file", CLIPS)
def test_every_rig_maps_to_anatomical_markers(file):
    if file is None:
        pytest.skip("the shared/data collection is not beside this checkout")
    motion = load(file)
    markers = marker_positions(motion, HUMANEVA_15)
    assert markers.shape == (motion.num_frames, 15, 3)
    upper = marker_positions(motion, UPPER_BODY_12)
    np.testing.assert_array_equal(upper[:, 0], markers[:, 0])
    # bounds wide enough for a child and an adult, tight enough to catch a clavicle taken for a
    # shoulder, a hand tip for a wrist or a toe for an ankle
    child = 0.7 if Path(file).stem.startswith(("fair1_", "8yr_old")) else 1.0
    for side in ("left", "right"):
        upper_arm = _segment(markers, HUMANEVA_15, f"{side}_shoulder", f"{side}_elbow")[0]
        forearm = _segment(markers, HUMANEVA_15, f"{side}_elbow", f"{side}_wrist")[0]
        thigh = _segment(markers, HUMANEVA_15, f"{side}_hip", f"{side}_knee")[0]
        shin = _segment(markers, HUMANEVA_15, f"{side}_knee", f"{side}_ankle")[0]
        # HDM05's actor bd has a 0.17 m forearm (elbow to wrist joint)
        assert 0.2 * child < upper_arm < 0.4 and 0.16 * child < forearm < 0.35
        assert 0.3 * child < thigh < 0.55 and 0.3 * child < shin < 0.55
    shoulders = _segment(markers, HUMANEVA_15, "left_shoulder", "right_shoulder")[0]
    hips = _segment(markers, HUMANEVA_15, "left_hip", "right_hip")[0]
    # Bandai's upper-arm joints sit only 0.2 m apart; a clavicle start would be < 0.12 m
    # HDM05's ASF shoulders (humerus roots) of the broadest actor sit 0.51 m apart
    assert 0.18 * child < shoulders < 0.55 and 0.1 * child < hips < 0.35
    # thorax between neck and pelvis; neck about shoulder height, head above it: heights in a
    # frame where the subject stands, or distances along the trunk for one who never does
    frame = upright_frame(Path(file).stem)
    first = upper[0 if frame is None else frame]
    up = np.array([0.0, 1.0, 0.0])
    if frame is None:
        up = first[UPPER_BODY_12.index("neck")] - first[UPPER_BODY_12.index("pelvis")]
        up /= np.linalg.norm(up)
    heights = {name: first[UPPER_BODY_12.index(name)] @ up for name in UPPER_BODY_12}
    assert heights["head"] > heights["neck"] > heights["thorax"] > heights["pelvis"]
    assert abs(heights["neck"] - heights["left_shoulder"]) < 0.15


# rigs whose only real files are in shared/data: the DeepMimic clips are LGPL (never copied into
# the repository) and the MotionBuilder-friendly CMU clips are not bundled;
# test_motion.py reads both dialects from files it writes
SHARED_ONLY_RIGS = {"deepmimic"}


def test_every_rig_has_a_clip_here():
    rigs = {load(file).rig for file in LOCAL.values()}
    assert rigs == set(RIGS) - {"generic_bvh"} - SHARED_ONLY_RIGS
    if SHARED:
        sample = one_take_per_hdm05_actor(SHARED)
        assert {load(file).rig for file in sample.values()} == set(RIGS) - {"generic_bvh"}


def _motion(names: tuple[str, ...], rig: str) -> Motion:
    return Motion(np.zeros((2, len(names), 3)), names, (-1,) + (0,) * (len(names) - 1), 30.0,
                  "made-up skeleton", rig)


def test_generic_rig_uses_common_exporter_names():
    names = ("Hips", "Spine2", "Neck", "Head") + tuple(
        f"{side}{part}" for side in ("Left", "Right")
        for part in ("Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot"))
    motion = _motion(names, "generic_bvh")
    motion = Motion(np.arange(2 * len(names) * 3, dtype=float).reshape(2, len(names), 3), names,
                    motion.parents, 30.0, "made-up", "generic_bvh")
    markers = marker_positions(motion, HUMANEVA_15)
    np.testing.assert_array_equal(markers[:, HUMANEVA_15.index("left_elbow")],
                                  motion.positions[:, names.index("LeftForeArm")])


def test_unmappable_rig_names_what_is_missing():
    motion = _motion(("Hips", "Spine2", "Neck", "Head", "LeftArm", "RightArm"), "generic_bvh")
    with pytest.raises(MarkerMapError) as caught:
        marker_positions(motion, HUMANEVA_15)
    message = str(caught.value)
    assert "generic_bvh" in message and "left_knee" in message and "LeftLeg" in message
    assert "left_shoulder" not in message  # that one was found
    broken_cmu = _motion(("Hips", "LeftShoulder"), "cmu_bvh")
    with pytest.raises(MarkerMapError, match=r"cmu_bvh.*right_wrist \(looked for joint RightWrist"):
        marker_positions(broken_cmu, HUMANEVA_15)
    # the MotionBuilder-friendly CMU names: LeftShoulder is a clavicle, never taken for a shoulder
    clavicles_only = _motion(("Hips", "LeftShoulder", "RightShoulder"), "cmu_bvh_mb")
    with pytest.raises(MarkerMapError,
                       match=r"rig 'cmu_bvh_mb'.*left_shoulder \(looked for joint LeftArm\)"):
        marker_positions(clavicles_only, UPPER_BODY_12)
    torso_only = _motion(("Hips", "Spine", "Neck", "Head"), "deepmimic")
    with pytest.raises(MarkerMapError) as caught:
        marker_positions(torso_only, UPPER_BODY_12)
    message = str(caught.value)
    assert "rig 'deepmimic'" in message and "right_wrist (looked for joint RightHand)" in message
    assert "thorax" not in message and "head" not in message  # those were found
    with pytest.raises(MarkerMapError, match="not a marker known"):
        marker_positions(load(LOCAL["cmu_bvh/131_01"]), ("nose",))
    assert isinstance(caught.value, KeyError)


def test_recognition_by_name_agrees_with_every_known_rig():
    """Joint names alone find what each rig's own map names (on the real files): the only
    difference is the MotionBuilder-friendly CMU neck, whose `Neck` is the lower neck."""
    from jaxtrack.body.markers import recognise_markers

    names = tuple(dict.fromkeys(HUMANEVA_15 + UPPER_BODY_12))
    rigs = {}
    for file in {**LOCAL, **one_take_per_hdm05_actor(SHARED)}.values():
        rigs.setdefault(load(file).rig, load(file))
    assert {"cmu_asf", "cmu_bvh", "animateddrawings", "bandai"} <= set(rigs)
    for rig, motion in rigs.items():
        found, _ = recognise_markers(motion.joint_names, motion.parents)
        expected = dict(zip(names, marker_joint_indices(motion, names), strict=True))
        differ = {marker for marker in names if found.get(marker) != expected[marker]}
        assert differ == ({"neck"} if rig == "cmu_bvh_mb" else set()), rig


def test_a_renamed_real_rig_is_read_as_generic_and_mapped(tmp_path):
    """A real BVH whose joints carry an exporter's namespace (`mixamorig:`) is no known rig;
    its markers are found by name, on the same joints as the original's."""
    original = load(LOCAL["animateddrawings/fair1_wave_hello"])
    text = LOCAL["animateddrawings/fair1_wave_hello"].read_text()
    for name in original.joint_names:
        text = text.replace(f"JOINT {name}\n", f"JOINT mixamorig:{name}\n")
        text = text.replace(f"ROOT {name}\n", f"ROOT mixamorig:{name}\n")
    renamed_file = tmp_path / "exported.bvh"
    renamed_file.write_text(text)
    renamed = load_motion(renamed_file)
    assert renamed.rig == "generic_bvh"
    assert renamed.joint_names == tuple(f"mixamorig:{name}" for name in original.joint_names)
    np.testing.assert_array_equal(marker_joint_indices(renamed, HUMANEVA_15),
                                  marker_joint_indices(original, HUMANEVA_15))
    np.testing.assert_array_equal(marker_joint_indices(renamed, UPPER_BODY_12),
                                  marker_joint_indices(original, UPPER_BODY_12))


def _tree(parents_by_name: dict[str, str | None]) -> Motion:
    names = tuple(parents_by_name)
    parents = tuple(-1 if parent is None else names.index(parent)
                    for parent in parents_by_name.values())
    return Motion(np.zeros((1, len(names), 3)), names, parents, 30.0, "made-up", "generic_bvh")


def test_other_exporters_names_are_recognised():
    # SMPL: `L_Shoulder` is the shoulder (`L_Collar` the clavicle), `L_Wrist` before `L_Hand`,
    # and the thorax is Spine3, the joint both collars hang from
    smpl = _tree({"Pelvis": None, "L_Hip": "Pelvis", "R_Hip": "Pelvis", "Spine1": "Pelvis",
                  "L_Knee": "L_Hip", "R_Knee": "R_Hip", "Spine2": "Spine1",
                  "L_Ankle": "L_Knee", "R_Ankle": "R_Knee", "Spine3": "Spine2",
                  "L_Foot": "L_Ankle", "R_Foot": "R_Ankle", "Neck": "Spine3",
                  "L_Collar": "Spine3", "R_Collar": "Spine3", "Head": "Neck",
                  "L_Shoulder": "L_Collar", "R_Shoulder": "R_Collar", "L_Elbow": "L_Shoulder",
                  "R_Elbow": "R_Shoulder", "L_Wrist": "L_Elbow", "R_Wrist": "R_Elbow",
                  "L_Hand": "L_Wrist", "R_Hand": "R_Wrist"})
    chosen = dict(zip(UPPER_BODY_12, (smpl.joint_names[i] for i in
                                      marker_joint_indices(smpl, UPPER_BODY_12)), strict=True))
    assert chosen == {"head": "Head", "neck": "Neck", "thorax": "Spine3", "pelvis": "Pelvis",
                      "right_shoulder": "R_Shoulder", "right_elbow": "R_Elbow",
                      "right_wrist": "R_Wrist", "right_hip": "R_Hip",
                      "left_shoulder": "L_Shoulder", "left_elbow": "L_Elbow",
                      "left_wrist": "L_Wrist", "left_hip": "L_Hip"}
    # Blender (rigify-style): sides as `.L`, `shoulder.L` a clavicle below `upper_arm.L`
    blender = _tree({"hips": None, "spine": "hips", "chest": "spine", "neck": "chest",
                     "head": "neck", **{name: parent for side in "LR" for name, parent in (
                         (f"shoulder.{side}", "chest"),
                         (f"upper_arm.{side}", f"shoulder.{side}"),
                         (f"forearm.{side}", f"upper_arm.{side}"),
                         (f"hand.{side}", f"forearm.{side}"), (f"thigh.{side}", "hips"),
                         (f"shin.{side}", f"thigh.{side}"), (f"foot.{side}", f"shin.{side}"))}})
    chosen = [blender.joint_names[i] for i in marker_joint_indices(blender, HUMANEVA_15)]
    assert chosen == ["head", "neck", "upper_arm.R", "forearm.R", "hand.R", "upper_arm.L",
                      "forearm.L", "hand.L", "hips", "thigh.R", "shin.R", "foot.R", "thigh.L",
                      "shin.L", "foot.L"]


def test_an_unrecognised_rig_names_markers_and_joints_in_one_line():
    motion = _tree({"Root": None, "Torso": "Root", "Skull": "Torso", "BicepL": "Torso",
                    "LeftForeArm": "BicepL"})
    with pytest.raises(MarkerMapError) as caught:
        marker_positions(motion, UPPER_BODY_12)
    message = str(caught.value)
    assert "\n" not in message
    assert "head (looked for a joint named Head)" in message
    assert ("left_shoulder (looked for a joint named LeftUpperArm or LeftUpArm or LeftArm or "
            "LeftHumerus or LeftShoulder (or its side written L_, _L, .L))") in message
    assert "thorax (looked for the joint both shoulders hang from, or a joint named" in message
    assert "left_elbow" not in message and "pelvis" not in message  # found
    assert message.endswith("joints not recognised: Torso, Skull, BicepL")
