"""The splits by subject: every catalogue clip has one subject, and a subject one split."""

import pytest

from jaxtrack.data import list_clips
from jaxtrack.data.splits import (
    SPLITS,
    SUBJECTS,
    UnknownSubjectError,
    check_disjoint,
    clips_in,
    split_of,
    subject_of,
    subjects_in,
)


def test_every_catalogue_clip_has_a_subject():
    for clip in list_clips():
        assert split_of(clip) in SPLITS, clip


def test_a_clip_is_claimed_by_one_subject_and_every_split_is_used():
    clips = [clip for _, (_, declared) in SUBJECTS.items() for clip in declared]
    assert len(clips) == len(set(clips))
    for split in SPLITS:
        assert subjects_in(split)
    assert set(clips_in("training")).isdisjoint(clips_in("test"))


def test_the_demo_and_protocol_test_takes_are_held_out_subjects():
    assert split_of("animateddrawings/history_c119d6b/cmu_1006_wave_hello_2") == "test"
    assert split_of("animateddrawings_bvh/history_c119d6b/cmu_1006_wave_hello_1.bvh") == "test"
    assert split_of("animateddrawings/fair1_wave_hello") == "training"
    assert split_of("bandai/dataset-2_wave-right-hand_active_001") == "validation"


def test_training_and_evaluated_clips_must_not_share_a_subject():
    check_disjoint(clips_in("training", "animateddrawings"), clips_in("test", "animateddrawings"))
    with pytest.raises(ValueError, match="animateddrawings:cmu_1006 is in both"):
        check_disjoint(["animateddrawings/history_c119d6b/cmu_1006_wave_hello_1"],
                       ["animateddrawings/history_c119d6b/cmu_1006_wave_hello_2"])
    # a user's own file is in no split and is not checked
    check_disjoint(["/tmp/my_own.bvh"], ["animateddrawings/fair1_wave_hello"])


def test_unknown_clips_and_splits_are_refused_clearly():
    with pytest.raises(UnknownSubjectError, match="belongs to no subject"):
        subject_of("/data/someone.bvh")
    with pytest.raises(ValueError, match="split must be one of"):
        clips_in("train")
