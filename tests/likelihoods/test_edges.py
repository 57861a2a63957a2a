"""Limb strips plus edges (``likelihood="limbs+edges"``) on video rendered from a real wave
gesture (the frames of ``_wave.rendered_wave``)."""

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _wave import rendered_wave, wrong_poses

from jaxtrack.likelihoods import (
    DEFAULT_LIMB_SHARPNESS,
    LIMB_SEGMENTS,
    EdgeLimbTemplates,
    fit_border_widths,
    limb_edge_distances,
    limb_ncc_log_likelihood,
    limb_points,
    make_appearance_templates,
    make_edge_limb_templates,
    needs_edges,
)
from jaxtrack.likelihoods.edges import FOREGROUND_SEGMENTS
from jaxtrack.vision import edge_observations, median_grey_background


@cache
def wave():
    """Observations (grey, edge distance, edge tangent), true markers, frame-0 templates."""
    grey, markers = rendered_wave()
    observations = edge_observations(grey)
    return observations, markers, make_edge_limb_templates(observations[0], markers[0])


batch_log_likelihood = jax.jit(jax.vmap(lambda markers, observation, templates:
                                        templates.log_likelihood(markers, observation, 4.0),
                                        in_axes=(0, None, None)))
distances_of = jax.jit(limb_edge_distances)
residuals_of = jax.jit(lambda templates, *args: templates.residuals(*args))



def test_strip_borders_lie_on_edges_at_the_true_pose():
    observations, markers, templates = wave()

    def edge_penalty(pose, observation):  # κ Σ_s mean min(d/σ, 2)²: the strips' score minus ours
        return float(templates.strips.log_likelihood(pose, observation[0], 4.0)
                     - templates.log_likelihood(pose, observation, 4.0))

    shifts = np.float32([[6, 0], [-6, 0], [0, 6], [0, -6], [12, 0], [0, 12]])
    for t in (0, 5, 9):
        true = np.asarray(distances_of(markers[t], observations[t, 1]))
        assert true.shape == (len(LIMB_SEGMENTS), 2 * (12 - 2))
        assert np.all(true >= 0) and np.all(np.isfinite(true))
        assert np.median(true) <= 2.5, (t, np.median(true))  # the outline's edges, ~2 px off
        at_truth = edge_penalty(markers[t], observations[t])
        moved = [edge_penalty(markers[t] + shift, observations[t]) for shift in shifts]
        assert 0 < at_truth < min(moved), (t, at_truth, moved)


def test_true_pose_beats_turned_and_shifted_arms():
    observations, markers, templates = wave()
    for t in (3, 6, 9):
        values = np.asarray(batch_log_likelihood(
            np.concatenate([markers[t][None], wrong_poses(markers[t])]), observations[t],
            templates))
        assert np.all(values[1:] < values[0]), (t, values)


def test_the_edge_term_adds_to_the_strips_and_residuals_are_the_cost():
    observations, markers, templates = wave()
    pose = markers[4] + np.float32(0.6)
    sharpness = jnp.float32(DEFAULT_LIMB_SHARPNESS)
    strips_only = limb_ncc_log_likelihood(pose, observations[4, 0], templates.strips, sharpness)
    combined = templates.log_likelihood(pose, observations[4], sharpness)
    unweighted = EdgeLimbTemplates(templates.strips, jnp.float32(0.0), templates.edge_scale,
                                   templates.edge_tolerance, templates.border_widths)
    np.testing.assert_allclose(unweighted.log_likelihood(pose, observations[4], sharpness),
                               strips_only, rtol=1e-6)
    assert combined < strips_only  # the edge penalty is never a reward
    # the strip penalty saturates: κ · 4 per strip at most
    assert strips_only - combined <= 4 * len(LIMB_SEGMENTS) * float(templates.edge_weight)
    residuals = residuals_of(templates, pose, observations[4], sharpness)
    bilinear = templates.log_likelihood(pose, observations[4], sharpness, nearest=False)
    np.testing.assert_allclose(0.5 * jnp.sum(residuals**2), -bilinear, rtol=1e-4)
    assert combined.dtype == jnp.float32


