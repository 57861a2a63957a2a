"""Facts about the real clips that the body tests check, as their folders' SOURCE.txt state them."""

from __future__ import annotations

import numpy as np

from jaxtrack.body.markers import marker_positions
from jaxtrack.body.motion import Motion

# frames after which the subject stands upright, for the clips that start on the floor (every
# other clip starts standing). Times from SOURCE.txt; CMU posture clips lose their reference frame
# 0, so file time t is Motion frame 30 t - 1.
_UPRIGHT_FRAME = {
    "139_16": 158,  # cmu_posture_bvh: "5.3 s upright" after lying prone and kneeling
    "getup_facedown": 182,  # deepmimic_getup_bvh: "3.03 s standing upright", the last frame
    "crawl": None,  # deepmimic_getup_bvh: "prone throughout"
}


def upright_frame(stem: str) -> int | None:
    """A frame in which the subject stands upright, or None for a clip where they never do."""
    return _UPRIGHT_FRAME.get(stem, 0)


def knees_bend_backwards(motion: Motion, min_bend_degrees: float = 30.0) -> tuple[int, int]:
    """How many (knee, frame) pairs bend by more than `min_bend_degrees`, and in how many of them
    the knee's hinge axis (thigh x shin) points to the side the joint names call left.

    A knee only bends backwards, so thigh x shin points to the subject's left whatever the pose
    (standing, kneeling, lying): an anatomical left that does not depend on the joint names.
    """
    names = ("left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle")
    points = dict(zip(names, np.moveaxis(marker_positions(motion, names), 1, 0), strict=True))
    named_left = points["left_hip"] - points["right_hip"]
    bent = agreeing = 0
    for side in ("left", "right"):
        thigh = points[f"{side}_knee"] - points[f"{side}_hip"]
        shin = points[f"{side}_ankle"] - points[f"{side}_knee"]
        cosine = np.sum(thigh * shin, -1) / (np.linalg.norm(thigh, axis=-1)
                                            * np.linalg.norm(shin, axis=-1))
        is_bent = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))) > min_bend_degrees
        points_left = np.sum(np.cross(thigh, shin) * named_left, -1) > 0
        bent += int(is_bent.sum())
        agreeing += int((is_bent & points_left).sum())
    return bent, agreeing


def one_take_per_hdm05_actor(shared: dict) -> dict:
    """``shared`` without HDM05's takes beyond the first of each actor (every HDM05 take is the
    same rig and exporter; its 127 takes at 120 Hz would otherwise dominate a test's time)."""
    kept, actors = {}, set()
    for name, file in shared.items():
        if name.startswith("hdm05_cut/"):
            actor = name.rsplit("/", 1)[-1].split("_")[1]
            if actor in actors:
                continue
            actors.add(actor)
        kept[name] = file
    return kept


def shared_clip_params(shared: dict) -> list:
    """``pytest.param`` per shared clip, ``id="shared:<name>"``. HDM05's 127 takes share five
    skeletons and one exporter: one take per actor runs in the default suite, the rest are
    marked ``slow`` (``pytest -m slow``) so that every take is still checked."""
    import pytest

    params, actors = [], set()
    for name, file in shared.items():
        marks = ()
        if name.startswith("hdm05_cut/"):
            actor = name.rsplit("/", 1)[-1].split("_")[1]
            marks = (pytest.mark.slow,) if actor in actors else ()
            actors.add(actor)
        params.append(pytest.param(file, id=f"shared:{name}", marks=marks))
    return params
