"""The prior-generalisation benchmark's reconstructions: nearest pose, per part, given lengths."""

import numpy as np
import pytest

from jaxtrack.data.splits import split_of
from papers.tian2005.prior_generalisation import (
    held_out_clips,
    latent_smoothness,
    marker_speed,
    nearest_per_part,
    nearest_reconstruction,
    walk_steps,
    with_lengths_of,
)


def test_nearest_reconstruction_picks_the_closest_training_row():
    train = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    test = np.array([[9.0, 1.0], [1.0, 8.0], [0.2, -0.1]])
    np.testing.assert_array_equal(nearest_reconstruction(train, test), train[[1, 2, 0]])


def test_nearest_per_part_combines_parts_of_different_training_poses():
    rng = np.random.default_rng(0)
    first, second = rng.normal(size=22), rng.normal(size=22)
    # a held-out pose with the first pose's torso and right arm and the second's left arm
    mixed = first.copy()
    left_arm = [i for link in (7, 8, 9) for i in (2 * link, 2 * link + 1)]
    mixed[left_arm] = second[left_arm]
    train = np.stack([first, second])
    np.testing.assert_allclose(nearest_per_part(train, mixed[None])[0], mixed)
    # the whole-body nearest pose cannot make that combination
    assert not np.allclose(nearest_reconstruction(train, mixed[None])[0], mixed)


def test_with_lengths_of_keeps_directions_and_takes_the_reference_lengths():
    features = np.array([[3.0, 4.0] * 11])
    reference = np.array([[0.0, 2.0] * 11])
    out = with_lengths_of(features, reference).reshape(11, 2)
    np.testing.assert_allclose(out, np.tile([1.2, 1.6], (11, 1)))


def test_held_out_clips_are_the_splits_gesture_clips():
    clips = held_out_clips("validation")
    assert clips and {split_of(clip) for clip in clips} == {"validation"}
    assert all(clip.split("/")[0] in ("animateddrawings", "bandai") for clip in clips)


def test_a_clip_outside_the_split_is_refused_in_one_line(capsys):
    from papers.tian2005.prior_generalisation import main

    with pytest.raises(SystemExit):
        main(["--split", "validation", "--clips", "animateddrawings/fair1_wave_hello"])
    assert "not a gesture clip of the validation split" in capsys.readouterr().err


def test_the_diagnosis_variants_each_change_one_setting():
    from papers.tian2005.latent_diagnosis import variants

    rows = variants()
    assert rows[0] == ("default", {}, 1.0, 1.0)
    for name, options, sharpness, step in rows[1:]:
        changed = bool(options) + (sharpness != 1.0) + (step != 1.0)
        assert changed == 1, name


def test_latent_smoothness_tells_islands_from_smooth_trajectories():
    # two sequences: one moving smoothly along a line, one sitting on two islands, jumping
    # between them three times; steps between the sequences are not counted
    smooth = np.stack([np.linspace(0, 1, 50), np.zeros(50)], axis=1)
    islands = np.repeat([[0.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.0, 1.0]], [13, 12, 13, 12],
                        axis=0)
    ids = np.repeat([0, 1], 50)
    both = latent_smoothness(np.concatenate([smooth, islands]), ids)
    alone = latent_smoothness(smooth, np.zeros(50, int))
    spread = np.sqrt(np.linspace(0, 1, 50).var())
    np.testing.assert_allclose(alone["median_step"], (1 / 49) / spread)
    assert alone["carried"][0] > 0.99  # a constant step is carried on whole
    assert both["median_step"] < alone["median_step"]  # islands: most steps are zero
    assert both["p99_step"] > 1.0  # ... and a few are jumps across the space


def test_walk_steps_are_in_units_of_the_walk_and_stay_within_a_sequence():
    nu = np.array([0.1, 0.2])
    # sequence 0 steps (0.1, 0.2) = 1 ν per frame; sequence 1 jumps by 10 ν once
    walking = np.cumsum(np.tile(nu, (11, 1)), axis=0)
    jumping = np.repeat([[5.0, 5.0], [6.0, 7.0]], [5, 5], axis=0)
    steps = walk_steps(np.concatenate([walking, jumping]), np.repeat([0, 1], [11, 10]), nu)
    # 10 steps of 1 ν, 8 of 0 and one of 10 ν: the step between the sequences is not counted
    assert steps["median_nu"] == pytest.approx(1.0)
    assert steps["over_3nu"] == pytest.approx(1 / 19)
    assert steps["p99_nu"] > 3.0


def test_marker_speed_is_the_fastest_markers_move_over_the_torso():
    from jaxtrack.body import UPPER_BODY_12

    markers = np.zeros((4, 12, 2))
    markers[:, UPPER_BODY_12.index("pelvis"), 1] = 100.0  # a torso of 100 px
    markers[:, UPPER_BODY_12.index("right_wrist"), 0] = [0.0, 30.0, 60.0, 90.0]
    assert marker_speed(markers, np.zeros(4, int)) == pytest.approx(0.3)
    # a new sequence's first frame is no move
    assert marker_speed(markers, np.array([0, 0, 1, 1])) == pytest.approx(0.3)


def test_the_trajectory_plot_has_one_panel_per_prior(tmp_path):
    from papers.tian2005.prior_generalisation import plot_trajectories

    rng = np.random.default_rng(0)
    priors = {f"prior {k}": (rng.normal(size=(30, 2 + k)), np.repeat([0, 1, 2], 10))
              for k in range(5)}
    path = tmp_path / "trajectories.png"
    plot_trajectories(priors, path)
    assert path.stat().st_size > 10_000
