"""Posture labels from real mocap on the clips' documented timelines; the posture model's fit,
transitions and files."""

import json

import numpy as np
import pytest

from jaxtrack.priors.postures import (
    CRAWLING,
    LYING_LEFT,
    LYING_RIGHT,
    NUM_POSTURES,
    SITTING,
    STANDING,
    PostureFormatError,
    fit_posture_model,
    load_posture_model,
    posture_labels,
    save_posture_model,
)


def _labels(clip: str, fps: float = 10.0) -> tuple[np.ndarray, float]:
    from jaxtrack.body.markers import HUMANEVA_15, marker_positions
    from jaxtrack.data import load_clip

    try:
        motion = load_clip(clip).resample(fps)
    except FileNotFoundError:
        pytest.skip(f"{clip} is in the project's shared data, not found here")
    joints = marker_positions(motion, HUMANEVA_15)
    image = joints[..., :2] * np.array([1.0, -1.0])  # an orthographic view along -z
    return posture_labels(joints, image, HUMANEVA_15), fps


def _during(labels, fps, begin, end):
    return labels[int(round(begin * fps)):int(round(end * fps)) + 1]


def test_cmu_139_16_lies_then_crawls_then_stands():
    labels, fps = _labels("cmu_posture_bvh/139_16")
    lying = _during(labels, fps, 0.1, 1.6)
    assert np.all((lying == LYING_LEFT) | (lying == LYING_RIGHT))
    assert len(set(lying.tolist())) == 1  # one side: the body does not turn over
    assert np.mean(_during(labels, fps, 2.0, 3.3) == CRAWLING) >= 0.5  # all fours, kneeling
    assert np.all(_during(labels, fps, 3.5, 4.9) == CRAWLING)  # forward-leaning crouch
    assert labels[-1] == STANDING


def test_cmu_75_20_stands_sits_stands():
    labels, fps = _labels("cmu_posture_bvh/75_20")
    assert np.all(_during(labels, fps, 0.0, 0.9) == STANDING)
    assert np.all(_during(labels, fps, 1.6, 2.7) == SITTING)
    assert np.all(_during(labels, fps, 3.4, 4.1) == STANDING)


def test_lying_side_follows_the_head_in_the_image():
    labels, _ = _labels("cmu_posture_bvh/139_16")
    from jaxtrack.body.markers import HUMANEVA_15, marker_positions
    from jaxtrack.data import load_clip

    joints = marker_positions(load_clip("cmu_posture_bvh/139_16").resample(10.0), HUMANEVA_15)
    mirrored = joints[..., :2] * np.array([-1.0, -1.0])
    flipped = posture_labels(joints, mirrored, HUMANEVA_15)
    swap = {LYING_LEFT: LYING_RIGHT, LYING_RIGHT: LYING_LEFT}
    np.testing.assert_array_equal(flipped, [swap.get(label, label) for label in labels])


def _toy_training(rng):
    means = rng.normal(size=(NUM_POSTURES, 3)) * 5
    labels = [np.repeat(np.arange(NUM_POSTURES), 400), np.array([0, 0, 1, 1, 1, 2])]
    features = [means[labels[0]] + rng.normal(size=(2000, 3)), means[labels[1]]]
    return means, features, labels


def test_fit_recovers_means_and_counts_transitions():
    rng = np.random.default_rng(1)
    means, features, labels = _toy_training(rng)
    model = fit_posture_model(features, labels, pseudocount=0.5, regularisation=1e-3)
    assert model.num_components == 1
    np.testing.assert_allclose(model.means[:, 0], means, atol=0.2)
    counts = np.full((NUM_POSTURES, NUM_POSTURES), 0.5)
    for sequence in labels:
        for i, j in zip(sequence[:-1], sequence[1:], strict=True):
            counts[i, j] += 1
    np.testing.assert_allclose(np.exp(model.log_transition),
                               counts / counts.sum(1, keepdims=True))
    assert np.mean(np.asarray(model.classify(features[0])) == labels[0]) > 0.97
    # truncation: a far-away feature vector has the same Mahalanobis term under every posture
    far = np.asarray(model.log_likelihoods(np.full(3, 1e6)))
    np.testing.assert_allclose(far + 0.5 * np.asarray(model.log_determinants[:, 0]),
                               -0.5 * float(model.cutoff))


