"""Common marker sets and the per-rig maps from skeleton joints to markers.

A marker is a named body point that every rig can supply, so trackers, priors and metrics work on
one vocabulary whatever file the motion came from. Joint positions in a Motion sit at the joint
(the proximal end of a bone), which fixes what each marker means:

- `head`: the head joint (base of the skull, top of the neck); the rigs have no skull-centre
  joint, except DeepMimic, whose only head joint is the centre of its head sphere.
- `neck`: the neck joint at about shoulder height (CMU ASF `upperneck`, CMU BVH `Neck`, CMU
  MotionBuilder-friendly BVH `Neck1`, DeepMimic `Neck`).
- `thorax`: the spine joint the shoulder girdle hangs from (AnimatedDrawings `Spine3`, Bandai
  `Chest`, CMU `thorax`/`Chest2`/`Spine1`, DeepMimic `Spine`).
- `pelvis`: the spine base / hip centre (the root in every rig).
- `*_shoulder`: the shoulder (gleno-humeral) joint, the start of the upper arm (BVH `RightArm`,
  Bandai `UpperArm_R`, CMU ASF `rhumerus`, CMU BVH `RightShoulder`), not the clavicle (CMU
  MotionBuilder-friendly `RightShoulder`).
- `*_elbow`, `*_wrist`: start of the forearm and of the hand; `*_hip`, `*_knee`, `*_ankle`: start
  of the thigh, shin and foot.
"""

from __future__ import annotations

import re

import numpy as np

from jaxtrack.body.motion import Motion

__all__ = [
    "HUMANEVA_15", "UPPER_BODY_12", "MARKER_EDGES", "RIG_MARKER_MAPS", "MarkerMapError",
    "marker_edges", "marker_joint_indices", "marker_positions", "recognise_markers",
]

HUMANEVA_15 = (
    "head", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder", "left_elbow",
    "left_wrist", "pelvis", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee",
    "left_ankle",
)
"""The HumanEva-style 15-marker body (pelvis = spine base)."""

UPPER_BODY_12 = (
    "head", "neck", "thorax", "pelvis", "right_shoulder", "right_elbow", "right_wrist", "right_hip",
    "left_shoulder", "left_elbow", "left_wrist", "left_hip",
)
"""The 12 vertices of the Scaled Prismatic Model upper body (Tian et al.; Ong & Gong)."""

_SIDES = ("right", "left")


def _sided(template: dict[str, tuple[str, str]]) -> dict[str, str]:
    # template: marker part -> (right joint, left joint)
    return {f"{side}_{part}": joints[i] for part, joints in template.items()
            for i, side in enumerate(_SIDES)}


_PART_WORDS: dict[str, tuple[str, ...]] = {
    # marker part -> joint-name words that mean it, the most specific first: a rig with both
    # `LeftWrist` and `LeftHand` (SMPL, CMU) has its wrist at `LeftWrist`; one with both
    # `LeftShoulder` and `LeftArm` (Mixamo, MotionBuilder) has its clavicle at `LeftShoulder`
    "head": ("Head",),
    "neck": ("Neck", "UpperNeck", "Neck1", "Neck01"),
    "thorax": ("Chest", "UpperChest", "Thorax", "Spine3", "Spine2", "Spine1", "Spine"),
    "pelvis": ("Hips", "Pelvis", "Hip", "Root", "HipCenter", "HipsCenter", "SpineBase", "Waist"),
    "shoulder": ("UpperArm", "UpArm", "Arm", "Humerus", "Shoulder"),
    "elbow": ("Elbow", "ForeArm", "LowerArm", "LowArm", "Radius"),
    "wrist": ("Wrist", "Hand"),
    "hip": ("UpLeg", "UpperLeg", "Thigh", "Femur", "Hip"),
    "knee": ("Knee", "Leg", "LowerLeg", "LowLeg", "Shin", "Calf", "Tibia"),
    "ankle": ("Ankle", "Foot"),
}
_SIDED_PARTS = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")
_GENERIC_WORDS: dict[str, tuple[str | None, tuple[str, ...]]] = {
    **{part: (None, _PART_WORDS[part]) for part in ("head", "neck", "thorax", "pelvis")},
    **{f"{side}_{part}": (side, _PART_WORDS[part]) for side in _SIDES for part in _SIDED_PARTS},
}
"""Marker -> (side or None, joint-name words) for rigs recognised by name."""


