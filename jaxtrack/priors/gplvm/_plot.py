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

    Args:
        model: a 2-D GPLVM.
        labels: ``(n,)`` a label per training point (e.g. its clip), for the colours.
        decode: maps one latent ``(2,)`` to image markers ``(markers, 2)`` (y down); those of
            ``num_poses`` spread-out active points are drawn as stick figures joined by ``edges``.
        resolution: grid cells per axis for σ².
    """
    if model.latent_dim != 2:
        raise ValueError(f"plot_latent_space draws 2-D latent spaces, got {model.latent_dim}-D")
    latents = np.asarray(model.latents, np.float64)
    if labels is not None and len(labels) != latents.shape[0]:
        raise ValueError(f"labels has {len(labels)} entries for {latents.shape[0]} latent points")
    low, high = latents.min(axis=0), latents.max(axis=0)
    pad = 0.1 * (high - low)
    xs = np.linspace(low[0] - pad[0], high[0] + pad[0], resolution)
    ys = np.linspace(low[1] - pad[1], high[1] + pad[1], resolution)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    with jax.enable_x64(True):
        variance = np.asarray(jax.jit(jax.vmap(model.variance))(jnp.asarray(grid)))
    figure, axes = new_figure(7.5, 6.5)
    image = axes.imshow(np.log(variance).reshape(resolution, resolution), origin="lower",
                        extent=(xs[0], xs[-1], ys[0], ys[-1]), cmap="Greys", aspect="auto")
    figure.colorbar(image, ax=axes, label="ln σ²(x)")
    if labels is None:
        axes.scatter(latents[:, 0], latents[:, 1], s=4, c="tab:blue", label="training poses")
    else:
        labels = np.asarray(labels)
        for name in dict.fromkeys(labels):
            mask = labels == name
            axes.scatter(latents[mask, 0], latents[mask, 1], s=4, label=str(name))
    active = np.asarray(model.active_latents)
    axes.scatter(active[:, 0], active[:, 1], s=14, facecolors="none", edgecolors="red",
                 linewidths=0.6, label="active set")
    if decode is not None and num_poses > 0:
        size = 0.09 * max(xs[-1] - xs[0], ys[-1] - ys[0])
        for index in _spread_points(active, min(num_poses, len(active))):
            markers = np.asarray(decode(active[index]), np.float64)
            centred = markers - markers.mean(axis=0)
            scale = size / max(float(np.ptp(centred[:, 1])), 1e-9)
            points = active[index] + centred * scale * np.array([1.0, -1.0])  # image y is down
            for a, b in edges:
                axes.plot(points[[a, b], 0], points[[a, b], 1], color="black", linewidth=1.2)
    axes.set_xlabel("latent x₁")
    axes.set_ylabel("latent x₂")
    axes.set_title(title or f"GPLVM latent space ({latents.shape[0]} poses, "
                            f"{model.active_size} active)")
    axes.legend(loc="upper right", fontsize=7, markerscale=2)
    return save_figure(figure, path, dpi)
