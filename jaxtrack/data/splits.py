"""Training, validation and test subjects: the one place that says which person is in which split.

A claim about tracking is a claim about people the prior has never seen, so clips are split by
**subject** (the person captured), never by take: every take of a subject is in the same split.
Settings are chosen on ``"validation"``; ``"test"`` is only ever scored. Each default in
jaxtrack says in its docstring which split chose it.

Subjects are named ``<source>:<person>``. Where a source does not publish who performed a clip
(Bandai-Namco dataset-2 lists styles, not actors), the whole source is one subject, so no actor
can be on both sides of a split. The assignment (docs/tracking.md, "Splits by subject"):

=============  ===================================================================================
split          subjects
=============  ===================================================================================
training       AnimatedDrawings fair1 (wave, dab, jumping, zombie), cmu1 (jumping jacks), the
               8-year-old (wave), cmu_new (walks with point, clap, raise the roof, side punch);
               CMU 07 (walks); CMU 75 (sit at three heights) and 64 (stoop); DeepMimic's humanoid
               (get-up, crawl, roll); HDM05 actors bd, bk, dg (lie down, squat, crouch, reach,
               arm circles, elbow to knee)
validation     Bandai-Namco dataset-2 (professional actors: waves, raise-ups, walks, styles);
               CMU 02 (walk); CMU 77 (half-crouch); HDM05 actor mm
test           AnimatedDrawings cmu_1006 (two waves); CMU 131 (stylised walk, stop, hop); CMU 139
               (lying face down → all fours → kneel → stand); the man of the Pose2Sim demo videos
               (real video, four cameras; single- and multi-person takes); HDM05 actor tr
=============  ===================================================================================

Real video has no validation subject: the only real videos with a reference show the test
subject, so settings for real video are chosen on rendered validation clips.

The mixed-state evaluation's clips (``jaxtrack.experiments.mixed_state``) follow this split
too: HDM05 actor mm (with CMU 77 and 02) on the validation side, HDM05 actor tr and CMU 139 (with
CMU 131) on the test side. Until 2026-11-29 clips of training subjects (CMU 75, DeepMimic) were
held out by clip instead, for want of other people who sit and lie down.

    >>> from jaxtrack.data.splits import split_of, clips_in
    >>> split_of("animateddrawings/history_c119d6b/cmu_1006_wave_hello_2")
    'test'
    >>> clips_in("training", "animateddrawings")[:2]
    ('animateddrawings/cmu1_jumping_jacks', 'animateddrawings/fair1_dab')
"""

from __future__ import annotations

import re
from collections.abc import Iterable

__all__ = ["SPLITS", "SUBJECTS", "UnknownSubjectError", "check_disjoint", "clips_in",
           "split_of", "subject_of", "subjects_in"]

SPLITS = ("training", "validation", "test")

_AD = "animateddrawings/"
_HISTORY = _AD + "history_c119d6b/"

_HDM05_TAKES = {  # actor: {class: takes} of ../shared/data/hdm05_cut (its SOURCE.txt)
    "bd": {"depositFloorR": "001-003", "elbowToKnee1RepsLelbowStart": "001-006",
           "grabHighR": "001-004", "lieDownFloor": "001-004",
           "rotateArmsBothBackward1Reps": "001-004", "squat1Reps": "001-004"},
    "bk": {"depositFloorR": "007-009", "elbowToKnee1RepsLelbowStart": "007-012",
           "grabHighR": "005-010", "lieDownFloor": "005-010",
           "rotateArmsBothBackward1Reps": "005-008", "squat1Reps": "013-016"},
    "dg": {"depositFloorR": "013-015", "elbowToKnee1RepsLelbowStart": "013-018",
           "grabHighR": "011-016", "lieDownFloor": "011-014",
           "rotateArmsBothBackward1Reps": "009-010", "squat1Reps": "025-028"},
    "mm": {"depositFloorR": "019-021", "elbowToKnee1RepsLelbowStart": "019-020",
           "grabHighR": "017-022", "lieDownFloor": "015-018",
           "rotateArmsBothBackward1Reps": "011-013", "squat1Reps": "037-040"},
    "tr": {"depositFloorR": "027-029", "elbowToKnee1RepsLelbowStart": "021-027",
           "grabHighR": "023-029", "lieDownFloor": "019-020",
           "rotateArmsBothBackward1Reps": "014-016", "squat1Reps": "041-044"},
}
_HDM05_SPLIT = {"bd": "training", "bk": "training", "dg": "training", "mm": "validation",
                "tr": "test"}  # hdm05_cut's SOURCE.txt's split by actor


def _hdm05_clips(actor: str) -> tuple[str, ...]:
    """Catalogue names of one HDM05 actor's takes."""
    clips = []
    for kind, takes in _HDM05_TAKES[actor].items():
        first, last = (int(value) for value in takes.split("-"))
        clips += [f"hdm05_cut/{kind}/HDM_{actor}_{kind}_{take:03d}_120"
                  for take in range(first, last + 1)]
    return tuple(clips)