@pytest.mark.parametrize("tolerance", [30.0, 45.0])
def test_edge_term_is_the_documented_formula_written_out_with_numpy(tolerance):
    """−κ Σ_s mean_i e_i², e_i = min(d_i/σ, 2) where |sin(φ_i − θ_s)| ≤ sin(tolerance), else 2,
    over each strip's two long borders without their ends: from the strip points, the distance
    map and the tangent map read at the nearest pixels, for the true and for wrong poses."""
    observations, markers, _ = wave()
    observation = observations[6]
    templates = make_edge_limb_templates(observations[0], markers[0], edge_tolerance=tolerance)
    height, width = observation.shape[1:]
    for pose in [markers[6], *wrong_poses(markers[6])[::3]]:
        points = np.asarray(limb_points(pose), np.float64)  # (segments, along, across, 2)
        # the borders at each strip's fitted half width (fit_border_widths)
        borders = np.asarray(limb_points(pose, across=2, width=templates.border_widths),
                             np.float64)[:, 1:-1].reshape(len(LIMB_SEGMENTS), -1, 2)
        column = np.clip(np.floor(borders[..., 0] + 0.5), 0, width - 1).astype(int)
        row = np.clip(np.floor(borders[..., 1] + 0.5), 0, height - 1).astype(int)
        distances, tangents = observation[1][row, column], observation[2][row, column]
        axis = points[:, -1, 0] - points[:, 0, 0]
        theta = np.arctan2(axis[:, 1], axis[:, 0])[:, None]
        spine = np.linalg.norm(np.asarray(pose[3], np.float64) - np.asarray(pose[1]))
        scaled = np.minimum(distances / (float(templates.edge_scale) * spine), 2.0)
        along = np.abs(np.sin(tangents - theta)) <= np.sin(np.deg2rad(tolerance)) + 1e-6
        expected = -float(templates.edge_weight) * np.sum(np.mean(
            np.where(along, scaled, 2.0) ** 2, axis=-1))
        strips = limb_ncc_log_likelihood(pose, observation[0], templates.strips, 4.0)
        combined = templates.log_likelihood(pose, observation, 4.0)
        np.testing.assert_allclose(float(combined - strips), expected, rtol=1e-4, atol=1e-4)


def test_only_edges_along_the_limb_count():
    """An outline edge turned across the limb is no longer on the limb's outline: the same
    distances with every tangent turned by 90° cost more, unless the tolerance is 90°."""
    observations, markers, templates = wave()
    turned = observations[5].copy()
    turned[2] = np.mod(turned[2] + np.pi / 2, np.pi)

    def edge_penalty(templates, observation):
        return float(templates.strips.log_likelihood(markers[5], observation[0], 4.0)
                     - templates.log_likelihood(markers[5], observation, 4.0))

    assert edge_penalty(templates, turned) > 1.5 * edge_penalty(templates, observations[5])
    any_edge = make_edge_limb_templates(observations[0], markers[0], edge_tolerance=90.0)
    np.testing.assert_allclose(edge_penalty(any_edge, turned),
                               edge_penalty(any_edge, observations[5]), rtol=1e-6)
    assert edge_penalty(any_edge, observations[5]) < edge_penalty(templates, observations[5])


def test_chosen_by_name_and_misuse_is_reported():
    observations, markers, _ = wave()
    assert needs_edges("limbs+edges") and not needs_edges("limbs")
    assert isinstance(make_appearance_templates("limbs+edges", observations[0], markers[0]),
                      EdgeLimbTemplates)
    # the templates are cut from the grey frame alone, given by itself or in its observation
    from_grey = make_edge_limb_templates(observations[0, 0], markers[0])
    from_observation = make_edge_limb_templates(observations[0], markers[0])
    np.testing.assert_array_equal(from_grey.strips.strips, from_observation.strips.strips)
    with pytest.raises(ValueError, match=r"\(3, height, width\)"):
        make_edge_limb_templates(np.stack([observations[0, 0]] * 2), markers[0])
    with pytest.raises(ValueError, match="edge_weight"):
        make_edge_limb_templates(observations[0], markers[0], edge_weight=-1.0)
    with pytest.raises(ValueError, match="edge_scale"):
        make_edge_limb_templates(observations[0], markers[0], edge_scale=0.0)
    templates = make_edge_limb_templates(observations[0], markers[0])
    with pytest.raises(ValueError, match=r"\(3, height, width\)"):
        templates.log_likelihood(markers[0], observations[0, :2], 4.0)
    with pytest.raises(ValueError, match="edge_tolerance"):
        make_edge_limb_templates(observations[0], markers[0], edge_tolerance=120.0)
    with pytest.raises(ValueError, match="likelihood must be one of"):
        needs_edges("edges")


