"""The detections' observation model: normalised (quadrature, Monte Carlo), the swap and outlier
components, several people without a pull, gradients reaching every parameter, real frames."""

from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import norm

from jaxtrack.body import SPM_MARKERS
from jaxtrack.likelihoods import (
    DetectionsFrame,
    detection_model,
    detections_frames,
    detections_log_density,
)
from jaxtrack.likelihoods.detections import log_density, swap_order
from jaxtrack.vision import read_openpose

M = len(SPM_MARKERS)
RIGHT_WRIST, LEFT_WRIST = SPM_MARKERS.index("right_wrist"), SPM_MARKERS.index("left_wrist")
OPENPOSE = Path(__file__).resolve().parent.parent / "data" / "detections" / "openpose_body25b"
density = jax.jit(log_density)  # one compile per frame shape, not an eager op per call
along_line = jax.jit(jax.vmap(log_density, in_axes=(0, None, None)))  # used with 11 poses
slopes = jax.jit(jax.grad(log_density, argnums=(0, 2)))  # in the pose and the parameters


def _pose(centre=(0.0, 0.0), scale=1.0):
    """An upright upper body, facing the camera (its right on the image's left), neck–pelvis 22
    units times ``scale``, neck at ``centre``."""
    shape = np.array([[0, -8], [0, 0], [0, 9], [0, 22], [-9, 1], [-12, 11], [-13, 20], [-5, 22],
                      [9, 1], [12, 11], [13, 20], [5, 22]], float)
    return shape * scale + np.asarray(centre, float)


def _frame(points, confidence, people, size, slots=2):
    """A frame of ``people`` detections, padded to ``slots`` (one shape: one compile)."""
    points = np.asarray(points, float).reshape(-1, M, 2)
    confidence = np.asarray(confidence, float).reshape(-1, M)
    pad = slots - len(points)
    points = np.concatenate([points, np.zeros((pad, M, 2))])
    confidence = np.concatenate([confidence, np.zeros((pad, M))])
    return DetectionsFrame(jnp.asarray(np.where((confidence > 0)[..., None], points, 0.0)),
                           jnp.asarray(confidence), jnp.asarray(people, jnp.int32),
                           jnp.asarray(size, float))


def _grid(size, step, order=1):
    """Quadrature nodes over the image and their weights: Gauss–Legendre of ``order`` nodes
    per cell of side ``step`` (order 1: the midpoint rule)."""
    nodes, weights = np.polynomial.legendre.leggauss(order)
    axes = []
    for length in size:
        starts = np.arange(-0.5, length - 0.5 - 1e-9, step)
        axes.append(((starts[:, None] + step * (nodes + 1) / 2).ravel(),
                     np.tile(weights * step / 2, len(starts))))
    (x, wx), (y, wy) = axes
    points = np.stack(np.meshgrid(x, y), -1).reshape(-1, 2)
    return points, np.outer(wy, wx).ravel()


def _placed(frame, where, point):
    """``frame`` with the keypoint ``where = (person, marker)`` at ``point``."""
    return eqx.tree_at(lambda f: f.points, frame, frame.points.at[where[0], where[1]].set(point))


@jax.jit
def _one_point_values(pose, params, frame, where, nodes):
    """log p at each of ``nodes`` for the keypoint ``where`` placed there."""
    return jax.vmap(lambda point: log_density(pose, _placed(frame, where, point), params))(nodes)


@jax.jit
def _two_point_integral(pose, params, frame, first, second, nodes, weights):
    """∫∫ p over the positions of two keypoints (``first``, ``second``: (person, marker)), each
    over the image, with the quadrature ``nodes`` and ``weights`` of one."""
    def row(a):
        inner = jax.vmap(lambda b: jnp.exp(log_density(
            pose, _placed(_placed(frame, first, a), second, b), params)))(nodes)
        return jnp.sum(weights * inner)

    return jnp.sum(weights * jax.lax.map(row, nodes, batch_size=64))


def _empty_frame(confidence, people, size):
    return DetectionsFrame(jnp.zeros((*confidence.shape, 2)), jnp.asarray(confidence),
                           jnp.asarray(people, jnp.int32), jnp.asarray(size))


@pytest.mark.parametrize("centre, swap", [((32.0, 14.0), 0.05), ((44.0, 14.0), 0.4)])
def test_one_keypoint_integrates_to_one_over_the_image(centre, swap):
    # near the border the Gaussian's truncation to the image matters; with a large swap
    # probability the mirror marker's Gaussian elsewhere does
    size = (64.0, 48.0)
    params = detection_model(pixel_noise=1.5, swap_probability=swap, outlier_rate=0.1)
    confidence = np.zeros((2, M))
    confidence[0, LEFT_WRIST] = 0.8
    nodes, weights = _grid(size, 1.0, order=3)  # Gauss–Legendre, 3 nodes per pixel and axis
    values = _one_point_values(_pose(centre), params, _empty_frame(confidence, 1, size),
                               jnp.asarray([0, LEFT_WRIST]), jnp.asarray(nodes))
    assert float(jnp.sum(jnp.exp(values) * weights)) == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize("case", ["one person, two keypoints, swap", "two people"])
