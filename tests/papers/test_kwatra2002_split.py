"""Part 2's split by actor: no actor on two sides; the bootstrap interval over takes."""

import numpy as np
import pytest

from papers.kwatra2002.held_out import SPLIT, bootstrap_interval, check_split


def test_no_actor_is_on_two_sides_of_the_split():
    check_split(SPLIT)
    sides = [set(actors) for actors in SPLIT.values()]
    assert all(not (a & b) for i, a in enumerate(sides) for b in sides[i + 1:])
    assert set().union(*sides) == {"bd", "bk", "dg", "mm", "tr"}
    with pytest.raises(ValueError, match="'mm' is on two sides"):
        check_split({"train": ("bd", "mm"), "validation": ("mm",), "test": ("tr",)})
    with pytest.raises(ValueError, match="has no actor"):
        check_split({"train": ("bd",), "validation": (), "test": ("tr",)})


def test_bootstrap_interval_over_takes():
    rng = np.random.default_rng(0)
    takes = [rng.normal(10.0, 1.0, size=50) for _ in range(8)]
    low, high = bootstrap_interval(takes)
    pooled = np.concatenate(takes).mean()
    assert low < pooled < high and high - low < 1.0
    # one take alone: every resample is that take, the interval a point
    assert bootstrap_interval([np.full(5, 3.0)]) == [3.0, 3.0]


def test_the_mixed_state_evaluations_clips_share_no_person_across_splits():
    """The rendered evaluation (papers.kwatra2002.mixed_state_evaluation): training clips of
    training subjects, validation of validation subjects, test of test subjects, by
    jaxtrack.data.splits; and the test side holds a person who lies down (CMU 139, HDM05 tr)."""
    from jaxtrack.data.splits import split_of, subject_of
    from jaxtrack.experiments import mixed_state as ms

    sides = {"training": ms.TRAINING_CLIPS, "validation": ms.VALIDATION_CLIPS,
             "test": ms.TEST_CLIPS}
    for split, clips in sides.items():
        assert [split_of(clip) for clip in clips] == [split] * len(clips), split
    people = {split: {subject_of(clip) for clip in clips} for split, clips in sides.items()}
    assert not (people["training"] & people["validation"] or people["training"] & people["test"]
                or people["validation"] & people["test"])
    assert {"cmu:139", "hdm05:tr"} <= people["test"] and "hdm05:mm" in people["validation"]