def test_a_trackers_likelihood_settings_reach_the_templates():
    from jaxtrack.trackers import Likelihood
    from jaxtrack.trackers._particles import frame0_templates

    observations, markers, defaults = wave()
    likelihood = Likelihood(edge_weight=3.0, edge_tolerance=30.0, foreground_weight=0.5)
    templates = frame0_templates(likelihood, observations[0], markers[0], None, jnp.float32)
    assert float(templates.edge_weight) == 3.0 and float(templates.edge_tolerance) == 30.0
    assert float(templates.foreground_weight) == 0.5
    assert float(defaults.edge_weight) != 3.0
    with pytest.raises(ValueError, match="settings of the 'limbs\\+edges' likelihood only"):
        make_appearance_templates("limbs", observations[0, 0], markers[0], edge_weight=1.0)


def test_border_widths_are_fitted_to_the_limbs_outlines_at_initialisation():
    """The rendered forearms are narrower than the strips: their borders are fitted inwards on
    frame 0, the spine (whose borders lie on no outline) keeps the strips' half width, and the
    true pose's edge penalty is lower on every later frame than with the strips' own width."""
    observations, markers, templates = wave()
    unfitted = make_edge_limb_templates(observations[0], markers[0], border_scales=None)
    strip_width = float(templates.strips.width)
    np.testing.assert_array_equal(unfitted.border_widths, strip_width)
    factors = np.asarray(templates.border_widths) / strip_width
    names = [segment[0] for segment in LIMB_SEGMENTS]
    assert factors[names.index("right forearm and hand")] < 1
    assert factors[names.index("left forearm and hand")] < 1
    assert factors[names.index("upper spine")] == factors[names.index("lower spine")] == 1

    def edge_penalty(templates, t):
        return float(templates.strips.log_likelihood(markers[t], observations[t, 0], 4.0)
                     - templates.log_likelihood(markers[t], observations[t], 4.0))

    for t in range(1, len(markers)):
        assert edge_penalty(templates, t) < edge_penalty(unfitted, t), t
    # the same fit from the grey frame alone (its edge maps made by jaxtrack.vision)
    from_grey = make_edge_limb_templates(observations[0, 0], markers[0])
    np.testing.assert_array_equal(from_grey.border_widths, templates.border_widths)
    # a margin no fit can beat keeps every border at the strips' width
    kept = fit_border_widths(unfitted, observations[0], markers[0], margin=4.0)
    np.testing.assert_array_equal(kept.border_widths, strip_width)
    with pytest.raises(ValueError, match="scales"):
        fit_border_widths(unfitted, observations[0], markers[0], scales=(0.5, -1.0))
    with pytest.raises(ValueError, match="margin"):
        fit_border_widths(unfitted, observations[0], markers[0], margin=float("nan"))
    with pytest.raises(ValueError, match="12 finite"):
        fit_border_widths(unfitted, observations[0], np.full((12, 2), np.nan))


