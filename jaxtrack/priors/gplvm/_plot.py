"""The learned latent space as a figure (like Figure 2 of Tian, Li & Sclaroff 2005)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack._plotting import new_figure, save_figure
from jaxtrack.priors.gplvm._model import GPLVM

__all__ = ["plot_latent_space"]


def _spread_points(points: np.ndarray, count: int) -> np.ndarray:
    """Indices of ``count`` points spread out by farthest-point sampling."""
    chosen = [int(np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1)))]
    distances = np.linalg.norm(points - points[chosen[0]], axis=1)
    for _ in range(count - 1):
        chosen.append(int(np.argmax(distances)))
        distances = np.minimum(distances, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.array(chosen)


_BACKING = 1.2  # a glyph's white backing square, relative to the glyph's size


def _legend_names(labels: Sequence[str]) -> dict[str, str]:
    """Each label's last path component (clip names are long paths), unless two would clash."""
    short = {name: name.rstrip("/").rsplit("/", 1)[-1] or name for name in labels}
    return short if len(set(short.values())) == len(short) else {name: name for name in labels}


def _glyphs(decode: Callable[[np.ndarray], np.ndarray], anchors: np.ndarray, span: float
            ) -> list[np.ndarray]:
    """Decoded poses as ``(markers, 2)`` latent-space points, each inside a square at its anchor.

    The square's side is 12 % of the latent span, shrunk below the Chebyshev distance between
    the two closest anchors so that no two glyphs (nor their backing squares) overlap.
    """
    size = 0.12 * span
    if len(anchors) > 1:
        gaps = np.abs(anchors[:, None] - anchors[None]).max(axis=-1)
        size = min(size, float(gaps[~np.eye(len(anchors), dtype=bool)].min()) / _BACKING)
    glyphs = []
    for anchor in anchors:
        markers = np.asarray(decode(anchor), np.float64)
        low, high = markers.min(axis=0), markers.max(axis=0)
        scale = size / max(float((high - low).max()), 1e-9)
        # image y is down, latent x₂ up
        glyphs.append(anchor + (markers - (low + high) / 2) * scale * np.array([1.0, -1.0]))
    return glyphs


def _backing_corners(points: np.ndarray) -> np.ndarray:
    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    half = _BACKING * float(np.ptp(points, axis=0).max()) / 2
    return centre + np.array([[-half, -half], [half, half]])


def plot_latent_space(
    model: GPLVM,
    path: str | os.PathLike,
    *,
    labels: Sequence[str] | None = None,
    decode: Callable[[np.ndarray], np.ndarray] | None = None,
    edges: Sequence[tuple[int, int]] = (),
    num_poses: int = 8,
    resolution: int = 120,
    title: str | None = None,
    dpi: int = 120,
) -> Path:
    """Latent points coloured by label, ln σ²(x) as the background, decoded poses drawn on top.

    The axes span the points and the pose glyphs with a 5 % margin, all of it covered by the
    σ² background; the legend sits below the axes, clear of the data.

    Args:
        model: a 2-D GPLVM.
        labels: ``(n,)`` a label per training point (e.g. its clip), for the colours; the legend
            names each by its last path component.
        decode: maps one latent ``(2,)`` to image markers ``(markers, 2)`` (y down); those of
            ``num_poses`` spread-out active points are drawn as stick figures joined by ``edges``,
            each in a square small enough that no two overlap.
        resolution: grid cells per axis for σ².
    """
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Rectangle

    if model.latent_dim != 2:
        raise ValueError(f"plot_latent_space draws 2-D latent spaces, got {model.latent_dim}-D")
    latents = np.asarray(model.latents, np.float64)
    if labels is not None and len(labels) != latents.shape[0]:
        raise ValueError(f"labels has {len(labels)} entries for {latents.shape[0]} latent points")
    active = np.asarray(model.active_latents, np.float64)
    span = float(np.ptp(latents, axis=0).max()) or 1.0
    glyphs = []
    if decode is not None and num_poses > 0:
        anchors = active[_spread_points(active, min(num_poses, len(active)))]
        glyphs = _glyphs(decode, anchors, span)
    # the backing squares reach (_BACKING - 1) / 2 of a glyph beyond it
    drawn = np.concatenate([latents, *(_backing_corners(points) for points in glyphs)])
    low, high = drawn.min(axis=0), drawn.max(axis=0)
    pad = 0.05 * np.maximum(high - low, 1e-9)
    xs = np.linspace(low[0] - pad[0], high[0] + pad[0], resolution)
    ys = np.linspace(low[1] - pad[1], high[1] + pad[1], resolution)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    with jax.enable_x64(True):
        variance = np.asarray(jax.jit(jax.vmap(model.variance))(jnp.asarray(grid)))
    figure, axes = new_figure(7.5, 7.5)
    # the background's cells are centred on the grid, so its edges are half a cell outside it
    half = np.array([xs[1] - xs[0], ys[1] - ys[0]]) / 2
    extent = (xs[0] - half[0], xs[-1] + half[0], ys[0] - half[1], ys[-1] + half[1])
    image = axes.imshow(np.log(variance).reshape(resolution, resolution), origin="lower",
                        extent=extent, cmap="Greys", interpolation="nearest")
    figure.colorbar(image, ax=axes, label="ln σ²(x)", shrink=0.8)
    if labels is None:
        axes.scatter(latents[:, 0], latents[:, 1], s=4, c="tab:blue", label="training poses")
    else:
        labels = np.asarray(labels)
        names = _legend_names([str(name) for name in dict.fromkeys(labels)])
        for name in dict.fromkeys(labels):
            mask = labels == name
            axes.scatter(latents[mask, 0], latents[mask, 1], s=4, label=names[str(name)])
    axes.scatter(active[:, 0], active[:, 1], s=14, facecolors="none", edgecolors="red",
                 linewidths=0.6, label="active set")
    for points in glyphs:
        # a white square behind each pose keeps it legible over dark σ² and dense points
        centre = (points.min(axis=0) + points.max(axis=0)) / 2
        side = _BACKING * float(np.ptp(points, axis=0).max())
        axes.add_patch(Rectangle(centre - side / 2, side, side, facecolor="white", alpha=0.8,
                                 edgecolor="0.4", linewidth=0.6, zorder=3, gid="pose backing"))
        segments = [points[[a, b]] for a, b in edges]
        axes.add_collection(LineCollection(segments, colors="black", linewidths=1.4, zorder=4,
                                           capstyle="round", gid="pose glyph"))
    axes.set_xlim(extent[0], extent[1])
    axes.set_ylim(extent[2], extent[3])
    axes.set_xlabel("latent x₁")
    axes.set_ylabel("latent x₂")
    axes.set_title(title or f"GPLVM latent space ({latents.shape[0]} poses, "
                            f"{model.active_size} active)")
    figure.legend(*axes.get_legend_handles_labels(), loc="outside lower center",
                  ncols=2, fontsize="small", markerscale=2.5, frameon=False)
    return save_figure(figure, path, dpi)
