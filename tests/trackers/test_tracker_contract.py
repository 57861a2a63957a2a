"""One contract, every tracker: start/update shapes, jit without retracing, chunk-size
invariance, clear errors for a bad frame or a bad initial pose, options recorded, and the
refinement stage taken by every tracker."""

import ast
import itertools
import json
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack.body import SPM_MARKERS, spm_initial_state
from jaxtrack.trackers import (
    ArmSearch,
    Engine,
    FrameEstimate,
    Likelihood,
    Refinement,
    Tracker,
    condensation_tracker,
    latent_tracker,
    mht_tracker,
    track,
)
from jaxtrack.vision import edge_observations

FRAMES = 6
HELD_OUT = "animateddrawings/history_c119d6b/cmu_1006_wave_hello_2"
# a light refinement keeps the compiled scans small; the stage is the one the latent tracker runs
LIGHT = Refinement(steps=3, arm_search=ArmSearch(grid=3))


def _states(prior, sequence):
    return np.asarray(spm_initial_state(jnp.asarray(sequence.truth), prior.template))


def _make(name, prior, sequence, refinement="default"):
    """The tracker ``name`` with few particles; ``refinement`` None, LIGHT or the default."""
    if name == "latent":
        return latent_tracker(prior.model, prior.template, engine=Engine(16), fps=sequence.fps,
                              refinement=LIGHT if refinement == "default" else refinement)
    stage = None if refinement == "default" else refinement
    if name == "condensation":
        return condensation_tracker(prior.template, _states(prior, sequence), engine=Engine(32),
                                    refinement=stage)
    return mht_tracker(prior.template, _states(prior, sequence), num_modes=3, max_steps=3,
                       refinement=stage)


TRACKERS = ("latent", "condensation", "mht")


@pytest.mark.parametrize("name", TRACKERS)
def test_start_and_update_keep_shapes_and_compile_once(name, prior, sequence):
    tracker = _make(name, prior, sequence)
    assert isinstance(tracker, Tracker)
    observations = edge_observations(sequence.frames[:3])
    state = tracker.start(jr.PRNGKey(0), observations[0], sequence.truth[0])
    first = eqx.filter_jit(lambda t, s: t.first_estimate(s))(tracker, state)
    traces = []

    @eqx.filter_jit
    def update(tracker, state, key, frame):
        traces.append(1)  # runs once per trace
        return tracker.update(key, state, frame)

    estimates = [first]
    for index in (1, 2):
        state, estimate = update(tracker, state, jr.PRNGKey(index),
                                 jnp.asarray(observations[index]))
        estimates.append(estimate)
    assert len(traces) == 1  # the updated state has the structure and dtypes of the started one
    for estimate in estimates:
        assert isinstance(estimate, FrameEstimate)
        assert estimate.markers.shape == estimate.best_markers.shape == (len(SPM_MARKERS), 2)
        for scalar in (estimate.ess, estimate.log_likelihood, estimate.degenerate):
            assert np.shape(scalar) == ()
        assert np.all(np.isfinite(np.asarray(estimate.markers)))
    # frame 0 reports the given pose, to the prior's reconstruction for the latent tracker
    torso = float(np.linalg.norm(sequence.truth[0, 3] - sequence.truth[0, 1]))
    assert np.mean(np.linalg.norm(np.asarray(first.markers) - sequence.truth[0], axis=-1)) < (
        0.2 * torso)


@pytest.mark.parametrize("name", TRACKERS)
def test_track_does_not_depend_on_the_chunk_size(name, prior, sequence):
    tracker = _make(name, prior, sequence)
    results = [track(tracker, jr.PRNGKey(1), sequence.frames[:FRAMES], sequence.truth[0],
                     chunk_size=size, progress=False) for size in (2, FRAMES)]
    for field in ("markers", "best_markers", "ess", "log_likelihood", "degenerate"):
        np.testing.assert_array_equal(getattr(results[0], field), getattr(results[1], field))
    assert results[0].markers.shape == (FRAMES, len(SPM_MARKERS), 2)
    # the result records what produced it, as JSON
    options = json.loads(json.dumps(results[0].options))
    assert options["method"] == name and options["particles"] == tracker.num_particles