@pytest.mark.parametrize("likelihood", ["limbs+edges", "foreground", "limbs", "markers"])
def test_parts_are_the_likelihood_term_by_term(likelihood):
    """``part_log_likelihoods`` are the terms ``log_likelihood`` sums, a picked part's term is
    computed alone with the same value, ``part_residuals`` are ``residuals`` grouped by part,
    and each part's row moves only with the markers ``part_markers`` names for it (what the
    arm search and the refinement's Gauss–Newton rely on). "foreground": limbs+edges with a
    background."""
    observations, markers, _ = wave()
    edges = likelihood in ("limbs+edges", "foreground")
    observation = observations[4] if edges else observations[4, 0]
    background = median_grey_background(observations[:, 0]) if likelihood == "foreground" else None
    templates = make_appearance_templates("limbs+edges" if edges else likelihood,
                                          observations[0] if edges else observations[0, 0],
                                          markers[0], background)
    pose = jnp.asarray(markers[4] + np.float32(0.6))
    for nearest in (True, False):
        terms = templates.part_log_likelihoods(pose, observation, 4.0, nearest)
        assert terms.shape == (len(templates.part_markers),)
        np.testing.assert_allclose(jnp.sum(terms),
                                   templates.log_likelihood(pose, observation, 4.0, nearest),
                                   rtol=1e-5)
        picked = (4, 1)
        np.testing.assert_allclose(
            templates.part_log_likelihoods(pose, observation, 4.0, nearest, picked),
            terms[jnp.asarray(picked)], rtol=1e-6)
    rows = templates.part_residuals(pose, observation, 4.0)
    assert rows.shape[0] == len(templates.part_markers)
    np.testing.assert_array_equal(np.sort(rows.reshape(-1)),
                                  np.sort(templates.residuals(pose, observation, 4.0)))
    jacobian = jax.jacfwd(lambda m: templates.part_residuals(m, observation, 4.0))(pose)
    reads = np.abs(np.asarray(jacobian)).sum(axis=(1, 3)) > 0  # (parts, markers)
    for part, named in enumerate(templates.part_markers):
        assert set(np.flatnonzero(reads[part])) <= set(named), (part, named)
    assert reads.any(axis=0).all()  # and every marker is read by some part
    # the spine length given apart (the refinement's Gauss–Newton): the same rows at the
    # markers' own spine length, each reading only its direct_part_markers, and the strips'
    # widths moving with the spine length given
    if templates.spine_markers is None:
        assert templates.direct_part_markers == templates.part_markers
    else:
        neck, pelvis = templates.spine_markers
        spine = jnp.linalg.norm(pose[pelvis] - pose[neck])
        np.testing.assert_allclose(templates.part_residuals(pose, observation, 4.0, spine), rows,
                                   rtol=1e-6, atol=1e-6)
        jacobian, by_spine = jax.jacfwd(
            lambda m, s: templates.part_residuals(m, observation, 4.0, s), argnums=(0, 1))(
                pose, spine)
        reads = np.abs(np.asarray(jacobian)).sum(axis=(1, 3)) > 0
        for part, named in enumerate(templates.direct_part_markers):
            assert set(np.flatnonzero(reads[part])) <= set(named), (part, named)
        assert (np.abs(np.asarray(by_spine)).sum(axis=1) > 0).all()  # every strip's width
    with pytest.raises(ValueError, match="parts|segments"):
        templates.part_log_likelihoods(pose, observation, 4.0, True, (len(templates.part_markers),))