SUBJECTS: dict[str, tuple[str, tuple[str, ...]]] = {
    # subject: (split, catalogue clips)
    "animateddrawings:fair1": ("training", (
        _AD + "fair1_wave_hello", _AD + "fair1_dab", _AD + "fair1_jumping", _AD + "fair1_zombie")),
    "animateddrawings:cmu1": ("training", (_AD + "cmu1_jumping_jacks",)),
    "animateddrawings:8yr_old": ("training", (_HISTORY + "8yr_old_wave_hello",)),
    "animateddrawings:cmu_new": ("training", tuple(
        _HISTORY + f"cmu_new_walk_{gesture}"
        for gesture in ("clap", "point", "raise_the_roof", "side_punch"))),
    "cmu:07": ("training", tuple(f"cmu_amc/07_{take}" for take in ("01", "02", "09", "10", "11"))),
    "cmu:75": ("training", tuple(f"cmu_posture_bvh/75_{take}" for take in ("17", "19", "20"))),
    "cmu:64": ("training", ("cmu_posture_bvh/64_26",)),
    "deepmimic:humanoid": ("training", tuple(
        f"deepmimic_getup_bvh/{clip}" for clip in ("getup_facedown", "crawl", "roll"))),
    "bandai:dataset-2": ("validation", tuple(
        f"bandai/dataset-2_{content}_{style}_{take}" for content, style, take in (
            ("raise-up-both-hands", "normal", "001"), ("raise-up-both-hands", "normal", "002"),
            ("raise-up-right-hand", "normal", "001"), ("raise-up-right-hand", "normal", "002"),
            ("walk", "normal", "001"), ("walk", "normal", "002"),
            ("wave-both-hands", "normal", "001"), ("wave-both-hands", "normal", "002"),
            ("wave-left-hand", "normal", "001"), ("wave-left-hand", "normal", "002"),
            ("wave-right-hand", "active", "001"), ("wave-right-hand", "elderly", "001"),
            ("wave-right-hand", "normal", "001"), ("wave-right-hand", "normal", "002"),
            ("wave-right-hand", "youthful", "001")))),
    "cmu:02": ("validation", ("cmu_amc/02_01",)),
    "cmu:77": ("validation", ("cmu_posture_bvh/77_07",)),
    "animateddrawings:cmu_1006": ("test", (
        _HISTORY + "cmu_1006_wave_hello_1", _HISTORY + "cmu_1006_wave_hello_2")),
    "cmu:131": ("test", tuple(f"cmu_bvh/131_{take}" for take in ("01", "02", "03"))),
    "cmu:139": ("test", ("cmu_posture_bvh/139_16",)),
    "pose2sim:man": ("test", ("pose2sim/videos/cam01", "pose2sim/videos/cam02",
                              "pose2sim/videos/cam03", "pose2sim/videos/cam04")),
    **{f"hdm05:{actor}": (split, _hdm05_clips(actor)) for actor, split in _HDM05_SPLIT.items()},
}
"""Every known subject: its split and its clips (catalogue names; the Pose2Sim entries name the
real videos, whose reference keypoints are the ground truth)."""


class UnknownSubjectError(KeyError):
    """A clip that no subject of :data:`SUBJECTS` claims (a user's own file, a new clip)."""

    def __str__(self) -> str:
        return str(self.args[0])


_CLIP_SUBJECT = {clip: subject for subject, (_, clips) in SUBJECTS.items() for clip in clips}


def _normalise(clip: str) -> str:
    name = clip.replace("\\", "/").strip("/")
    name = re.sub(r"\.(bvh|amc|mp4)$", "", name, flags=re.IGNORECASE)
    for folder, collection in (("animateddrawings_bvh/", _AD),
                               ("bandai_namco_gestures/", "bandai/"),
                               ("cmu_asfamc_walk/", "cmu_amc/"), ("cmu_bvh_131/", "cmu_bvh/"),
                               ("pose2sim_demo_singleperson/", "pose2sim/")):
        if name.startswith(folder):
            name = collection + name[len(folder):]
    return name


def subject_of(clip: str) -> str:
    """The subject who performed a catalogue clip.

    Raises:
        UnknownSubjectError: the clip is in no split (a file of your own: you know its subject).
    """
    name = _normalise(clip)
    if name not in _CLIP_SUBJECT:
        raise UnknownSubjectError(
            f"clip {clip!r} belongs to no subject in jaxtrack.data.splits.SUBJECTS; a file of "
            "your own is in no split, so say yourself which split it is")
    return _CLIP_SUBJECT[name]


def split_of(clip: str) -> str:
    """``"training"``, ``"validation"`` or ``"test"``: the split of a catalogue clip's subject."""
    return SUBJECTS[subject_of(clip)][0]


def _check_split(split: str) -> None:
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")


def subjects_in(split: str) -> tuple[str, ...]:
    """The subjects of one split, in declaration order."""
    _check_split(split)
    return tuple(subject for subject, (where, _) in SUBJECTS.items() if where == split)


def clips_in(split: str, *collections: str) -> tuple[str, ...]:
    """The clips of one split (sorted), optionally only those of the given collections
    (``"animateddrawings"``, ``"bandai"``, ``"cmu_amc"``, ``"cmu_posture_bvh"``, ...)."""
    _check_split(split)
    clips = [clip for subject in subjects_in(split) for clip in SUBJECTS[subject][1]]
    if collections:
        clips = [clip for clip in clips if clip.split("/")[0] in collections]
    return tuple(sorted(clips))


def check_disjoint(training: Iterable[str], evaluated: Iterable[str]) -> None:
    """Refuse an evaluation whose clips share a subject with the training clips.

    Clips of no known subject (a user's own files) are not checked.

    Raises:
        ValueError: naming the shared subject and the clips on each side.
    """
    def known(clips):
        found = {}
        for clip in clips:
            try:
                found.setdefault(subject_of(clip), []).append(clip)
            except UnknownSubjectError:
                pass
        return found

    trained, scored = known(training), known(evaluated)
    shared = sorted(set(trained) & set(scored))
    if shared:
        subject = shared[0]
        raise ValueError(
            f"subject {subject} is in both the training clips ({', '.join(trained[subject])}) "
            f"and the evaluated clips ({', '.join(scored[subject])}): score people the prior "
            "has never seen (jaxtrack.data.splits)")