@pytest.mark.parametrize("name", TRACKERS)
def test_bad_frames_and_bad_initial_poses_are_clear_errors(name, prior, sequence):
    tracker = _make(name, prior, sequence, refinement=None)
    frames, truth = sequence.frames[:3], sequence.truth[0]
    with pytest.raises(ValueError, match="grey images"):
        track(tracker, jr.PRNGKey(0), sequence.images[:3], truth, progress=False)
    with pytest.raises(ValueError, match="no frame"):
        track(tracker, jr.PRNGKey(0), frames[:0], truth, progress=False)
    broken = frames.copy()
    broken[0, 5, 5] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        track(tracker, jr.PRNGKey(0), broken, truth, progress=False)
    with pytest.raises(ValueError, match=r"initial_pose must be 12 finite \(x, y\) pixel markers "
                                         r"of shape \(12, 2\)"):
        track(tracker, jr.PRNGKey(0), frames, truth[:5], progress=False)
    with pytest.raises(ValueError, match="initial_pose must be 12 finite .* non-finite"):
        track(tracker, jr.PRNGKey(0), frames, np.full_like(truth, np.nan), progress=False)
    with pytest.raises(TypeError, match="must be a jaxtrack.trackers.Tracker"):
        track(object(), jr.PRNGKey(0), frames, truth, progress=False)


@pytest.mark.parametrize("name", ["condensation", "mht"])
def test_baselines_take_the_refinement_stage(name, prior, sequence):
    """The stage is an argument of every tracker: it changes the reported pose and nothing the
    filter (or the mode pool) does, and the result file says which stage ran."""
    plain, refined = (track(_make(name, prior, sequence, stage), jr.PRNGKey(2),
                            sequence.frames[:FRAMES], sequence.truth[0], progress=False)
                      for stage in (None, LIGHT))
    for field in ("best_markers", "ess", "log_likelihood"):
        np.testing.assert_array_equal(getattr(plain, field), getattr(refined, field))
    assert np.max(np.abs(refined.markers[1:] - plain.markers[1:])) > 0.1  # pixels
    assert plain.options["refinement"] is None
    assert refined.options["refinement"] == {
        "steps": 3, "prior_std": 40.0,
        "arm_search": {"grid": 3, "span": 0.6, "margin": 2.0, "momentum": 1.0}}


def test_options_are_validated_once_where_they_are_built():
    with pytest.raises(ValueError, match="likelihood must be one of"):
        Likelihood("patches")
    with pytest.raises(ValueError, match="sharpness"):
        Likelihood(sharpness=-1.0)
    for name, value in (("edge_weight", -1.0), ("edge_tolerance", 0.0),
                        ("edge_tolerance", 120.0), ("foreground_weight", float("nan"))):
        with pytest.raises(ValueError, match=name):
            Likelihood(**{name: value})
    with pytest.raises(ValueError, match="edge_weight is a setting of the 'limbs\\+edges'"):
        Likelihood("markers", edge_weight=2.0)
    for grid in (4, -1, 2.5):
        with pytest.raises(ValueError, match="arm_grid"):
            ArmSearch(grid=grid)
    with pytest.raises(ValueError, match="arm_span"):
        ArmSearch(span=0.0)
    with pytest.raises(ValueError, match="arm_margin"):
        ArmSearch(margin=-1.0)
    for momentum in (-0.5, 1.5, float("nan")):
        with pytest.raises(ValueError, match="arm_momentum"):
            ArmSearch(momentum=momentum)
    for steps in (0, -1, 2.5):
        with pytest.raises(ValueError, match="refine_steps"):
            Refinement(steps=steps)
    with pytest.raises(ValueError, match="prior_std"):
        Refinement(prior_std=0.0)
    for particles in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="num_particles"):
            Engine(particles)
    with pytest.raises(ValueError, match="resampler must be one of"):
        Engine(8, resampler="bogus")
    with pytest.raises(ValueError, match="ess_threshold"):
        Engine(8, ess_threshold=1.5)
    for iterations in (0, 1.5, True):
        with pytest.raises(ValueError, match="iterations_per_frame must be a positive integer"):
            Engine(8, iterations_per_frame=iterations)


def test_the_engine_runs_several_cycles_per_frame_when_asked(prior, sequence):
    # Ong & Gong's cycles on one frame, for any tracker on the engine: the filter's particles
    # after a frame differ from one cycle's, and the setting is recorded with the run
    observations = edge_observations(sequence.frames[:2])
    states = _states(prior, sequence)
    moved = {}
    for name, iterations in itertools.product(("latent", "condensation"), (1, 3)):
        engine = Engine(32, iterations_per_frame=iterations)
        tracker = (latent_tracker(prior.model, prior.template, engine=engine, refinement=None,
                                  fps=sequence.fps) if name == "latent" else
                   condensation_tracker(prior.template, states, engine=engine))
        state = tracker.start(jr.PRNGKey(0), observations[0], sequence.truth[0])
        state, estimate = tracker.update(jr.PRNGKey(1), state, observations[1])
        assert np.all(np.isfinite(np.asarray(estimate.markers)))
        moved[name, iterations] = np.concatenate([np.asarray(leaf).ravel() for leaf in
                                                  jax.tree.leaves(state.filter.particles)])
        assert tracker.options()["engine"]["iterations_per_frame"] == iterations
    for name in ("latent", "condensation"):
        assert not np.allclose(moved[name, 1], moved[name, 3]), name
    from tests.trackers.test_partitioned import _parts_prior

    with pytest.raises(ValueError, match="partitioned sampling runs one cycle per frame"):
        latent_tracker(_parts_prior(), prior.template, partitioned=True,
                       engine=Engine(16, iterations_per_frame=2))