def test_two_keypoints_integrate_to_one(case):
    size = (8.0, 6.0)
    nodes, weights = (jnp.asarray(a) for a in _grid(size, 1.0, order=2))
    confidence = np.zeros((2, M))
    if case == "two people":  # one keypoint each; the mixture over who is ours, and none
        params = detection_model(pixel_noise=1.2, absent_probability=0.2)
        confidence[0, RIGHT_WRIST], confidence[1, LEFT_WRIST] = 0.9, 0.7
        people, first, second = 2, [0, RIGHT_WRIST], [1, LEFT_WRIST]
    else:  # the wrists, whose mirror images are each other: the swap component moves them
        params = detection_model(pixel_noise=1.2, swap_probability=0.3, outlier_rate=0.1)
        confidence[0, [LEFT_WRIST, RIGHT_WRIST]] = (0.9, 0.6)
        people, first, second = 1, [0, LEFT_WRIST], [0, RIGHT_WRIST]
    total = _two_point_integral(_pose((4.0, 1.0), scale=0.2), params,
                                _empty_frame(confidence, people, size), jnp.asarray(first),
                                jnp.asarray(second), nodes, weights)
    assert float(total) == pytest.approx(1.0, abs=1e-3)


def _truncated_normal(rng, mean, scale, size, count):
    """``count`` draws of N(mean, scale² I) restricted to the image (rejection)."""
    out = np.empty((count, 2))
    filled = 0
    while filled < count:
        draws = rng.normal(mean, scale, (2 * count, 2))
        inside = draws[np.all((draws >= -0.5) & (draws <= np.asarray(size) - 0.5), -1)]
        take = min(len(inside), count - filled)
        out[filled:filled + take] = inside[:take]
        filled += take
    return out


def test_all_twelve_keypoints_integrate_to_one_by_importance_sampling():
    # the full product with the swap, all 12 keypoints found: ∫ p = E_q[p / q], q per keypoint
    # ½ a Gaussian 1.5 times wider than the model's (truncated to the image) + ½ uniform
    size = np.array([24.0, 20.0])
    pose = _pose((12.0, 4.0), scale=0.5)
    params = detection_model(pixel_noise=1.5, swap_probability=0.2, outlier_rate=0.1)
    confidence = np.linspace(0.5, 0.95, M)[None]
    torso = np.linalg.norm(pose[1] - pose[3])
    sigma = np.sqrt((np.asarray(params.joint_scales) * torso) ** 2 + 1.5 ** 2)
    wide = 1.5 * sigma
    rng = np.random.default_rng(0)
    count = 100_000
    samples = np.empty((count, M, 2))
    log_q = np.zeros(count)
    for k in range(M):
        gaussian = _truncated_normal(rng, pose[k], wide[k], size, count)
        uniform = rng.uniform(-0.5, size - 0.5, (count, 2))
        samples[:, k] = np.where(rng.random(count)[:, None] < 0.5, gaussian, uniform)
        mass = np.prod(norm.cdf((size - 0.5 - pose[k]) / wide[k]) -
                       norm.cdf((-0.5 - pose[k]) / wide[k]))
        density = np.prod(norm.pdf(samples[:, k], pose[k], wide[k]), -1) / mass
        log_q += np.log(0.5 * density + 0.5 / np.prod(size))
    log_p = jax.jit(jax.vmap(lambda points: log_density(
        pose, DetectionsFrame(points[None], jnp.asarray(confidence), jnp.asarray(1, jnp.int32),
                              jnp.asarray(size)), params)))(jnp.asarray(samples))
    ratios = np.exp(np.asarray(log_p) - log_q)
    standard_error = ratios.std() / np.sqrt(count)
    assert standard_error < 0.05
    assert abs(ratios.mean() - 1.0) < 4 * standard_error


SIZE = (640.0, 480.0)


