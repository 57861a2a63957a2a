"""The contract on all five trackers: each is a ``Tracker`` exported from ``jaxtrack.trackers``,
says which parts of a video it reads, observes a chunk of video into a pytree with a time axis,
and ``track()`` runs it from the video, from observations made beforehand and in chunks of any
size, with the same result."""

import json

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import jaxtrack.trackers as trackers
from jaxtrack.body import spm_initial_state
from jaxtrack.body.hybrid import HybridLayout
from jaxtrack.priors.linear_combinations import fit_linear_combinations
from jaxtrack.trackers import (
    Engine,
    Tracker,
    VideoChunk,
    condensation_tracker,
    latent_tracker,
    linear_combination_tracker,
    mht_tracker,
    track,
)
from jaxtrack.trackers._tracker import VIDEO_FIELDS
from tests.mixed_state._figures import draw, figure_postures

FRAMES = 5
NAMES = ("latent", "condensation", "mht", "linear-combination", "mixed-state")


@pytest.fixture(scope="module")
def hybrid():
    """Six rendered frames of a real clip through one camera, colour and background kept, and
    a tiny linear-combination model trained on them."""
    from jaxtrack.experiments.linear_combination import render_hybrid_sequences

    sequence = render_hybrid_sequences(
        "animateddrawings/history_c119d6b/cmu_1006_wave_hello_1", views=(0,), num_contour=40,
        fps=6.0, max_frames=FRAMES, keep_images=True)[0]
    vectors = sequence.vectors[sequence.valid]
    fit = fit_linear_combinations(vectors, np.zeros(len(vectors)),
                                  HybridLayout(num_contour=40, num_skeleton=12),
                                  variance_fraction=0.95, num_clusters=2)
    return sequence, fit.model


def _case(name, prior, sequence, hybrid):
    """``(tracker, video chunk, initial pose)`` of a tiny run of tracker ``name``."""
    if name in ("latent", "condensation", "mht"):
        states = np.asarray(spm_initial_state(jnp.asarray(sequence.truth), prior.template))
        tracker = {
            "latent": lambda: latent_tracker(prior.model, prior.template, engine=Engine(16),
                                             fps=sequence.fps, refinement=None),
            "condensation": lambda: condensation_tracker(prior.template, states,
                                                         engine=Engine(32)),
            "mht": lambda: mht_tracker(prior.template, states, num_modes=3, max_steps=3),
        }[name]()
        return tracker, VideoChunk(grey=sequence.frames[:FRAMES]), sequence.truth[0]
    if name == "linear-combination":
        rendered, model = hybrid
        tracker = linear_combination_tracker(model, engine=Engine(24), iterations=2)
        return tracker, VideoChunk(colour=rendered.images[:FRAMES],
                                   background=rendered.background), None
    from jaxtrack.trackers.mixed_state import MixedStateModel, MixedStateTracker

    mask = draw("standing")[0]
    masks = np.stack([np.roll(mask, 2 * t, axis=1) for t in range(FRAMES)])
    return MixedStateTracker(MixedStateModel(figure_postures()), 32), VideoChunk(masks=masks), None


@pytest.mark.parametrize("name", NAMES)
def test_every_tracker_observes_a_video_and_tracks_it_alike_in_any_chunks(name, prior, sequence,
                                                                          hybrid):
    pytest.importorskip("cv2")
    tracker, video, pose = _case(name, prior, sequence, hybrid)
    assert isinstance(tracker, Tracker)
    assert type(tracker).__name__ in trackers.__all__
    assert set(tracker.reads) <= set(VIDEO_FIELDS)
    observations = tracker.observe(video)
    leaves = jax.tree.leaves(observations)
    assert leaves and all(np.shape(leaf)[0] == FRAMES for leaf in leaves)
    key = jr.PRNGKey(3)
    whole = track(tracker, key, video, pose, progress=False)
    chunked = track(tracker, key, video, pose, progress=False, chunk_size=2)
    made = track(tracker, key, observations, pose, progress=False, chunk_size=3)
    for other in (chunked, made):
        np.testing.assert_allclose(other.markers, whole.markers, rtol=1e-5, atol=1e-4)
    assert whole.markers.shape[0] == FRAMES and whole.ess.shape == (FRAMES,)
    assert whole.estimates is not None and whole.estimates.markers.shape == whole.markers.shape
    assert isinstance(json.loads(json.dumps(whole.options))["method"], str)
    assert 0 <= whole.observe_seconds and whole.seconds_per_frame > 0
    # a stream of chunks (a video decoded chunk by chunk) is tracked too
    stream = (video.frames(begin, begin + 2) for begin in range(0, FRAMES, 2))
    streamed = track(tracker, key, stream, pose, progress=False)
    assert streamed.markers.shape == whole.markers.shape


@pytest.mark.parametrize("name", NAMES)
def test_a_video_without_what_the_tracker_reads_is_refused_in_one_line(name, prior, sequence,
                                                                       hybrid):
    tracker, video, pose = _case(name, prior, sequence, hybrid)
    empty = VideoChunk(keypoints=(np.zeros((FRAMES, 12, 2)), np.zeros((FRAMES, 12))))
    with pytest.raises(ValueError) as error:
        track(tracker, jr.PRNGKey(0), empty, pose, progress=False)
    message = str(error.value)
    assert "\n" not in message and "give" in message