def test_a_pooled_covariance_is_the_within_posture_scatter_shared_by_every_posture():
    rng = np.random.default_rng(3)
    means, features, labels = _toy_training(rng)
    # one posture spread far wider than the others: its own covariance differs, the pooled not
    features[0][labels[0] == 2] = means[2] + 4.0 * rng.normal(size=(400, 3))
    own = fit_posture_model(features, labels, regularisation=1e-3)
    pooled = fit_posture_model(features, labels, regularisation=1e-3, covariance="pooled")
    np.testing.assert_array_equal(pooled.means, own.means)
    values, names = np.concatenate(features), np.concatenate(labels)
    scatter = sum((values[names == q] - values[names == q].mean(0)).T
                  @ (values[names == q] - values[names == q].mean(0))
                  for q in range(NUM_POSTURES)) / (len(values) - NUM_POSTURES)
    ridge = 1e-3 * np.trace(np.cov(values.T)) / 3
    for q in range(NUM_POSTURES):
        np.testing.assert_allclose(np.linalg.inv(pooled.precisions[q, 0]),
                                   scatter + ridge * np.eye(3), rtol=1e-6)
    assert np.ptp(np.asarray(pooled.log_determinants)) == 0
    assert np.ptp(np.asarray(own.log_determinants)) > 1.0
    assert np.mean(np.asarray(pooled.classify(features[0])) == labels[0]) > 0.9
    with pytest.raises(ValueError, match="covariance must be one of per-posture, pooled"):
        fit_posture_model(features, labels, covariance="shared")


def test_a_mixture_finds_a_postures_two_groups_and_weighs_them_by_their_frames():
    """Each posture's frames in two groups (two views of it, say), the postures' groups
    interleaved along a line: one Gaussian per posture spreads over both groups and its mean
    sits nearer another posture's group; two components find both groups, weighted by their
    shares, and classify nearly every frame."""
    rng = np.random.default_rng(4)
    centres = np.zeros((NUM_POSTURES, 2, 4))
    centres[:, 0, 0] = 10.0 * np.arange(NUM_POSTURES)
    centres[:, 1, 0] = 10.0 * np.arange(NUM_POSTURES) + 25.0
    centres[..., 1:] = rng.normal(size=(NUM_POSTURES, 2, 3))
    counts = (300, 100)
    labels = np.repeat(np.arange(NUM_POSTURES), sum(counts))
    group = np.tile(np.repeat([0, 1], counts), NUM_POSTURES)
    values = centres[labels, group] + 0.5 * rng.normal(size=(len(labels), 4))
    one = fit_posture_model([values], [labels], regularisation=1e-3)
    two = fit_posture_model([values], [labels], regularisation=1e-3, components=2)
    assert two.num_components == 2 and two.means.shape == (NUM_POSTURES, 2, 4)
    for q in range(NUM_POSTURES):
        found = np.asarray(two.means[q])
        order = np.argsort([np.linalg.norm(found[k] - centres[q, 0]) for k in range(2)])
        np.testing.assert_allclose(found[order], centres[q], atol=0.2)
        np.testing.assert_allclose(np.exp(np.asarray(two.log_weights[q]))[order],
                                   np.array(counts) / sum(counts))
    assert np.mean(np.asarray(two.classify(values)) == labels) > 0.995
    assert np.mean(np.asarray(one.classify(values)) == labels) < 0.95
    # the mixture's density is the weighted sum of its truncated Gaussians, written out
    h = values[7]
    dense = []
    for q in range(NUM_POSTURES):
        terms = []
        for k in range(2):
            d = h - np.asarray(two.means[q, k])
            m = min(float(d @ np.asarray(two.precisions[q, k]) @ d), float(two.cutoff))
            terms.append(np.exp(float(two.log_weights[q, k]) - 0.5 * m
                                - 0.5 * float(two.log_determinants[q, k])))
        dense.append(np.log(sum(terms)))
    np.testing.assert_allclose(np.asarray(two.log_likelihoods(h)), dense, rtol=1e-6)


