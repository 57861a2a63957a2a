"""The headline, guarded on a small case of a subject the prior never saw.

The prior learns from two *training* subjects' waves (small settings); the tracked take is a
*test* subject's (``cmu_1006``: only ever scored, never used to choose a setting), 16 frames at
320 × 240 in which the arms come down from a T pose. The shipped latent tracker (200 particles,
the default refinement) must stay on the body; the filter's own estimates of the latent tracker
and of CONDENSATION (1 000 particles, AR(2) learned from the same training poses) must not get
worse than measured. The bounds are the values measured on 2026-11-26 and, with the subject's
link lengths that the latent tracker decodes with since, on 2026-11-28 (commented beside each)
with a margin for another CPU's rounding (XLA compiles for the CPU it runs on), so a regression
of the prior, the dynamics or the likelihood fails here.
"""

import pytest

from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data.splits import check_disjoint, split_of
from jaxtrack.evaluation import evaluate_track
from jaxtrack.experiments import run_method
from jaxtrack.priors.train import train_prior

TRAINING = ("animateddrawings/fair1_wave_hello",
            "animateddrawings/history_c119d6b/8yr_old_wave_hello")
HELD_OUT = "animateddrawings/history_c119d6b/cmu_1006_wave_hello_2"


@pytest.fixture(scope="module")
def subject_prior():
    check_disjoint(TRAINING, [HELD_OUT])
    assert {split_of(clip) for clip in TRAINING} == {"training"}
    assert split_of(HELD_OUT) == "test"
    return train_prior(TRAINING, views=2, fps=10.0, active_size=60, iterations=1,
                       progress=False)


def _error(prior, sequence, method, particles, refinement):
    result = run_method(method, prior, sequence, particles=particles, refinement=refinement,
                        progress=False)
    return evaluate_track(result.markers, sequence.truth, UPPER_BODY_12)


def test_the_shipped_latent_tracker_stays_on_a_held_out_subject(subject_prior, sequence):
    metrics = _error(subject_prior, sequence, "latent", 200, "default")
    assert metrics["mean_error_torso"] < 0.08  # measured 0.054 of the torso
    assert metrics["fraction_within_15"] >= 0.85  # measured 15 of 16 frames
    assert not metrics["failed"]


def test_the_filters_own_estimates_on_a_held_out_subject(subject_prior, sequence):
    latent = _error(subject_prior, sequence, "latent", 200, None)
    condensation = _error(subject_prior, sequence, "condensation", 1000, None)
    # the prior alone does not carry this subject (papers/tian2005/history.md): guarded, not
    # celebrated
    assert latent["mean_error_torso"] < 0.35  # measured 0.19 (0.32 with the paper's decoder)
    assert condensation["mean_error_torso"] < 0.12  # measured 0.077; 0.087 on 2026-11-28


def test_a_prior_of_parts_trains_reloads_and_tracks(tmp_path, sequence):
    from jaxtrack.priors.gplvm import UPPER_BODY_PARTS, PartsGPLVM
    from jaxtrack.priors.train import load_prior

    cache = tmp_path / "parts.npz"
    prior = train_prior(TRAINING[:1], views=1, fps=5.0, active_size=30, iterations=1,
                        parts=UPPER_BODY_PARTS, cache=cache, progress=False)
    assert isinstance(prior.model, PartsGPLVM)
    assert prior.model.names == tuple(UPPER_BODY_PARTS) and prior.model.latent_dim == 6
    assert prior.description["settings"]["parts"]["left_arm"] == [7, 8, 9]
    loaded = load_prior(cache)
    assert isinstance(loaded.model, PartsGPLVM) and loaded.model.links == prior.model.links
    # the same settings load the cache
    again = train_prior(TRAINING[:1], views=1, fps=5.0, active_size=30, iterations=1,
                        parts=UPPER_BODY_PARTS, cache=cache, progress=False)
    assert again.description["settings_key"] == prior.description["settings_key"]
    short = type(sequence)(name=sequence.name, images=sequence.images[:4],
                           frames=sequence.frames[:4], truth=sequence.truth[:4], fps=sequence.fps)
    metrics = _error(loaded, short, "latent", 32, None)
    assert metrics["mean_error_torso"] < 0.5
    # partitioned sampling over the parts: a proper filter (finite, normalised, no re-seed)
    import jax.random as jr

    from jaxtrack.experiments.protocol import build_tracker
    from jaxtrack.trackers import track

    tracker = build_tracker("latent", loaded, short, 32, refinement=None,
                            latent_options={"partitioned": True})
    result = track(tracker, jr.PRNGKey(0), short.frames, short.truth[0], progress=False)
    assert result.options["partitioned"] is True
    assert not result.degenerate.any() and (result.ess > 0).all() and (result.ess <= 32).all()
    assert evaluate_track(result.markers, short.truth, UPPER_BODY_12)["mean_error_torso"] < 0.5