def _detection_of(pose, confidence=0.9, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    return pose + noise * rng.normal(size=pose.shape), np.full(M, confidence)


def test_a_left_right_swapped_detection_costs_log_s_with_the_swap_and_much_more_without():
    pose = _pose((300.0, 150.0), scale=5.0)
    points, confidence = _detection_of(pose)
    swapped = points[list(swap_order(SPM_MARKERS))]
    for s in (0.05, 0.2):
        params = detection_model(swap_probability=s)
        straight = float(density(pose, _frame(points, confidence, 1, SIZE), params))
        mirrored = float(density(pose, _frame(swapped, confidence, 1, SIZE), params))
        # nearly as high: the swap explains it at the price log(s / (1 − s))
        assert straight - mirrored == pytest.approx(np.log((1 - s) / s), abs=0.05)
    params = detection_model(swap_probability=0.0)
    straight = float(density(pose, _frame(points, confidence, 1, SIZE), params))
    mirrored = float(density(pose, _frame(swapped, confidence, 1, SIZE), params))
    # far lower: each of the 8 sided keypoints is then an outlier (the outlier component keeps
    # the cost finite, about log of the Gaussian's peak over ε each)
    assert straight - mirrored > 8 * np.log(1 / 0.05 * 0.9)


def test_a_wild_keypoint_costs_at_most_what_the_outlier_component_allows():
    pose = _pose((300.0, 150.0), scale=5.0)
    points, confidence = _detection_of(pose, confidence=1.0)
    wild = points.copy()
    wild[RIGHT_WRIST] += (250.0, 200.0)
    area = SIZE[0] * SIZE[1]
    for epsilon in (0.05, 0.2):
        params = detection_model(outlier_rate=epsilon)
        clean = float(density(pose, _frame(points, confidence, 1, SIZE), params))
        spoilt = float(density(pose, _frame(wild, confidence, 1, SIZE), params))
        torso = np.linalg.norm(pose[1] - pose[3])
        sigma = np.hypot(float(params.joint_scales[RIGHT_WRIST]) * torso, 2.0)
        peak = 1 / (2 * np.pi * sigma ** 2)
        # the keypoint's factor falls from at most (1 − ε) G(0) A + ε to at least ε
        bound = np.log((1 - epsilon) * peak * area + epsilon) - np.log(epsilon)
        assert 0 < clean - spoilt <= bound + 1e-6
        assert clean - spoilt > bound - 0.1  # the outlier takes it: a log ε-sized cost
    pure = detection_model(outlier_rate=1e-12)
    clean = float(density(pose, _frame(points, confidence, 1, SIZE), pure))
    spoilt = float(density(pose, _frame(wild, confidence, 1, SIZE), pure))
    assert clean - spoilt > 25.0


def test_a_passer_by_is_another_explanation_not_a_pull():
    ours = _pose((200.0, 150.0), scale=5.0)
    passer = _pose((420.0, 170.0), scale=4.5)
    mine, sure = _detection_of(ours, 0.9, noise=2.0, seed=1)
    theirs, _ = _detection_of(passer, 0.6, noise=2.0, seed=2)
    sure_theirs = np.full(M, 0.6)
    alone = _frame(mine, sure, 1, SIZE)
    both = _frame(np.stack([theirs, mine]), np.stack([sure_theirs, sure]), 2, SIZE)
    params = detection_model()
    shifts = np.linspace(0.0, 1.0, 11)[:, None, None] * (passer - ours)[None]
    along = along_line(jnp.asarray(ours + shifts), both, params)
    assert int(jnp.argmax(along)) == 0  # the true pose stays the highest
    assert float(along[0] - along[5]) > 20.0  # halfway is no compromise
    # and the passer-by moves neither the score's slope at the true pose nor, beyond the
    # mixture's log(1/2), its height
    gradient, gradient_both = slopes(ours, alone, params)[0], slopes(ours, both, params)[0]
    np.testing.assert_allclose(gradient_both, gradient, atol=1e-6)
    difference = float(density(ours, both, params) - density(ours, alone, params))
    assert difference == pytest.approx(np.log(0.5) - 12 * np.log(SIZE[0] * SIZE[1]), abs=0.01)


def test_no_one_detected_is_no_evidence_and_padded_people_are_ignored():
    pose = _pose((300.0, 150.0), scale=5.0)
    points, confidence = _detection_of(pose)
    params = detection_model()
    assert float(density(pose, _frame(np.stack([points, points]),
                                          np.stack([confidence, confidence]), 0, SIZE),
                             params)) == 0.0
    one = float(density(pose, _frame(points, confidence, 1, SIZE), params))
    padded = float(density(pose, _frame(np.stack([points, points + 50]),
                                            np.stack([confidence, confidence]), 1, SIZE),
                               params))
    assert padded == pytest.approx(one, abs=1e-10)


def test_gradients_reach_every_parameter_and_match_finite_differences():
    pose = _pose((300.0, 150.0), scale=5.0)
    points, confidence = _detection_of(pose, 0.8, noise=6.0, seed=3)
    points[LEFT_WRIST] += (60.0, 0.0)  # an outlier, so ε matters
    swapped = points[list(swap_order(SPM_MARKERS))]
    other, _ = _detection_of(_pose((100.0, 160.0), 5.0), 0.7, noise=3.0, seed=4)
    frames = [_frame(points, confidence, 1, SIZE),
              _frame(np.stack([swapped, other]), np.stack([confidence, confidence]), 2, SIZE)]
    params = detection_model(swap_probability=0.1, absent_probability=0.1)

    def evidence(params):
        return sum(density(pose, frame, params) for frame in frames)

    gradient = jax.tree.map(lambda *g: sum(g), *(slopes(pose, f, params)[1] for f in frames))
    for name in ("pixel_noise", "outlier_rate", "swap_probability", "absent_probability"):
        step = 1e-6
        plus = eqx.tree_at(lambda p, n=name: getattr(p, n), params,
                           getattr(params, name) + step)
        minus = eqx.tree_at(lambda p, n=name: getattr(p, n), params,
                            getattr(params, name) - step)
        numeric = (evidence(plus) - evidence(minus)) / (2 * step)
        assert float(getattr(gradient, name)) == pytest.approx(float(numeric), rel=1e-5)
        assert float(getattr(gradient, name)) != 0.0
    step = 1e-6
    scales = params.joint_scales
    for k in (0, RIGHT_WRIST, LEFT_WRIST):
        plus = eqx.tree_at(lambda p: p.joint_scales, params, scales.at[k].add(step))
        minus = eqx.tree_at(lambda p: p.joint_scales, params, scales.at[k].add(-step))
        numeric = (evidence(plus) - evidence(minus)) / (2 * step)
        assert float(gradient.joint_scales[k]) == pytest.approx(float(numeric), rel=1e-5)


def test_jit_and_vmap_over_particles_agree_with_one_at_a_time():
    pose = _pose((300.0, 150.0), scale=5.0)
    points, confidence = _detection_of(pose, 0.8, noise=4.0)
    frame = _frame(points, confidence, 1, SIZE)
    params = detection_model()
    particles = pose[None] + np.random.default_rng(5).normal(0, 8.0, (11, M, 2))
    batched = along_line(jnp.asarray(particles), frame, params)
    assert detections_log_density is log_density
    np.testing.assert_allclose(batched, [float(density(p, frame, params)) for p in particles],
                               rtol=1e-12)
    float32 = density(jnp.asarray(pose, jnp.float32),
                          jax.tree.map(lambda a: a.astype(jnp.float32)
                                       if jnp.issubdtype(a.dtype, jnp.floating) else a, frame),
                          detection_model(dtype=jnp.float32))
    assert float32.dtype == jnp.float32
    assert float(float32) == pytest.approx(float(density(pose, frame, params)), rel=1e-4)


def test_real_openpose_frames_mirror_and_passer_by():
    detections = read_openpose(OPENPOSE / "cam01_json")
    frames = detections_frames(detections, frame_size=(1080, 1920))
    assert frames.points.shape == (3, 2, M, 2) and frames.image_size.shape == (3, 2)
    params = detection_model()
    for t in range(3):
        frame = jax.tree.map(lambda a, t=t: a[t], frames)
        man = detections.points[t, 0]  # the man on the beam, all 12 markers found
        assert np.all(detections.confidence[t, 0] > 0)
        mirrored = man[list(swap_order(SPM_MARKERS))]
        # the same detections, read as the mirror image: exactly the swap's price
        gap = float(density(man, frame, params) - density(mirrored, frame, params))
        assert gap == pytest.approx(np.log(0.95 / 0.05), abs=1e-3)
        # the woman behind him is another explanation: his pose is the best of the line to her
        woman = np.nanmean(detections.points[t, 1], 0)
        shifts = np.linspace(0, 1, 11)[:, None, None] * (woman - np.nanmean(man, 0))
        along = along_line(jnp.asarray(man[None] + shifts), frame, params)
        assert int(jnp.argmax(along)) == 0
    with pytest.raises(ValueError, match="frame size is unknown"):
        detections_frames(detections)
    # keypoints outside the image are not found (the model's support is the image), whether
    # the frames say so or the density sees it
    small = detections_frames(detections, frame_size=(400, 1920))
    outside = np.asarray(detections.points[..., 0] > 399.5) & (detections.confidence > 0)
    assert outside.any() and np.all(np.asarray(small.confidence)[outside] == 0)
    frame = jax.tree.map(lambda a: a[0], small)
    unmarked = eqx.tree_at(lambda f: (f.points, f.confidence), frame,
                           (jnp.asarray(np.nan_to_num(detections.points[0])),
                            jnp.asarray(detections.confidence[0])))
    man = detections.points[0, 0]
    assert float(density(man, unmarked, params)) == float(density(man, frame, params))
    # the markers the pose has, in its order, taken by name
    wide = read_openpose(OPENPOSE / "cam01_json", markers=(*SPM_MARKERS[::-1], "left_knee"))
    picked = detections_frames(wide, markers=SPM_MARKERS, frame_size=(1080, 1920))
    np.testing.assert_array_equal(picked.points, frames.points)