RIG_MARKER_MAPS: dict[str, dict[str, str | tuple[str, ...]]] = {
    "cmu_asf": {
        "head": "head", "neck": "upperneck", "thorax": "thorax", "pelvis": "root",
        **_sided({"shoulder": ("rhumerus", "lhumerus"), "elbow": ("rradius", "lradius"),
                  "wrist": ("rwrist", "lwrist"), "hip": ("rfemur", "lfemur"),
                  "knee": ("rtibia", "ltibia"), "ankle": ("rfoot", "lfoot")}),
    },
    "cmu_bvh": {
        "head": "Head", "neck": "Neck", "thorax": "Chest2", "pelvis": "Hips",
        **_sided({"shoulder": ("RightShoulder", "LeftShoulder"),
                  "elbow": ("RightElbow", "LeftElbow"), "wrist": ("RightWrist", "LeftWrist"),
                  "hip": ("RightHip", "LeftHip"), "knee": ("RightKnee", "LeftKnee"),
                  "ankle": ("RightAnkle", "LeftAnkle")}),
    },
    "animateddrawings": {
        "head": "Head", "neck": "Neck", "thorax": "Spine3", "pelvis": "Hips",
        **_sided({"shoulder": ("RightArm", "LeftArm"), "elbow": ("RightForeArm", "LeftForeArm"),
                  "wrist": ("RightHand", "LeftHand"), "hip": ("RightUpLeg", "LeftUpLeg"),
                  "knee": ("RightLeg", "LeftLeg"), "ankle": ("RightFoot", "LeftFoot")}),
    },
    "bandai": {
        "head": "Head", "neck": "Neck", "thorax": "Chest", "pelvis": "Hips",
        **_sided({"shoulder": ("UpperArm_R", "UpperArm_L"), "elbow": ("LowerArm_R", "LowerArm_L"),
                  "wrist": ("Hand_R", "Hand_L"), "hip": ("UpperLeg_R", "UpperLeg_L"),
                  "knee": ("LowerLeg_R", "LowerLeg_L"), "ankle": ("Foot_R", "Foot_L")}),
    },
    # CMU, MotionBuilder-friendly names: LeftShoulder is the clavicle, LeftArm the humerus; Neck
    # sits where the clavicles start (ASF lowerneck), Neck1 is ASF upperneck, as in `cmu_bvh`
    "cmu_bvh_mb": {
        "head": "Head", "neck": "Neck1", "thorax": "Spine1", "pelvis": "Hips",
        **_sided({"shoulder": ("RightArm", "LeftArm"), "elbow": ("RightForeArm", "LeftForeArm"),
                  "wrist": ("RightHand", "LeftHand"), "hip": ("RightUpLeg", "LeftUpLeg"),
                  "knee": ("RightLeg", "LeftLeg"), "ankle": ("RightFoot", "LeftFoot")}),
    },
    # DeepMimic humanoid: Spine is its chest (the arms hang from it), Neck its neck at about
    # shoulder height, Head the centre of the head sphere (it has no base-of-skull joint)
    "deepmimic": {
        "head": "Head", "neck": "Neck", "thorax": "Spine", "pelvis": "Hips",
        **_sided({"shoulder": ("RightArm", "LeftArm"), "elbow": ("RightForeArm", "LeftForeArm"),
                  "wrist": ("RightHand", "LeftHand"), "hip": ("RightUpLeg", "LeftUpLeg"),
                  "knee": ("RightLeg", "LeftLeg"), "ankle": ("RightFoot", "LeftFoot")}),
    },
    # any other BVH: joints recognised by name (`recognise_markers`); the names below are the
    # words it looks for, most specific first
    "generic_bvh": {
        marker: tuple(f"{side.capitalize() if side else ''}{word}" for word in words)
        for marker, (side, words) in _GENERIC_WORDS.items()
    },
}
"""Per rig: marker name -> joint name (or candidate joint names, the first present wins)."""

