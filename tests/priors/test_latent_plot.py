"""The latent-space figure: axes fitted to the data, a legend clear of it, pose glyphs apart."""

import itertools

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from jaxtrack.priors.gplvm import GPLVM, KernelParameters, _plot, plot_latent_space  # noqa: E402

# a stick figure: head, neck, two arms spread wide (wider than tall, as a waving pose is)
FIGURE = np.array([[0.0, -2.0], [0.0, -1.0], [-3.0, -1.5], [3.0, -1.5], [0.0, 1.0]])
EDGES = ((0, 1), (1, 2), (1, 3), (1, 4))


@pytest.fixture(scope="module")
def model():
    # a GPLVM on a ring of latent points (no fitting: the figure only needs μ, σ² and the points)
    rng = np.random.default_rng(0)
    angle = rng.uniform(0, 2 * np.pi, 60)
    latents = np.stack([np.cos(angle), 0.6 * np.sin(angle)], axis=1)
    poses = np.stack([np.cos(angle), np.sin(angle), np.cos(2 * angle)], axis=1)
    return GPLVM.from_active_set(KernelParameters.create(1.0, 100.0, 4.0), poses - poses.mean(0),
                                 poses.mean(0), latents, np.arange(0, 60, 3))


def drawn_figure(model, tmp_path, monkeypatch, **options):
    saved = {}

    def capture(figure, path, dpi):
        figure.canvas.draw()
        saved["figure"] = figure
        return path

    monkeypatch.setattr(_plot, "save_figure", capture)
    plot_latent_space(model, tmp_path / "latent.png", **options)
    return saved["figure"]


def test_axes_fit_the_data_and_glyphs_with_the_background_under_all_of_it(
        model, tmp_path, monkeypatch):
    labels = [f"library/takes/clip_{i % 3}" for i in range(model.latents.shape[0])]
    figure = drawn_figure(model, tmp_path, monkeypatch, labels=labels,
                          decode=lambda latent: FIGURE + 10 * np.asarray(latent), edges=EDGES,
                          num_poses=6)
    axes = figure.axes[0]
    (left, right), (bottom, top) = axes.get_xlim(), axes.get_ylim()
    latents = np.asarray(model.latents)
    glyphs = [c for c in axes.collections if c.get_gid() == "pose glyph"]
    assert len(glyphs) == 6
    boxes = [np.concatenate(c.get_segments()) for c in glyphs]
    backings = [np.array([r.get_xy(), np.add(r.get_xy(), (r.get_width(), r.get_height()))])
                for r in axes.patches if r.get_gid() == "pose backing"]
    assert len(backings) == 6
    drawn = np.concatenate([latents, *boxes, *backings])
    low, high = drawn.min(axis=0), drawn.max(axis=0)
    span = high - low
    # everything inside, with a margin of a few % of the span on every side: no empty band
    for margin in (low[0] - left, right - high[0]):
        assert 0 < margin < 0.1 * span[0]
    for margin in (low[1] - bottom, top - high[1]):
        assert 0 < margin < 0.1 * span[1]
    # the σ² background covers the whole axes
    np.testing.assert_allclose(axes.images[0].get_extent(), (left, right, bottom, top))
    # no two glyphs (nor the white squares behind them) overlap
    for a, b in itertools.combinations(backings, 2):
        apart = (a.max(axis=0) < b.min(axis=0)) | (b.max(axis=0) < a.min(axis=0))
        assert apart.any()
    # the legend is outside the axes, named by the clips' last path component
    legend = figure.legends[0]
    renderer = figure.canvas.get_renderer()
    legend_box, axes_box = legend.get_window_extent(renderer), axes.get_window_extent(renderer)
    assert not legend_box.overlaps(axes_box)
    assert [text.get_text() for text in legend.get_texts()] == [
        "clip_0", "clip_1", "clip_2", "active set"]
