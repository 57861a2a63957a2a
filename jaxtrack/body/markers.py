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

import numpy as np

from jaxtrack.body.motion import Motion

__all__ = [
    "HUMANEVA_15", "UPPER_BODY_12", "MARKER_EDGES", "RIG_MARKER_MAPS", "MarkerMapError",
    "marker_edges", "marker_joint_indices", "marker_positions",
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
    # any other BVH: the Mixamo/MotionBuilder names most exporters use; first joint found wins
    "generic_bvh": {
        "head": ("Head", "head"), "neck": ("Neck", "neck", "Neck1"),
        "thorax": ("Spine2", "Chest", "Spine1", "spine2", "chest"),
        "pelvis": ("Hips", "hips", "Pelvis", "pelvis", "Root"),
        **{f"{side}_{part}": tuple(f"{prefix}{name}" for name in names
                                   for prefix in (side.capitalize(), side))
           for side in _SIDES
           for part, names in {"shoulder": ("Arm", "UpArm", "Shoulder"),
                               "elbow": ("ForeArm", "LowArm", "Elbow"),
                               "wrist": ("Hand", "Wrist"), "hip": ("UpLeg", "Hip", "UpperLeg"),
                               "knee": ("Leg", "Knee", "LowLeg", "LowerLeg"),
                               "ankle": ("Foot", "Ankle")}.items()},
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


def marker_joint_indices(motion: Motion, names: tuple[str, ...] = HUMANEVA_15) -> np.ndarray:
    """Index into `motion.joint_names` of the joint behind each marker: `(markers,)` ints."""
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