_EDGE_NAMES = (
    ("head", "neck"), ("neck", "thorax"), ("thorax", "pelvis"), ("neck", "pelvis"),
    *((f"{s}_shoulder", f"{s}_elbow") for s in _SIDES),
    *((f"{s}_elbow", f"{s}_wrist") for s in _SIDES),
    *((f"{s}_hip", f"{s}_knee") for s in _SIDES),
    *((f"{s}_knee", f"{s}_ankle") for s in _SIDES),
    *(("neck", f"{s}_shoulder") for s in _SIDES),
    *(("pelvis", f"{s}_hip") for s in _SIDES),
)


def marker_edges(names: tuple[str, ...]) -> tuple[tuple[int, int], ...]:
    """Stick-figure edges among `names` as index pairs into `names`.

    The spine is drawn through `thorax` when the set has it (neck-thorax-pelvis), else neck-pelvis.
    """
    index = {name: i for i, name in enumerate(names)}
    edges = []
    for first, second in _EDGE_NAMES:
        if (first, second) == ("neck", "pelvis") and "thorax" in index:
            continue
        if first in index and second in index:
            edges.append((index[first], index[second]))
    return tuple(edges)


MARKER_EDGES: dict[tuple[str, ...], tuple[tuple[int, int], ...]] = {
    HUMANEVA_15: marker_edges(HUMANEVA_15),
    UPPER_BODY_12: marker_edges(UPPER_BODY_12),
}
"""Edges for drawing each marker set, keyed by the set: `MARKER_EDGES[HUMANEVA_15]`."""


class MarkerMapError(KeyError):
    """A motion's rig cannot supply some markers; the message names the rig and what is missing."""

    def __str__(self) -> str:  # KeyError would print the message with quotes around it
        return str(self.args[0]) if self.args else ""


_SIDE_WORDS = {"left": "left", "l": "left", "right": "right", "r": "right"}
_WORD_PART = {word.lower(): part for part, words in _PART_WORDS.items() for word in words}


def _name_tokens(name: str) -> list[str]:
    # `mixamorig:LeftForeArm` -> left fore arm; `upper_arm.L` -> upper arm l; `Bip01 L Thigh`
    name = re.split(r"[:|]", name)[-1]
    return [token.lower() for token in
            re.findall(r"[A-Z]+(?![a-z])\d*|[A-Z]?[a-z]+\d*|\d+", name)]


def _classify(name: str) -> tuple[str | None, str, int] | None:
    """``(side, part, rank)`` a joint name stands for (`LeftForeArm` -> ("left", "elbow", 1),
    `lhumerus` -> ("left", "shoulder", 3), `Spine2` -> (None, "thorax", 4)), or None; ``rank``
    is the word's place in ``_PART_WORDS[part]``, 0 for the most specific."""
    tokens = _name_tokens(name)
    sides = [token for token in tokens if token in _SIDE_WORDS]
    side = _SIDE_WORDS[sides[0]] if len(sides) == 1 else None
    rest = [token for token in tokens if token not in _SIDE_WORDS] if side else tokens
    if not sides and rest and rest[0][:1] in ("l", "r") and rest[0][1:] in _WORD_PART:
        side, rest = _SIDE_WORDS[rest[0][0]], [rest[0][1:], *rest[1:]]
    for start in range(len(rest)):  # the whole name first, then without a prefix (`Bip01`)
        word = "".join(rest[start:])
        part = _WORD_PART.get(word)
        if part is None:
            continue
        if part == "hip" and side is None:  # an unsided `Hip` is the pelvis
            part = "pelvis"
        if (part in _SIDED_PARTS) != (side is not None):
            return None  # `Hand` without a side, `LeftHead`: not a marker's joint
        return side, part, [w.lower() for w in _PART_WORDS[part]].index(word)
    return None


def _common_ancestor(parents: tuple[int, ...], first: int, second: int) -> int:
    chain = set()
    while first >= 0:
        chain.add(first)
        first = parents[first]
    while second >= 0 and second not in chain:
        second = parents[second]
    return second


