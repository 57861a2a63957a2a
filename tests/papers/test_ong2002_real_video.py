"""The linear-combination real-video benchmark's scoring of a ``track.json`` (the benchmark
itself tracks four videos and is a script, not a test)."""

import numpy as np

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.evaluation.reference import CameraReference
from papers.ong2002.real_video import hands_error, score_track


def test_hands_are_scored_under_the_better_assignment():
    truth = np.array([[[0.0, 0.0], [10.0, 0.0]]])
    np.testing.assert_allclose(hands_error(truth[:, ::-1], truth), [[0.0, 0.0]])
    np.testing.assert_allclose(hands_error(truth + [0.0, 3.0], truth), [[3.0, 3.0]])


def _record(skeletons, chosen, joints, worlds=None):
    """A two-view track.json whose views report ``skeletons[view][t]`` (neck-relative) and, in
    the world's axes, ``worlds[view][t]`` (default the same)."""
    worlds = skeletons if worlds is None else worlds
    frames = []
    for t, pick in enumerate(chosen):
        views = [{"head": [100.0 + view, 50.0], "hands": [[80.0, 120.0], [120.0, 120.0]],
                  "skeleton_m": dict(zip(joints, skeletons[view][t].tolist(), strict=True)),
                  "skeleton_world_m": dict(zip(joints, worlds[view][t].tolist(), strict=True))}
                 for view in range(len(skeletons))]
        frames.append({"frame": t + 1, "views": views, "selected_view": pick})
    return {"joints": joints, "views": [{"camera": "a"}, {"camera": "b"}], "frames": frames}


def test_a_track_is_scored_in_2d_and_3d_and_its_view_selection_against_best_and_worst():
    rng = np.random.default_rng(0)
    num = 4
    world = rng.normal(size=(num, 12, 3))
    markers = np.zeros((num, 12, 2))
    head, neck, pelvis = (UPPER_BODY_12.index(name) for name in ("head", "neck", "pelvis"))
    markers[:, head] = [100.0, 50.0]
    markers[:, neck] = [100.0, 60.0]
    markers[:, pelvis] = [100.0, 160.0]  # torso 100 px
    markers[:, UPPER_BODY_12.index("right_wrist")] = [120.0, 120.0]
    markers[:, UPPER_BODY_12.index("left_wrist")] = [80.0, 120.0]
    frames = np.arange(1, num + 1)
    reference = CameraReference("a", markers, np.zeros((num, 21, 2)), frames, frames - 1,
                                np.ones((num, 21)))
    references = {"a": reference, "b": CameraReference("b", *list(vars(reference).values())[1:])}
    joints = list(reversed(UPPER_BODY_12))  # the record's own joint order
    order = [UPPER_BODY_12.index(name) for name in joints]
    # view a: the truth turned and scaled (0 after alignment); view b: the truth plus noise
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    exact = 2.0 * world @ turn.T
    noisy = world + rng.normal(scale=0.2, size=world.shape)
    skeletons = [exact[:, order], noisy[:, order]]
    # in jaxtrack track's Y-up world (the reference is Z-up: (X, Y, Z) is (X, Z, −Y)),
    # neck-relative: view a exact, view b 0.1 m off along x
    y_up = world[..., [0, 2, 1]] * [1.0, 1.0, -1.0]
    y_up = y_up - y_up[:, neck:neck + 1]
    worlds = [y_up[:, order], (y_up + [0.1, 0.0, 0.0])[:, order]]
    record = _record(skeletons, [0, 1, None, 1], joints, worlds)
    scores = score_track(record, references, world, frames, mean_skeleton=world[0, order])
    assert scores["views"]["a"]["raw_3d_error_mm"] < 1e-6
    np.testing.assert_allclose(scores["views"]["b"]["raw_3d_error_mm"], 100.0)
    assert scores["selection"]["raw_oracle_mm"] < 1e-6
    np.testing.assert_allclose(scores["selection"]["raw_selected_mm"], 200.0 / 3)
    np.testing.assert_allclose(scores["selection"]["raw_worst_mm"], 100.0)
    assert scores["frames"] == num
    assert scores["views"]["a"]["aligned_3d_error_mm"] < 1e-6
    assert scores["views"]["b"]["aligned_3d_error_mm"] > 10.0
    np.testing.assert_allclose(scores["views"]["a"]["head_error_torso"], 0.0)
    np.testing.assert_allclose(scores["views"]["b"]["head_error_torso"], 0.01)
    np.testing.assert_allclose(scores["views"]["a"]["hand_error_torso"], 0.0)
    selection = scores["selection"]
    assert selection["frames"] == 3 and selection["times_selected"] == {"a": 1, "b": 2}
    assert selection["oracle_mm"] < 1e-6
    assert selection["oracle_mm"] < selection["selected_mm"] < selection["worst_mm"]
    assert scores["constant_mean_skeleton_mm"] > 0.0


def test_a_take_without_reference_is_summarised_per_view():
    from papers.ong2002.real_video import unscored_summary

    def view(observed, ambiguity):
        return {"observed": observed, "ambiguity": ambiguity}

    record = {"views": [{"camera": "a", "crop_from_silhouettes": 3},
                        {"camera": "b", "crop_from_silhouettes": 2}],
              "frames": [{"views": [view(True, 0.2), view(True, 0.6)], "selected_view": 0},
                         {"views": [view(True, 0.4), view(False, None)], "selected_view": 0},
                         {"views": [view(False, None), view(False, None)],
                          "selected_view": None}]}
    summary = unscored_summary(record)
    assert summary["frames"] == 3 and summary["no_view_observed"] == 1
    a, b = summary["views"]["a"], summary["views"]["b"]
    assert (a["observed"], a["selected"], b["observed"], b["selected"]) == (2, 2, 1, 0)
    np.testing.assert_allclose([a["mean_ambiguity"], b["mean_ambiguity"]], [0.3, 0.6])
    assert a["crop_from_silhouettes"] == 3
