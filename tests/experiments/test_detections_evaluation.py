"""The detections' evaluation: its scores on estimates of known error, every baseline row on a
constructed four-view setting (exact projections of a known motion, plus noise), the hook for
more rows, and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12, look_at
from jaxtrack.body._staging import project_numpy
from jaxtrack.experiments.detections_evaluation import (
    PAPER_ROWS,
    Setting,
    _hand_set,
    _view_detections,
    _with_prior,
    add_rows,
    beaten_by,
    evaluate,
    latent_estimates,
    left_right_swaps,
    main,
    particle_filter_estimates,
    projected,
    score_2d,
    score_3d,
    score_rows,
    table,
    targets,
    triangulated,
    walk_steps,
)

NECK, PELVIS = UPPER_BODY_12.index("neck"), UPPER_BODY_12.index("pelvis")


def body_motion(frames: int = 40, fps: float = 60.0) -> np.ndarray:
    """(frames, 12, 3) metres: a fixed 12-marker body (torso 0.5 m) swaying slowly."""
    rng = np.random.default_rng(3)
    body = rng.uniform([-0.25, -0.15, 0.9], [0.25, 0.15, 1.7], (12, 3))
    body[NECK], body[PELVIS] = (0.0, 0.0, 1.5), (0.0, 0.0, 1.0)
    t = np.arange(frames) / fps
    sway = np.stack([0.1 * np.sin(2 * np.pi * 0.7 * t), 0.05 * np.cos(2 * np.pi * 0.5 * t),
                     np.zeros_like(t)], -1)
    return body[None] + sway[:, None]


def constructed_setting(noise_px: float = 0.0) -> Setting:
    cameras = [look_at(eye, (0.0, 0.0, 1.2), (0.0, 0.0, 1.0), 1000.0, (1080, 1920), name=f"v{i}")
               for i, eye in enumerate([(3.0, 0.0, 1.4), (0.0, 3.0, 1.6), (-3.0, 0.3, 1.2),
                                        (0.2, -3.0, 1.5)])]
    world = body_motion()
    truth = {camera.name: project_numpy(camera, world)[0] for camera in cameras}
    rng = np.random.default_rng(0)
    detections = {name: (points + rng.normal(0.0, noise_px, points.shape),
                         np.full(points.shape[:2], 0.9)) for name, points in truth.items()}
    views = tuple(truth)
    return Setting(views, np.arange(1, 41), 60.0, truth, world, detections, cameras,
                   {view: {} for view in views})


def test_the_scores_of_estimates_of_known_error():
    world = body_motion(frames=5)
    truth = project_numpy(look_at((3.0, 0, 1.4), (0, 0, 1.2), (0, 0, 1.0), 1000.0, (1080, 1920)),
                          world)[0]
    torso = np.linalg.norm(truth[:, NECK] - truth[:, PELVIS], axis=-1)
    shifted = truth + np.array([0.1, 0.0]) * torso[:, None, None]  # 10 % of the torso, along x
    scored = score_2d(shifted, truth)
    assert scored["error_torso"] == pytest.approx(0.1) and scored["within_15"] == 1.0
    assert score_2d(truth + np.array([0.2, 0.0]) * torso[:, None, None], truth)["within_15"] == 0
    shifted[2, 5] = np.nan  # a frame lacking a marker is not within and not averaged
    scored = score_2d(shifted, truth)
    assert scored["within_15"] == pytest.approx(0.8) and scored["frames_complete"] == 4
    world_scored = score_3d(world + np.array([0.0, 0.0, 0.05]), world)  # 5 cm, torso 0.5 m
    assert world_scored["error_mm"] == pytest.approx(50.0)
    assert world_scored["error_torso"] == pytest.approx(0.1)
    with pytest.raises(ValueError, match="must have shape"):
        score_2d(truth[:, :11], truth)
    # two frames with left and right exchanged are found, and undone
    names = list(UPPER_BODY_12)
    mirror = [names.index(n.replace("left", "@").replace("right", "left").replace("@", "right"))
              for n in names]
    swapped = truth.copy()
    swapped[[1, 3]] = truth[[1, 3]][:, mirror]
    found = left_right_swaps(swapped, truth)
    assert found["frames"] == 2 and found["error_torso_undone"] == pytest.approx(0.0)


def test_every_baseline_row_on_four_constructed_views():
    exact = evaluate(constructed_setting(0.0))
    for name in ("raw", "butterworth", "one-euro", "kalman-rts", "kalman-rts vis>=0.5"):
        assert exact["rows_2d"][name]["all"]["within_15"] > 0.9, name
    assert exact["rows_2d"]["raw"]["all"]["error_px"] == pytest.approx(0.0, abs=1e-9)
    assert exact["rows_3d"]["dlt"]["error_mm"] == pytest.approx(0.0, abs=1e-6)
    # noisy detections: the smoothers come nearer the truth than the raw detections
    noisy = evaluate(constructed_setting(8.0))
    raw = noisy["rows_2d"]["raw"]["all"]["error_px"]
    assert raw == pytest.approx(8.0 * np.sqrt(np.pi / 2), rel=0.1)  # Rayleigh mean of σ = 8
    for name in ("butterworth", "kalman-rts"):
        assert noisy["rows_2d"][name]["all"]["error_px"] < 0.7 * raw, name
    assert noisy["rows_3d"]["dlt+butterworth"]["error_mm"] < noisy["rows_3d"]["dlt"]["error_mm"]
    text = table(noisy)
    assert "| kalman-rts |" in text and "| dlt+butterworth |" in text


def test_more_rows_are_scored_as_the_baselines_are():
    setting = constructed_setting(2.0)
    results = evaluate(setting, extra_2d={"truth": setting.truth_2d},
                       extra_3d={"truth 3-D": setting.truth_3d})
    assert results["rows_2d"]["truth"]["all"]["error_px"] == pytest.approx(0.0)
    assert results["rows_3d"]["truth 3-D"]["within_15"] == 1.0
    with pytest.raises(ValueError, match="lacks views"):
        evaluate(setting, extra_2d={"half": {"v0": setting.truth_2d["v0"]}})


def test_the_targets_are_read_from_the_scores():
    setting = constructed_setting(6.0)
    raw = {view: setting.detections[view][0] for view in setting.views}
    # a "filter" that is the truth meets every target; one that is the raw detections shifted
    # by 40 px in one view misses them there, and the baselines that beat it are named
    shifted = {**raw, "v1": raw["v1"] + 40.0}
    rows = {"condensation random walk": setting.truth_2d, "condensation hand-set x1": raw,
            "condensation bad": shifted}
    results = evaluate(setting, extra_2d=rows,
                       extra_3d={f"dlt of {name}": triangulated(setting, per_view)
                                 for name, per_view in rows.items()})
    results["notes"]["particle_filters"] = {"speed": {"ms_per_frame": 7.5}}
    good = targets(results)
    assert good["within_15_every_view"]["met"] and good["error_against_butterworth"]["met"]
    assert good["3d_against_dlt"]["met"] and good["3d_against_dlt"]["value"] < 1e-6
    assert good["fitted_against_hand_set"]["met"] and not good["speed"]["met"]
    assert good["baselines_beating_the_filter"]["all"] == []
    bad = targets(results, "condensation bad")
    assert not bad["error_against_butterworth"]["met"] and not bad["3d_against_dlt"]["met"]
    assert bad["fitted_against_hand_set"]["value"]["v0"]["met"]  # the same as hand-set there
    assert not bad["fitted_against_hand_set"]["value"]["v1"]["met"]
    assert "butterworth" in bad["baselines_beating_the_filter"]["v1"]
    assert "dlt" in bad["baselines_beating_the_filter_3d"]
    with pytest.raises(ValueError, match="no row"):
        targets(results, "condensation absent")


def test_a_papers_rows_are_added_to_written_results_and_what_beats_them_is_named(tmp_path):
    from jaxtrack._files import write_json_atomically
    from jaxtrack.vision.smoothing import butterworth_filter

    setting = constructed_setting(6.0)
    raw = {view: setting.detections[view][0] for view in setting.views}
    rows_2d, rows_3d = score_rows(setting, {
        "raw": raw, "butterworth": {view: butterworth_filter(points, 60.0)
                                    for view, points in raw.items()},
        "condensation random walk": raw}, {"dlt": triangulated(setting, raw)})
    results = {"rows_2d": rows_2d, "rows_3d": rows_3d, "notes": {},
               "frames": [int(i) for i in setting.frame_indices]}
    path = tmp_path / "results.json"
    write_json_atomically(path, results)
    # a "tracker" 30 px off in one view and exact in the others: beaten there by the raw
    # detections and every smoother, by no one in the others; its own smoother is left out
    latent = PAPER_ROWS["tian2005"]
    rows = {latent: {**setting.truth_2d, "v2": setting.truth_2d["v2"] + 30.0},
            f"{latent} smoother": raw}
    merged = add_rows(path, setting, rows, notes_key="latent", notes={"particles": 8},
                      command="the command")
    written = json.loads(path.read_text())
    assert set(written["rows_2d"]) == set(results["rows_2d"]) | set(rows)
    assert written["rows_2d"]["raw"]["all"]["error_px"] == pytest.approx(
        merged["rows_2d"]["raw"]["all"]["error_px"])
    assert written["rows_2d"][latent]["v0"]["error_px"] == pytest.approx(0.0, abs=1e-9)
    assert f"dlt of {latent}" in written["rows_3d"]
    assert written["notes"]["latent"] == {"particles": 8}
    assert written["commands"]["latent"] == "the command"
    beaten = written["paper_priors"][latent]["beaten_by"]
    assert beaten["v0"] == [] and {"raw", "butterworth",
                                   "condensation random walk"} <= set(beaten["v2"])
    assert f"{latent} smoother" not in beaten["v2"]
    assert beaten == beaten_by(written, latent)
    # the SPM filter's targets count the paper's row as a tracker, not as a baseline
    assert latent not in written["targets"]["baselines_beating_the_filter"]["v0"]
    # a 3-D tracker's row (Ong & Gong's): its skeleton in 3-D, its projections in 2-D
    ong = PAPER_ROWS["ong2002"]
    world = setting.truth_3d + np.array([0.0, 0.0, 0.05])  # 5 cm up: 10 % of the torso
    both = add_rows(path, setting, {ong: projected(setting, world)}, rows_3d={ong: world},
                    notes_key="ong", notes={}, command="", triangulate=False)
    assert both["rows_3d"][ong]["error_mm"] == pytest.approx(50.0)
    assert f"dlt of {ong}" not in both["rows_3d"]
    assert 0.0 < both["rows_2d"][ong]["all"]["error_torso"] < 0.2
    # 6 px of noise triangulate to far less than 5 cm; a view 30 px off, to more
    assert set(both["paper_priors"][ong]["beaten_by_3d"]) == {"dlt", f"dlt of {latent} smoother"}
    assert latent in both["paper_priors"]  # the rows added before are kept
    # rows of other frames, or no results yet, are refused
    shorter = Setting(setting.views, setting.frame_indices[:-1], setting.fps, setting.truth_2d,
                      setting.truth_3d, setting.detections, setting.cameras, setting.detector)
    with pytest.raises(ValueError, match="other frames"):
        add_rows(path, shorter, rows, notes_key="latent", notes={}, command="")
    with pytest.raises(FileNotFoundError, match="run python -m"):
        add_rows(tmp_path / "none.json", setting, rows, notes_key="latent", notes={},
                 command="")


def test_the_particle_filter_inputs():
    setting = constructed_setting(0.0)
    points = setting.detections["v0"][0].copy()
    points[3] = np.nan  # a frame where the detector found no one
    setting = Setting(setting.views, setting.frame_indices, setting.fps, setting.truth_2d,
                      setting.truth_3d, {**setting.detections, "v0": (points,
                                                                     setting.detections["v0"][1])},
                      setting.cameras, setting.detector)
    detections = _view_detections(setting, "v0")
    assert detections.frame_size == (1080.0, 1920.0)
    assert detections.people.tolist() == [1] * 3 + [0] + [1] * 36
    assert np.all(detections.confidence[3] == 0)
    from jaxtrack.experiments.detection_tracking import detection_tracker

    tracker = detection_tracker(points[0], num_particles=8)
    velocity = _with_prior(tracker, (2.0, -1.0))
    assert np.all(np.asarray(velocity.dynamics.first_coefficients) == 2.0)
    assert np.all(np.asarray(velocity.dynamics.second_coefficients) == -1.0)
    assert np.array_equal(velocity.dynamics.noise_std, tracker.dynamics.noise_std)
    sharp = _hand_set(tracker, 16.0).likelihood.detections
    base = tracker.likelihood.detections
    assert np.allclose(sharp.joint_scales, base.joint_scales / 4.0)
    assert float(sharp.pixel_noise) == pytest.approx(float(base.pixel_noise) / 4.0)
    assert float(sharp.swap_probability) == float(base.swap_probability) > 0


def test_the_walk_steps_of_a_known_motion():
    points = constructed_setting(0.0).truth_2d["v0"][:10]
    still = walk_steps(np.repeat(points[:1], 10, axis=0))
    assert still["beyond_3_sigma"] == 0.0 and max(still["largest"].values()) < 1e-3
    torso = float(np.linalg.norm(points[0, NECK] - points[0, PELVIS]))
    # the whole pose moves 0.3 torso lengths a frame along x: 10 walk steps of 0.03
    moving = walk_steps(points[:1] + np.arange(10)[:, None, None] * np.array([0.3 * torso, 0.0]))
    assert moving["beyond_3_sigma"] == 1.0
    assert next(iter(moving["largest"])) == "translation_x"
    assert moving["largest"]["translation_x"] == pytest.approx(10.0, rel=0.3)


@pytest.mark.slow
def test_the_particle_filter_rows_follow_a_constructed_motion():
    full = constructed_setting(3.0)
    # one view and one prior: each fit compiles for minutes on a loaded 2-core machine
    setting = Setting(full.views[:1], full.frame_indices, full.fps,
                      {"v0": full.truth_2d["v0"]}, full.truth_3d,
                      {"v0": full.detections["v0"]}, full.cameras[:1], {"v0": {}})
    rows, notes = particle_filter_estimates(setting, particles=200, iterations=2,
                                            priors={"random walk": (1.0, 0.0)},
                                            weights=(1.0,), speed_particles=None)
    assert set(rows) == {"condensation random walk", "condensation random walk smoother",
                         "condensation random walk lag 5", "condensation hand-set x1"}
    # the slow sway (at most 0.6 px per frame) is followed: most frames within 15 % of the torso
    scored = score_2d(rows["condensation random walk"]["v0"], setting.truth_2d["v0"])
    assert scored["within_15"] > 0.8, scored
    fit = notes["fits"]["random walk"]["v0"]
    assert fit["fitted"]["swap_pairs"] == 4 and fit["fitted"]["swap_probability"] > 0
    assert fit["log_evidence_last"] > fit["log_evidence_first"] - 50.0


@pytest.mark.slow
def test_the_latent_rows_on_a_constructed_view():
    full = constructed_setting(3.0)
    setting = Setting(full.views[:1], full.frame_indices[:12], full.fps,
                      {"v0": full.truth_2d["v0"][:12]}, full.truth_3d[:12],
                      {"v0": tuple(a[:12] for a in full.detections["v0"])}, full.cameras[:1],
                      {"v0": {}})
    from jaxtrack.likelihoods.detections import detection_model

    rows, notes = latent_estimates(setting, particles=32, iterations=2, lag=2)
    name = PAPER_ROWS["tian2005"]
    assert set(rows) == {name, f"{name} all particles", f"{name} smoother", f"{name} lag 2"}
    for per_view in rows.values():
        assert per_view["v0"].shape == (12, 12, 2) and np.all(np.isfinite(per_view["v0"]))
    fit = notes["fits"]["v0"]
    # the same hand-set density as the SPM filter's, fitted from there
    assert fit["hand_set"]["joint_scales"] == [round(float(v), 4) for v in np.asarray(
        detection_model().joint_scales)]
    assert np.isfinite(fit["log_evidence_last"]) and fit["noise_factor"] > 0
    assert notes["refinement"] is None and all("wave" in clip for clip in notes["model_clips"])


@pytest.mark.slow
def test_the_latent_reach_of_poses_the_prior_draws_and_of_one_it_does_not():
    import jax
    import jax.numpy as jnp

    from jaxtrack.experiments.detections_evaluation import _latent_prior, latent_reach
    from jaxtrack.priors.poses import markers_from_features

    prior = _latent_prior(None).model
    features = jax.vmap(prior.mean)(prior.latents[::400][:6])  # six training poses' μ
    placement = jnp.array([np.log(150.0), 540.0, 700.0])
    drawn = np.asarray(jax.vmap(lambda f: markers_from_features(f, placement))(features),
                       np.float64)
    bent = drawn.copy()
    elbow, wrist = UPPER_BODY_12.index("right_elbow"), UPPER_BODY_12.index("right_wrist")
    bent[1:, wrist] = 2 * bent[1:, elbow] - bent[1:, wrist]  # the forearm folded back
    frames = len(drawn)
    setting = Setting(("drawn", "bent"), np.arange(frames), 60.0,
                      {"drawn": drawn, "bent": bent}, np.zeros((frames, 12, 3)),
                      {}, [], {})
    reach = latent_reach(setting)
    assert reach["drawn"]["error_torso"] < 0.01, reach
    assert reach["bent"]["error_torso"] > 0.05, reach  # 11 % when written


def test_bad_arguments_are_refused_in_one_line(capsys):
    with pytest.raises(SystemExit):
        main(["--json", "out.txt"])
    assert "give a .json file name" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--iterations", "0"])
    assert "--iterations must be a positive integer" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--min-confidence", "2"])
    assert "--min-confidence must lie in [0, 1]" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--add", "latent"])
    assert "--add latent: give --json with the results" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--latent-model", "no-such-prior.npz"])
    assert "--latent-model no-such-prior.npz:" in capsys.readouterr().err


@pytest.mark.slow
def test_the_pose2sim_videos_from_the_cached_detections(tmp_path):
    from jaxtrack.evaluation.reference import default_folder

    try:
        default_folder()
    except FileNotFoundError as error:
        pytest.skip(str(error))
    out = tmp_path / "results.json"
    assert main(["--no-trackers", "--json", str(out)]) == 0
    results = json.loads(out.read_text())
    assert set(results["rows_2d"]) == {"raw", "butterworth", "one-euro", "kalman-rts",
                                       "kalman-rts vis>=0.5"}
    # MediaPipe is about as far from the reference as two detectors are from each other
    assert 0.7 < results["rows_2d"]["raw"]["all"]["within_15"] <= 1.0
    assert results["rows_3d"]["dlt"]["frames_complete"] == len(results["frames"])