def _centre_lines_still(templates, pose, grey, background):
    """NumPy: per strip, the fraction of its centre line's nearest pixels within the
    threshold of the background (the foreground term's ``b_s`` before the arm mask)."""
    points = np.asarray(limb_points(pose, along=templates.strips.along,
                                    across=templates.strips.across,
                                    width=float(templates.strips.width)))
    centre = points[:, :, templates.strips.across // 2]  # (segments, along, 2)
    height, width = grey.shape
    column = np.clip(np.floor(centre[..., 0] + 0.5), 0, width - 1).astype(int)
    row = np.clip(np.floor(centre[..., 1] + 0.5), 0, height - 1).astype(int)
    still = np.abs(grey[row, column] - background[row, column]) <= float(
        templates.foreground_threshold)
    return still.mean(axis=-1)


def test_foreground_term_scores_the_arm_strips_centre_lines_against_the_background():
    """−μ Σ_arms b_s written out with NumPy; no background, no term; a background that is the
    frame itself costs μ per arm strip, one that differs everywhere nothing; the residuals
    still give the cost, and the term is constant in the pose for Gauss–Newton."""
    observations, markers, templates = wave()
    grey = np.asarray(observations[5, 0])
    background = median_grey_background(observations[:, 0])
    with_background = make_edge_limb_templates(observations[0], markers[0],
                                               background=background, foreground_weight=2.0)
    pose = jnp.asarray(markers[5] + np.float32(0.6))
    plain = templates.log_likelihood(pose, observations[5], 4.0)
    still = _centre_lines_still(with_background, np.asarray(pose), grey, background)
    arms = np.isin(np.arange(len(LIMB_SEGMENTS)), FOREGROUND_SEGMENTS)
    assert arms.sum() == 4 and 0 < still[arms].sum() < 4  # a mixed case
    np.testing.assert_allclose(with_background.log_likelihood(pose, observations[5], 4.0),
                               plain - 2.0 * still[arms].sum(), rtol=1e-5)
    for scene, expected in ((grey, plain - 2.0 * 4), (grey + 0.5, plain)):
        shifted = make_edge_limb_templates(observations[0], markers[0], background=scene)
        np.testing.assert_allclose(shifted.log_likelihood(pose, observations[5], 4.0),
                                   expected, rtol=1e-5)
    residuals = residuals_of(with_background, pose, observations[5], 4.0)
    bilinear = with_background.log_likelihood(pose, observations[5], 4.0, nearest=False)
    np.testing.assert_allclose(0.5 * jnp.sum(residuals**2), -bilinear, rtol=1e-4)
    gradient = jax.grad(lambda m: with_background.log_likelihood(m, observations[5], 4.0, False)
                        - templates.log_likelihood(m, observations[5], 4.0, False))(pose)
    np.testing.assert_allclose(gradient, 0, atol=1e-5)


def test_a_mask_channel_makes_the_foreground_term_read_the_mask_frame_by_frame():
    """An observation's fourth channel, the person's mask, decides b_s where it is given:
    without a background the term appears; with one the mask wins (a background equal to
    the frame would cost μ per arm strip); the mask's 0.5 level splits person from scene;
    the residuals still give the cost; the term stays constant in the pose."""
    observations, markers, templates = wave()
    pose = jnp.asarray(markers[5] + np.float32(0.6))
    observation = np.asarray(observations[5])
    plain = templates.log_likelihood(pose, observation, 4.0)
    grey = observation[0]
    # a mask that is the person nowhere, everywhere, and on the left 40 % of the frame
    nowhere, everywhere = np.zeros_like(grey), np.ones_like(grey)
    left = np.zeros_like(grey)
    left[:, : int(0.4 * grey.shape[1])] = 1.0
    still = _centre_lines_still(templates, np.asarray(pose), left, np.zeros_like(grey))
    arms = np.isin(np.arange(len(LIMB_SEGMENTS)), FOREGROUND_SEGMENTS)
    assert 0 < still[arms].sum() < 4 and still[arms].sum() != 2  # an arm across its edge
    weighted = make_edge_limb_templates(observations[0], markers[0], foreground_weight=3.0)
    background_is_frame = make_edge_limb_templates(observations[0], markers[0], background=grey,
                                                   foreground_weight=3.0)
    for mask, off in ((nowhere, 4.0), (everywhere, 0.0), (left, still[arms].sum()),
                      (0.49 * everywhere, 4.0), (0.51 * everywhere, 0.0)):
        with_mask = np.concatenate([observation, mask[None]])
        for scored in (weighted, background_is_frame):
            np.testing.assert_allclose(scored.log_likelihood(pose, with_mask, 4.0),
                                       plain - 3.0 * off, rtol=1e-5)
    with_mask = np.concatenate([observation, left[None]])
    residuals = residuals_of(weighted, pose, with_mask, 4.0)
    np.testing.assert_allclose(0.5 * jnp.sum(residuals**2),
                               -weighted.log_likelihood(pose, with_mask, 4.0, nearest=False),
                               rtol=1e-4)
    gradient = jax.grad(lambda m: weighted.log_likelihood(m, with_mask, 4.0, False)
                        - templates.log_likelihood(m, observation, 4.0, False))(pose)
    np.testing.assert_allclose(gradient, 0, atol=1e-5)
    masks = np.zeros(observations[:2, 0].shape, bool)
    masks[:, :, :40] = True
    with_channel = edge_observations((255 * np.asarray(observations[:2, 0])).astype(np.uint8),
                                     masks=masks)
    assert with_channel.shape == (2, 4, *grey.shape)
    np.testing.assert_array_equal(with_channel[:, 3], masks)
    with pytest.raises(ValueError, match="masks must be"):
        edge_observations(np.asarray(observations[:2, 0]), masks=masks[:1])


def test_foreground_term_misuse_is_reported():
    observations, markers, _ = wave()
    grey = observations[0, 0]
    with pytest.raises(ValueError, match="background must be a grey image of the frame's size"):
        make_edge_limb_templates(observations[0], markers[0], background=grey[:10])
    with pytest.raises(ValueError, match="background holds non-finite"):
        make_edge_limb_templates(observations[0], markers[0], background=grey * np.nan)
    with pytest.raises(ValueError, match="foreground_weight"):
        make_edge_limb_templates(observations[0], markers[0], background=grey,
                                 foreground_weight=-1.0)
    with pytest.raises(ValueError, match="foreground_threshold"):
        make_edge_limb_templates(observations[0], markers[0], background=grey,
                                 foreground_threshold=0.0)
    with pytest.raises(ValueError, match="'limbs\\+edges' likelihood only"):
        make_appearance_templates("limbs", grey, markers[0], grey)
    levels = np.float32([0.1, 0.9, 0.2])[:, None, None] * np.ones((3, 4, 5), np.float32)
    np.testing.assert_allclose(median_grey_background(levels), 0.2)
    with pytest.raises(ValueError, match="at least 3 frames"):
        median_grey_background(observations[:2, 0])
    with pytest.raises(ValueError, match=r"\(time, height, width\)"):
        median_grey_background(grey)


def _coverage_numpy(markers, mask, weight):
    """The coverage term written out: a grid of 48 points along the longer side, the mask at
    the nearest pixel down to 1.1 spines from the neck, the distance to the nearest strip axis
    (head and hands extended)."""
    from jaxtrack.likelihoods.edges import COVERAGE_DEPTH, COVERAGE_GRID, COVERAGE_SCALE

    markers = np.asarray(markers, np.float64)
    height, width = mask.shape
    step = max(height, width) / COVERAGE_GRID
    rows, columns = round(height / step), round(width / step)
    total, count = 0.0, 0.0
    spine = np.linalg.norm(markers[3] - markers[1])
    for row in range(rows):
        for column in range(columns):
            x = (column + 0.5) * width / columns - 0.5
            y = (row + 0.5) * height / rows - 0.5
            value = mask[int(np.clip(np.round(y), 0, height - 1)),
                         int(np.clip(np.round(x), 0, width - 1))]
            axis = markers[3] - markers[1]
            if value < 0.5 or np.dot([x, y] - markers[1], axis) / np.dot(axis, axis) > (
                    COVERAGE_DEPTH):
                continue
            nearest = np.inf
            for _, start, end, before, after in LIMB_SEGMENTS:
                a, b = markers[start], markers[end]
                a, b = a - before * (b - a), b + after * (b - a)
                t = np.clip(np.dot([x, y] - a, b - a) / np.dot(b - a, b - a), 0, 1)
                nearest = min(nearest, np.linalg.norm([x, y] - (a + t * (b - a))))
            total += min(nearest / (COVERAGE_SCALE * spine), 2.0) ** 2
            count += 1
    return -weight * total / max(count, 1.0)


def test_the_coverage_term_is_the_documented_formula_and_belongs_to_no_part():
    """ν > 0 with a mask channel adds −ν Σ m c² / Σ m (written out with NumPy for masks over
    the left 40 % of the frame and over a box around the arms); the mask below the hips (the
    legs) counts for nothing; nothing without a mask or at
    ν = 0; the residuals still give the cost and its gradient; the parts leave it out and
    whole_pose_log_likelihood holds it; a pose whose arm lies where the mask has one costs
    less than the same pose with that arm folded in."""
    observations, markers, templates = wave()
    pose = np.asarray(markers[5], np.float32)
    observation = np.asarray(observations[5])
    grey = observation[0]
    covering = make_edge_limb_templates(observations[0], markers[0], coverage_weight=5.0)
    assert covering.has_whole_pose_terms and not templates.has_whole_pose_terms
    left = np.zeros_like(grey)
    left[:, : int(0.4 * grey.shape[1])] = 1.0
    box = np.zeros_like(grey)
    x0, y0 = pose.min(axis=0).astype(int)
    x1, y1 = pose.max(axis=0).astype(int)
    box[y0:y1, x0:x1] = 1.0
    plain = templates.log_likelihood(pose, observation, 4.0)
    np.testing.assert_allclose(covering.log_likelihood(pose, observation, 4.0), plain)
    for mask in (left, box):
        with_mask = np.concatenate([observation, mask[None]])
        expected = _coverage_numpy(pose, mask, 5.0)
        assert expected < 0
        base = templates.log_likelihood(pose, with_mask, 4.0)
        np.testing.assert_allclose(covering.log_likelihood(pose, with_mask, 4.0),
                                   base + expected, rtol=1e-4)
        np.testing.assert_allclose(covering.whole_pose_log_likelihood(pose, with_mask),
                                   expected, rtol=1e-4)
        parts = covering.part_log_likelihoods(pose, with_mask, 4.0)
        np.testing.assert_allclose(jnp.sum(parts) + expected,
                                   covering.log_likelihood(pose, with_mask, 4.0), rtol=1e-4)
        residuals = residuals_of(covering, pose, with_mask, 4.0)
        np.testing.assert_allclose(0.5 * jnp.sum(residuals**2),
                                   -covering.log_likelihood(pose, with_mask, 4.0, False),
                                   rtol=1e-4)
        assert covering.part_residuals(pose, with_mask, 4.0).size == templates.part_residuals(
            pose, with_mask, 4.0).size
    with_mask = np.concatenate([observation, box[None]])
    gradient = jax.grad(lambda m: covering.whole_pose_log_likelihood(m, with_mask))(
        jnp.asarray(pose))
    assert np.all(np.isfinite(gradient)) and np.abs(gradient).max() > 0
    # the mask holds the true arm: folding the right wrist onto the chest leaves it uncovered
    arm = np.zeros_like(grey)
    for start, end in ((4, 5), (5, 6)):
        for t in np.linspace(0, 1, 50):
            x, y = np.round(pose[start] + t * (pose[end] - pose[start])).astype(int)
            arm[max(y - 3, 0):y + 4, max(x - 3, 0):x + 4] = 1.0
    with_arm = np.concatenate([observation, arm[None]])
    folded = pose.copy()
    folded[5:7] = pose[2]
    assert (covering.whole_pose_log_likelihood(pose, with_arm)
            > covering.whole_pose_log_likelihood(folded, with_arm) + 1.0)
    # the legs: a mask wholly below the hips costs nothing, whatever the pose
    legs = np.zeros_like(grey)
    legs[int(pose[3, 1] + 0.6 * np.linalg.norm(pose[3] - pose[1])):] = 1.0
    assert legs.any()
    np.testing.assert_allclose(covering.whole_pose_log_likelihood(
        pose, np.concatenate([observation, legs[None]])), 0.0)
    with pytest.raises(ValueError, match="coverage_weight must be a non-negative number"):
        make_edge_limb_templates(observations[0], markers[0], coverage_weight=-1.0)


def _keypoint_term_numpy(markers, points, confidence, weight, factor=1.0):
    """The keypoint term written out: a bivariate Cauchy per marker at the scales of
    KEYPOINT_SCALES (in spines), the better of the as-given and left/right-swapped
    assignments."""
    from jaxtrack.likelihoods.edges import KEYPOINT_SCALES, MIRRORED_MARKERS

    markers = np.asarray(markers, np.float64)
    spine = np.linalg.norm(markers[3] - markers[1])
    scales = np.asarray(KEYPOINT_SCALES) * factor * spine
    costs = []
    for order in (list(range(12)), list(MIRRORED_MARKERS)):
        squared = np.sum((markers - points[order]) ** 2, axis=-1)
        costs.append(np.sum(confidence[order] * np.log1p(squared / scales**2)))
    return -weight * min(costs)


def test_the_keypoint_term_is_the_documented_formula_and_ignores_a_left_right_swap():
    """η > 0 with keypoints adds −η min_π Σ w log(1 + q²) (written out with NumPy);
    the detections with left and right exchanged score the same; a keypoint of confidence 0
    counts for nothing; the residuals give the cost, the parts leave it out; a pose on the
    keypoints beats one a spine away, and the pull has a gradient however far."""
    from jaxtrack.likelihoods.edges import MIRRORED_MARKERS
    from jaxtrack.vision.observations import ImageObservation, Keypoints

    observations, markers, templates = wave()
    pose = np.asarray(markers[5], np.float32)
    rng = np.random.default_rng(3)
    points = (pose + rng.normal(0, 3, pose.shape)).astype(np.float32)
    confidence = rng.uniform(0.3, 1.0, 12).astype(np.float32)

    def observation_with(points, confidence):
        return ImageObservation(np.asarray(observations[5]), Keypoints(points, confidence))

    keyed = make_edge_limb_templates(observations[0], markers[0], keypoint_weight=1.5)
    assert keyed.has_whole_pose_terms and keyed.reads_keypoints
    observation = observation_with(points, confidence)
    plain = templates.log_likelihood(pose, np.asarray(observations[5]), 4.0)
    for candidate in (pose, pose + 20.0):
        expected = _keypoint_term_numpy(candidate, points, confidence, 1.5)
        np.testing.assert_allclose(keyed.whole_pose_log_likelihood(candidate, observation),
                                   expected, rtol=1e-4)
    np.testing.assert_allclose(keyed.log_likelihood(pose, observation, 4.0),
                               plain + _keypoint_term_numpy(pose, points, confidence, 1.5),
                               rtol=1e-4)
    np.testing.assert_allclose(jnp.sum(keyed.part_log_likelihoods(pose, observation, 4.0)),
                               plain, rtol=1e-4)
    swapped = observation_with(points[list(MIRRORED_MARKERS)],
                               confidence[list(MIRRORED_MARKERS)])
    np.testing.assert_allclose(keyed.whole_pose_log_likelihood(pose, swapped),
                               keyed.whole_pose_log_likelihood(pose, observation), rtol=1e-6)
    unsure = confidence.copy()
    unsure[6] = 0.0
    moved = points.copy()
    moved[6] += 500.0  # a keypoint not found: its position means nothing
    np.testing.assert_allclose(
        keyed.whole_pose_log_likelihood(pose, observation_with(moved, unsure)),
        _keypoint_term_numpy(pose, points, unsure, 1.5), rtol=1e-4)
    np.testing.assert_allclose(keyed.whole_pose_log_likelihood(
        pose, observation_with(points, np.zeros(12, np.float32))), 0.0, atol=1e-6)
    residuals = residuals_of(keyed, pose, observation, 4.0)
    np.testing.assert_allclose(0.5 * jnp.sum(residuals**2),
                               -keyed.log_likelihood(pose, observation, 4.0, False), rtol=1e-4)
    spine = np.linalg.norm(pose[3] - pose[1])
    assert (keyed.whole_pose_log_likelihood(pose, observation)
            > keyed.whole_pose_log_likelihood(pose + spine, observation) + 10.0)
    far = jax.grad(lambda m: keyed.whole_pose_log_likelihood(m, observation))(
        jnp.asarray(pose + 3 * spine))
    # pulled back towards the keypoints
    assert np.all(np.isfinite(far)) and float(jnp.sum(far * -3 * spine)) > 0
    with pytest.raises(ValueError, match="keypoint_weight must be a non-negative number"):
        make_edge_limb_templates(observations[0], markers[0], keypoint_weight=-1.0)
    with pytest.raises(ValueError, match="keypoint_scale must be a positive factor"):
        make_edge_limb_templates(observations[0], markers[0], keypoint_weight=1.0,
                                 keypoint_scale=0.0)
    with pytest.raises(ValueError, match="reads a detector's keypoints: give an "
                                         "ImageObservation with keypoints"):
        keyed.log_likelihood(pose, np.asarray(observations[5]), 4.0)