def recognise_markers(joint_names: tuple[str, ...], parents: tuple[int, ...]
                      ) -> tuple[dict[str, int], tuple[str, ...]]:
    """Find the markers' joints in a rig by their names alone.

    Each joint name is split into words (camel case, `_`, `.`, spaces; a namespace such as
    `mixamorig:` dropped) and read as a side (`Left`, `L`, `_L`, `.L`, a leading `l` as in
    `lhumerus`) and a part from ``_PART_WORDS``; the most specific word found wins. The
    thorax is the joint both shoulders hang from when it lies between pelvis and neck (the
    definition of the marker), else the joint named most like a chest.

    Returns:
        marker -> joint index for every marker found, and the joints that stand for no marker.
    """
    best: dict[str, tuple[int, int]] = {}
    for index, name in enumerate(joint_names):
        found = _classify(name)
        if found is None:
            continue
        side, part, rank = found
        marker = f"{side}_{part}" if side else part
        if marker not in best or rank < best[marker][0]:
            best[marker] = (rank, index)
    markers = {marker: index for marker, (_, index) in best.items()}
    if {"left_shoulder", "right_shoulder", "neck", "pelvis"} <= set(markers):
        lca = _common_ancestor(parents, markers["left_shoulder"], markers["right_shoulder"])
        above_pelvis = lca != markers["pelvis"] and _common_ancestor(
            parents, lca, markers["pelvis"]) == markers["pelvis"]
        below_neck = lca != markers["neck"] and _common_ancestor(
            parents, lca, markers["neck"]) == lca
        if lca >= 0 and above_pelvis and below_neck:
            markers["thorax"] = lca
    used = set(markers.values())
    return markers, tuple(name for index, name in enumerate(joint_names) if index not in used)


def _generic_indices(motion: Motion, names: tuple[str, ...]) -> np.ndarray:
    markers, unrecognised = recognise_markers(motion.joint_names, motion.parents)
    missing = []
    for marker in names:
        if marker not in _GENERIC_WORDS:
            missing.append(f"{marker} (not a marker known to rig {motion.rig!r})")
        elif marker not in markers:
            side, words = _GENERIC_WORDS[marker]
            prefix = side.capitalize() if side else ""
            spelled = " or ".join(f"{prefix}{word}" for word in words)
            where = (" (or its side written L_, _L, .L)" if side else "")
            thorax = "the joint both shoulders hang from, or " if marker == "thorax" else ""
            missing.append(f"{marker} (looked for {thorax}a joint named {spelled}{where})")
    if missing:
        others = ", ".join(unrecognised) if unrecognised else "none"
        raise MarkerMapError(f"rig {motion.rig!r} ({motion.source}) cannot supply markers: "
                             + "; ".join(missing) + f"; joints not recognised: {others}")
    return np.array([markers[marker] for marker in names], dtype=int)


def marker_joint_indices(motion: Motion, names: tuple[str, ...] = HUMANEVA_15) -> np.ndarray:
    """Index into `motion.joint_names` of the joint behind each marker: `(markers,)` ints.

    A known rig uses its map in ``RIG_MARKER_MAPS``; any other (``generic_bvh``) has its joints
    recognised by name (:func:`recognise_markers`).

    Raises:
        MarkerMapError: one message naming every marker that could not be mapped and the
            joints looked for (and, for a rig recognised by name, the joints not recognised).
    """
    if motion.rig == "generic_bvh":
        return _generic_indices(motion, names)
    rig_map = RIG_MARKER_MAPS.get(motion.rig)
    if rig_map is None:
        raise MarkerMapError(f"no marker map for rig {motion.rig!r} ({motion.source}); "
                             f"known rigs: {sorted(RIG_MARKER_MAPS)}")
    position = {name: i for i, name in enumerate(motion.joint_names)}
    indices, missing = [], []
    for marker in names:
        candidates = rig_map.get(marker)
        if candidates is None:
            missing.append(f"{marker} (not a marker known to rig {motion.rig!r})")
            continue
        candidates = (candidates,) if isinstance(candidates, str) else candidates
        found = next((position[c] for c in candidates if c in position), None)
        if found is None:
            missing.append(f"{marker} (looked for joint {' or '.join(candidates)})")
        indices.append(found)
    if missing:
        raise MarkerMapError(f"rig {motion.rig!r} ({motion.source}) cannot supply markers: "
                             + "; ".join(missing))
    return np.array(indices, dtype=int)


def marker_positions(motion: Motion, names: tuple[str, ...] = HUMANEVA_15) -> np.ndarray:
    """Marker trajectories of a motion: `(time, markers, 3)` metres, Y up, ordered as `names`."""
    return motion.positions[:, marker_joint_indices(motion, names)]