def test_a_posture_with_few_frames_gets_fewer_components():
    rng = np.random.default_rng(5)
    sizes = (200, 200, 200, 200, 30)  # lying right: fewer than two components' worth
    labels = np.repeat(np.arange(NUM_POSTURES), sizes)
    values = 5.0 * np.eye(NUM_POSTURES, 3)[labels] + rng.normal(size=(len(labels), 3))
    model = fit_posture_model([values], [labels], components=4)
    weights = np.exp(np.asarray(model.log_weights))
    assert np.all(weights[:4] > 0) and np.count_nonzero(weights[4]) == 1
    np.testing.assert_allclose(weights.sum(axis=1), 1.0)
    assert np.all(np.isfinite(np.asarray(model.log_likelihoods(values[0]))))
    with pytest.raises(ValueError, match="components must be a whole number >= 1"):
        fit_posture_model([values], [labels], components=0)


def test_a_posture_without_training_frames_is_refused():
    with pytest.raises(ValueError, match="'lying_right' has 0 training frames"):
        fit_posture_model([np.zeros((8, 2)) + np.arange(8)[:, None]],
                          [np.array([0, 0, 1, 1, 2, 2, 3, 3])])


def test_save_load_round_trip_and_damaged_files(tmp_path):
    rng = np.random.default_rng(2)
    _, features, labels = _toy_training(rng)
    model = fit_posture_model(features, labels)
    path = save_posture_model(tmp_path / "postures.npz", model, description={"clips": ["a"]})
    saved = load_posture_model(path)
    assert saved.description == {"clips": ["a"]}
    for name in ("means", "precisions", "log_determinants", "log_transition", "log_initial"):
        np.testing.assert_array_equal(getattr(saved.model, name), getattr(model, name))
    # a mixture, a posture with fewer components than the rest (−inf weights) included
    keep = (labels[0] != NUM_POSTURES - 1) | (np.cumsum(labels[0] == NUM_POSTURES - 1) <= 30)
    mixture = fit_posture_model([features[0][keep], features[1]], [labels[0][keep], labels[1]],
                                components=3)  # lying right: 30 frames, one component
    saved = load_posture_model(save_posture_model(tmp_path / "mixture.npz", mixture))
    for name in ("means", "precisions", "log_determinants", "log_weights"):
        np.testing.assert_array_equal(getattr(saved.model, name), getattr(mixture, name))
    assert np.isneginf(np.asarray(saved.model.log_weights)).any()
    # a file of format version 1 (one Gaussian per posture, no weights) still loads
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files if name != "log_weights"}
    metadata = json.loads(str(arrays["metadata"]))
    metadata["format_version"] = 1
    del metadata["num_components"]
    arrays["metadata"] = np.array(json.dumps(metadata))
    arrays["means"], arrays["precisions"] = arrays["means"][:, 0], arrays["precisions"][:, 0]
    arrays["log_determinants"] = arrays["log_determinants"][:, 0]
    np.savez(tmp_path / "version1.npz", **arrays)
    old = load_posture_model(tmp_path / "version1.npz").model
    np.testing.assert_array_equal(old.means, model.means)
    np.testing.assert_array_equal(old.log_weights, np.zeros((NUM_POSTURES, 1)))
    # a file whose weights leave a posture no component, or hold NaN, is refused in one line
    with np.load(tmp_path / "mixture.npz") as archive:
        arrays = {name: archive[name] for name in archive.files}
    for row, bad, message in ((slice(None), -np.inf, "gives a posture no component"),
                              (0, np.nan, "'log_weights' holds non-finite values")):
        broken = dict(arrays, log_weights=arrays["log_weights"].copy())
        broken["log_weights"][2, row] = bad
        np.savez(tmp_path / "broken.npz", **broken)
        with pytest.raises(PostureFormatError, match=message):
            load_posture_model(tmp_path / "broken.npz")
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:200])
    with pytest.raises(PostureFormatError, match="damaged or truncated"):
        load_posture_model(truncated)
    text = tmp_path / "text.npz"
    text.write_text("hello")
    with pytest.raises(PostureFormatError, match="not a .npz archive"):
        load_posture_model(text)