TRACKER_MODULES = ("latent", "condensation", "mht")


def test_no_tracker_module_imports_another():
    """Trackers stand side by side: what two share lives in a module of its own."""
    package = Path(__file__).parents[2] / "jaxtrack" / "trackers"
    for name in TRACKER_MODULES + ("autoinit",):
        tree = ast.parse((package / f"{name}.py").read_text())
        imported = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                imported.add(node.module)
                imported.update(f"{node.module}.{alias.name}" for alias in node.names)
            elif isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names)
        others = {f"jaxtrack.trackers.{other}" for other in TRACKER_MODULES if other != name}
        assert not imported & others, (name, imported & others)
        assert "jaxtrack.trackers" not in imported  # not through the package either


def test_a_tracker_must_declare_the_whole_contract():
    class NoLikelihood(Tracker):
        reads = ("grey",)

        def observe(self, chunk, out=None):
            return chunk.grey

        @property
        def num_particles(self):
            return 1

        def start(self, key, first_frame, initial_pose):
            return None

        def first_estimate(self, state):
            return None

        def update(self, key, state, frame):
            return state, None

        def options(self):
            return {}

    with pytest.raises(TypeError, match="abstract attributes.*likelihood"):
        NoLikelihood()

    class NoUpdate(Tracker):
        likelihood: Likelihood = Likelihood()
        reads = ("grey",)

        def observe(self, chunk, out=None):
            return chunk.grey

        @property
        def num_particles(self):
            return 1

        def start(self, key, first_frame, initial_pose):
            return None

        def first_estimate(self, state):
            return None

        def options(self):
            return {}

    with pytest.raises(TypeError, match="abstract method.*update"):
        NoUpdate()


def test_evaluate_runs_the_baselines_with_the_latent_trackers_refinement(prior, tmp_path,
                                                                         monkeypatch, capsys):
    """``jaxtrack evaluate --method condensation`` takes the refinement options the latent
    tracker takes; the stage changes the result and the JSON records the options used."""
    import jaxtrack.priors.train
    from jaxtrack.cli import main

    # the small test prior stands in for the CLI's own training (only its template is used)
    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", lambda *args, **kwargs: prior)
    common = ["evaluate", "--method", "condensation", "--train",
              "animateddrawings/fair1_wave_hello", "--test", HELD_OUT, "--particles", "16",
              "--views", "1", "--backgrounds", "photo", "--max-frames", "5"]
    records = {}
    for name, extra in (("plain", []), ("refined", ["--refine-steps", "3", "--arm-grid", "3"])):
        path = tmp_path / f"{name}.json"
        assert main([*common, "--json", str(path), *extra]) == 0, capsys.readouterr().err
        records[name] = json.loads(path.read_text())
    plain, refined = records["plain"], records["refined"]
    assert plain["tracker"]["method"] == refined["tracker"]["method"] == "condensation"
    assert plain["tracker"]["refinement"] is None
    assert refined["tracker"]["refinement"] == {
        "steps": 3, "prior_std": 40.0,
        "arm_search": {"grid": 3, "span": 0.6, "margin": 2.0, "momentum": 1.0}}
    assert plain["tracker"]["likelihood"] == {"kind": "limbs+edges", "sharpness": None,
                                              "nearest": True, "edge_weight": None,
                                              "edge_tolerance": None, "foreground_weight": None,
                                              "coverage_weight": None,
                                              "keypoint_weight": None,
                                              "keypoint_scale": None}
    assert plain["overall"]["mean_error_px"] != refined["overall"]["mean_error_px"]


def test_a_degenerate_first_frame_is_reported_as_one():
    """Frame 0's report says when no initial particle had a finite likelihood (ESS 0), as the
    engine's later frames do."""
    from jaxtrack import smc
    from jaxtrack.trackers._particles import first_info

    weights = jnp.full(4, -jnp.log(4.0))
    healthy = smc.FilterState(jnp.zeros((4, 2)), weights, jnp.asarray(0), jnp.asarray(-3.0))
    lost = smc.FilterState(jnp.zeros((4, 2)), weights, jnp.asarray(0), jnp.asarray(-jnp.inf))
    assert not bool(first_info(healthy).degenerate) and float(first_info(healthy).ess) == 4.0
    assert bool(first_info(lost).degenerate) and float(first_info(lost).ess) == 0.0
