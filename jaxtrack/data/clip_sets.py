"""The named clip sets of the latent tracker's studies (``papers/tian2005``): which clips train
the pose prior and which gesture clips of each split's subjects are tracked.

Every set keeps to the subject splits of :mod:`jaxtrack.data.splits`: the prior's clips are
training subjects', the tracked clips validation or test subjects'.

    >>> from jaxtrack.data.clip_sets import GESTURE_CLIPS, TRAINING_CLIPS
    >>> from jaxtrack.data.splits import split_of
    >>> {split_of(clip) for clip in TRAINING_CLIPS}, {split_of(c) for c in GESTURE_CLIPS["test"]}
    ({'training'}, {'test'})
"""

from __future__ import annotations

from jaxtrack.data.splits import clips_in

_HISTORY = "animateddrawings/history_c119d6b/"

TRAINING_CLIPS = ("animateddrawings/fair1_wave_hello", _HISTORY + "8yr_old_wave_hello")
"""The prior's training clips: the wave gestures of the training subjects (bundled, MIT)."""

PRIOR_CLIPS = {
    "waves": TRAINING_CLIPS,
    "gestures": clips_in("training", "animateddrawings"),
}
"""Candidate training sets for the prior, all of training subjects: ``waves`` (two subjects'
waves) and ``gestures`` (every AnimatedDrawings clip of the training subjects: waves, dab,
jumping, zombie, jumping jacks and walks with a clap, a point, raise-the-roof and a side punch;
four subjects)."""

GESTURE_CLIPS = {
    "validation": ("bandai/dataset-2_wave-right-hand_normal_001",
                   "bandai/dataset-2_wave-left-hand_normal_001",
                   "bandai/dataset-2_raise-up-right-hand_normal_001"),
    "test": (_HISTORY + "cmu_1006_wave_hello_1", _HISTORY + "cmu_1006_wave_hello_2"),
}
"""Upper-body gesture clips of each split's subjects (the Bandai validation clips are the three
kept in ``tests/data``, so validation runs from a source checkout without ``../shared``)."""

_BANDAI = "bandai/dataset-2_"
WIDE_VALIDATION_CLIPS = GESTURE_CLIPS["validation"] + tuple(_BANDAI + name for name in (
    "wave-right-hand_active_001", "wave-right-hand_elderly_001", "wave-right-hand_youthful_001",
    "wave-both-hands_normal_001", "raise-up-both-hands_normal_001", "wave-left-hand_normal_002"))
"""The three validation clips and six more of the validation subject's upper-body gestures from
``../shared/data`` (the right-hand wave in three more styles, both hands waving and raised, the
left-hand wave's second take): one clip of every gesture and style the Bandai source holds
beside the three. The three alone favour the latent tracker (papers/tian2005/history.md, "Six
more of the validation subject's clips")."""

QUICK_TRAINING = {"views": 2, "fps": 10.0, "active_size": 60, "iterations": 1}
"""``train_prior`` settings of a small prior for smoke runs: 2 views, 10 fps, 60 active points,
one outer iteration."""

__all__ = ["GESTURE_CLIPS", "PRIOR_CLIPS", "QUICK_TRAINING", "TRAINING_CLIPS",
           "WIDE_VALIDATION_CLIPS"]
