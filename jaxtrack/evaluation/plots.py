"""Figures of tracking results: error over time, fraction of frames within ε (per method, or per
part and estimate), particle sweeps, a confusion matrix, an error surface.

matplotlib is imported inside the functions, so `import jaxtrack` works without it. Figures are
built with the object-oriented API on an Agg canvas — no pyplot, so no global backend switch and
no figure left registered (nothing to leak in a long benchmark) — and written atomically through
:func:`jaxtrack._files.write_atomically`: a failed save leaves no partial file and keeps any
earlier file at that path.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from jaxtrack._plotting import new_figure as _figure
from jaxtrack._plotting import save_figure as _save

__all__ = ["plot_confusion", "plot_error_surface", "plot_errors_over_time",
           "plot_fraction_within", "plot_fraction_within_per_part", "plot_particle_sweep"]


def _check_methods(name: str, values: Mapping) -> None:
    if not values:
        raise ValueError(f"{name} is empty; give at least one method")


def plot_errors_over_time(errors_torso: Mapping[str, Sequence[float]], path: str | os.PathLike,
                          *, title: str | None = None, fps: float | None = None,
                          failure_threshold: float | None = 0.25,
                          ylabel: str = "error / torso length", dpi: int = 120) -> Path:
    """Error per frame, as a fraction of the torso length, one line per method.

    Args:
        errors_torso: method -> `(time,)` errors (`evaluate_track(...)['errors_torso']`), or
            errors in other units named by `ylabel` (3-D skeleton errors in mm).
        path: the image file (format from its suffix; `.png` if none).
        title: figure title.
        fps: label the x axis in seconds at this frame rate instead of frames.
        failure_threshold: drawn as a dashed line (the failure criterion's threshold); None:
            no line.
        ylabel: the y axis' label.

    Returns:
        The path.
    """
    _check_methods("errors_torso", errors_torso)
    curves = {}
    for method, errors in errors_torso.items():
        errors = np.asarray(errors, dtype=np.float64)
        if errors.ndim != 1 or errors.size == 0:
            raise ValueError(f"errors_torso[{method!r}] must be a non-empty (time,) array, got "
                             f"shape {errors.shape}")
        curves[str(method)] = errors
    if fps is not None and not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")

    figure, axes = _figure(7.0, 3.5)
    for method, errors in curves.items():
        time = np.arange(errors.size) / (1.0 if fps is None else float(fps))
        axes.plot(time, errors, label=method, linewidth=1.2)
    if failure_threshold is not None:
        axes.axhline(failure_threshold, color="black", linestyle="--", linewidth=1,
                     label=f"failure ({failure_threshold:.0%} torso)")
    axes.set_xlabel("time (s)" if fps is not None else "frame")
    axes.set_ylabel(ylabel)
    axes.set_ylim(bottom=0)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize="small")
    if title:
        axes.set_title(title)
    return _save(figure, path, dpi)


def _fraction_curve(method: str, curve: Mapping) -> tuple[np.ndarray, np.ndarray]:
    # accept a whole evaluate_track / summarise result as well as its 'fraction_within' dict
    if "fraction_within" in curve and isinstance(curve["fraction_within"], Mapping):
        curve = curve["fraction_within"]
    if not curve:
        raise ValueError(f"curves[{method!r}] has no points")
    try:
        points = sorted((float(eps), float(fraction)) for eps, fraction in curve.items())
    except (TypeError, ValueError) as error:
        raise ValueError(f"curves[{method!r}] must map ε (a number or numeric string) to a "
                         f"fraction: {error}") from error
    epsilons, fractions = (np.array(values) for values in zip(*points, strict=True))
    return epsilons, fractions


def plot_fraction_within(curves: Mapping[str, Mapping], path: str | os.PathLike, *,
                         title: str | None = None, dpi: int = 120) -> Path:
    """The fraction of frames whose error is within ε torso lengths, against ε, per method.

    Args:
        curves: method -> {ε: fraction} (`evaluate_track(...)['fraction_within']`, keys may be
            strings), or method -> a whole result holding `fraction_within`.
        path: the image file.

    Returns:
        The path.
    """
    _check_methods("curves", curves)
    points = {str(method): _fraction_curve(str(method), curve) for method, curve in curves.items()}
    figure, axes = _figure(5.0, 4.0)
    for method, (epsilons, fractions) in points.items():
        axes.plot(epsilons, fractions, marker="o", markersize=3, label=method)
    axes.set_xlabel("ε (fraction of torso length)")
    axes.set_ylabel("fraction of frames with error ≤ ε")
    axes.set_xlim(left=0)
    axes.set_ylim(0, 1.02)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize="small", loc="lower right")
    if title:
        axes.set_title(title)
    return _save(figure, path, dpi)


def plot_fraction_within_per_part(curves: Mapping[str, Mapping[str, Mapping]],
                                  path: str | os.PathLike, *, parts: Sequence[str] | None = None,
                                  xlabel: str = "ε (pixels)", title: str | None = None,
                                  dpi: int = 120) -> Path:
    """The fraction of frames within ε against ε: one panel per part, one curve per estimate
    (Kwatra et al. 2002, Fig. 2/4).

    Args:
        curves: estimate -> part -> {ε: fraction or None} (keys may be numeric strings; None,
            a fraction with no frames, is left out of the line).
        path: the image file.
        parts: the panels, in order (None: the parts of the first estimate).
        xlabel: the x axis' label (ε's unit).
        title: figure title.

    Returns:
        The path.
    """
    _check_methods("curves", curves)
    parts = list(next(iter(curves.values())) if parts is None else parts)
    if not parts:
        raise ValueError("parts is empty; give at least one part")
    for estimate, per_part in curves.items():
        missing = [part for part in parts if part not in per_part]
        if missing:
            raise ValueError(f"curves[{estimate!r}] has no curve for {missing}")
    figure, axes = _figure(3.25 * len(parts), 3.6, columns=len(parts))
    axes = np.atleast_1d(axes)
    for axis, part in zip(axes, parts, strict=True):
        for estimate, per_part in curves.items():
            within = per_part[part]
            epsilons = sorted(within, key=float)
            fractions = [within[eps] for eps in epsilons]
            axis.plot([float(eps) for eps in epsilons],
                      [np.nan if value is None else value for value in fractions],
                      marker="o", markersize=3, label=str(estimate))
        axis.set_title(part)
        axis.set_xlabel(xlabel)
        axis.set_xlim(left=0)
        axis.set_ylim(0, 1.02)
        axis.grid(True, alpha=0.3)
    axes[0].set_ylabel("fraction of frames within ε")
    axes[-1].legend(fontsize="small", loc="lower right")
    if title:
        figure.suptitle(title)
    return _save(figure, path, dpi)


def plot_confusion(counts: Sequence[Sequence[int]], names: Sequence[str],
                   path: str | os.PathLike, *, xlabel: str = "estimate", ylabel: str = "truth",
                   colour_label: str = "fraction of the true class's frames",
                   title: str | None = None, dpi: int = 120) -> Path:
    """A confusion matrix: rows true, columns estimated, shaded by the fraction of each true
    class's frames, annotated with the counts.

    Args:
        counts: `(classes, classes)` frame counts, `counts[true][estimated]`.
        names: `(classes,)` class names, the ticks of both axes.
        path: the image file.
        xlabel, ylabel, colour_label: the axes' and the colour bar's labels.
        title: figure title.

    Returns:
        The path.
    """
    counts = np.asarray(counts, float)
    if counts.ndim != 2 or counts.shape != (len(names), len(names)):
        raise ValueError(f"counts must be ({len(names)}, {len(names)}) for {len(names)} names, "
                         f"got shape {counts.shape}")
    rows = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1)
    figure, axis = _figure(6.0, 5.0)
    image = axis.imshow(rows, cmap="Blues", vmin=0, vmax=1)
    figure.colorbar(image, ax=axis, label=colour_label)
    axis.set_xticks(range(len(names)), names, rotation=30, ha="right")
    axis.set_yticks(range(len(names)), names)
    axis.set_xlabel(xlabel)
    axis.set_ylabel(ylabel)
    for (row, column), count in np.ndenumerate(counts):
        axis.text(column, row, f"{int(count)}", ha="center", va="center",
                  color="white" if rows[row, column] > 0.5 else "black", fontsize="small")
    if title:
        axis.set_title(title)
    return _save(figure, path, dpi)


_SWEEP_KEYS = ("method", "particles", "mean_error_torso", "ms_per_frame")


def plot_particle_sweep(rows: Sequence[Mapping], path: str | os.PathLike, *,
                        title: str | None = None, dpi: int = 120) -> Path:
    """Accuracy and cost against the number of particles: two panels, log-x.

    Args:
        rows: dicts `{method, particles, mean_error_torso, ms_per_frame}`, one per run;
            `ms_per_frame` may be None (that point is left out of the time panel).
        path: the image file.

    Returns:
        The path.
    """
    rows = list(rows)
    if not rows:
        raise ValueError("rows is empty; give at least one {method, particles, ...} row")
    series: dict[str, list[tuple[int, float, float]]] = {}
    for i, row in enumerate(rows):
        missing = [key for key in _SWEEP_KEYS if key not in row]
        if missing:
            raise ValueError(f"rows[{i}] lacks {missing}; each row needs {list(_SWEEP_KEYS)}")
        particles = int(row["particles"])
        if particles < 1:
            raise ValueError(f"rows[{i}] has {particles} particles; the count must be positive")
        milliseconds = row["ms_per_frame"]
        series.setdefault(str(row["method"]), []).append(
            (particles, float(row["mean_error_torso"]),
             np.nan if milliseconds is None else float(milliseconds)))

    figure, (error_axes, time_axes) = _figure(9.0, 3.5, columns=2)
    for method, points in series.items():
        particles, errors, milliseconds = (np.array(v) for v in zip(*sorted(points), strict=True))
        error_axes.plot(particles, errors, marker="o", markersize=3, label=method)
        timed = np.isfinite(milliseconds)
        time_axes.plot(particles[timed], milliseconds[timed], marker="o", markersize=3,
                       label=method)
    for axes, label in ((error_axes, "mean error / torso length"), (time_axes, "ms per frame")):
        axes.set_xscale("log")
        axes.set_xlabel("particles")
        axes.set_ylabel(label)
        axes.set_ylim(bottom=0)
        axes.grid(True, which="both", alpha=0.3)
    error_axes.legend(fontsize="small")
    if title:
        figure.suptitle(title)
    return _save(figure, path, dpi)


def plot_error_surface(rows: Sequence[Mapping], path: str | os.PathLike, *,
                       panels: Sequence[tuple[str, str]] = (("training_m", "training clip"),
                                                            ("test_m", "held-out subject")),
                       title: str | None = None, dpi: int = 120) -> Path:
    """Error over a clusters × samples grid (Ong & Gong's Fig. 10 and 12): one panel per error
    key, the error against the samples per iteration, one line per cluster count.

    Args:
        rows: dicts ``{clusters, samples, <key>: error in metres, ...}``, one per grid point.
        path: the image file.
        panels: ``(key, panel title)`` for each panel; every row must hold every key.

    Returns:
        The path.
    """
    rows = list(rows)
    if not rows:
        raise ValueError("rows is empty; give at least one {clusters, samples, ...} row")
    keys = ["clusters", "samples", *(key for key, _ in panels)]
    for i, row in enumerate(rows):
        missing = [key for key in keys if key not in row]
        if missing:
            raise ValueError(f"rows[{i}] lacks {missing}; each row needs {keys}")
    figure, axes = _figure(4.5 * len(panels), 3.5, columns=len(panels))
    axes = np.atleast_1d(axes)
    clusters = sorted({int(row["clusters"]) for row in rows})
    colours = _cluster_colours(len(clusters))
    for panel, (key, panel_title) in zip(axes, panels, strict=True):
        for colour, count in zip(colours, clusters, strict=True):
            points = sorted((int(row["samples"]), 1e3 * float(row[key])) for row in rows
                            if int(row["clusters"]) == count)
            samples, errors = zip(*points, strict=True)
            panel.plot(samples, errors, marker="o", markersize=3, color=colour,
                       label=f"{count} clusters")
        panel.set_xlabel("samples per iteration")
        panel.set_ylabel("mean 3-D skeleton error (mm)")
        panel.set_title(panel_title)
        panel.grid(True, alpha=0.3)
    axes[-1].legend(fontsize="x-small", ncol=2)
    if title:
        figure.suptitle(title)
    return _save(figure, path, dpi)


def _cluster_colours(count: int) -> list:
    """``count`` colours along viridis, dark (few clusters) to light (many)."""
    from matplotlib import colormaps

    return [colormaps["viridis"](value) for value in np.linspace(0.0, 0.9, count)]
