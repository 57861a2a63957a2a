"""Markdown tables of evaluation results, as ``jaxtrack evaluate`` prints them.

- The linear-combination comparison (Ong & Gong 2002; ``docs/linear-combination.md``): per
  method the mean and worst 3-D skeleton error over sequences, frames, run time per frame and
  compile time (:func:`summarise_skeleton_errors`, :func:`skeleton_error_table`).
- The mixed-state tracker's Table 1 (Kwatra, Bobick & Johnson 2002; ``docs/mixed-state.md``):
  per estimate the mean squared error per part, the posture error and the largest head error
  (:func:`mixed_state_table`).

Plain Python in and out: the results read are the JSON-able dicts that
``jaxtrack.experiments.linear_combination.evaluate`` and
``jaxtrack.experiments.mixed_state.evaluate`` return.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["MIXED_STATE_ESTIMATES", "MIXED_STATE_PARTS", "mixed_state_label", "mixed_state_table",
           "skeleton_error_table", "summarise_skeleton_errors"]

MIXED_STATE_ESTIMATES = ("instantaneous", "filtered", "smoothed", "fixed_lag")
"""The mixed-state tracker's estimates, in the order of Table 1's rows."""

MIXED_STATE_PARTS = ("head", "hands", "feet", "all")
"""The part groups of Table 1's columns and Fig. 2/4's panels."""

_ROW_NAMES = {"instantaneous": "instantaneous (extended Ghost)", "filtered": "filtered",
              "smoothed": "smoothed (whole sequence)", "fixed_lag": "fixed-lag ({lag} frames)"}


def summarise_skeleton_errors(results: Mapping) -> list[dict]:
    """Per method: mean and worst 3-D error over sequences, frames, run and compile time.

    Args:
        results: ``{"methods": [...], "sequences": {name: {method: {"error_m", "errors_m",
            "seconds_per_frame", "compile_seconds"}}}}``.

    Returns:
        One row per method: ``method``, ``error_mm``, ``worst_sequence_mm``, ``aligned_mm``
        (after a similarity alignment per frame; None when not recorded), ``sequences``,
        ``frames``, ``ms_per_frame`` (weighted by frames), ``compile_seconds`` (summed; None
        when a sequence's is not finite).
    """
    rows = []
    for method in results["methods"]:
        entries = [sequence[method] for sequence in results["sequences"].values()]
        frames = [len(entry["errors_m"]) for entry in entries]
        compile_seconds = [entry["compile_seconds"] for entry in entries]
        rows.append({
            "method": method, "error_mm": 1e3 * float(np.mean([e["error_m"] for e in entries])),
            "worst_sequence_mm": 1e3 * float(np.max([e["error_m"] for e in entries])),
            "aligned_mm": (1e3 * float(np.mean([e["aligned_error_m"] for e in entries]))
                           if all("aligned_error_m" in e for e in entries) else None),
            "sequences": len(entries), "frames": int(sum(frames)),
            "ms_per_frame": 1e3 * float(np.average([e["seconds_per_frame"] for e in entries],
                                                   weights=frames)),
            "compile_seconds": (float(np.sum(compile_seconds))
                                if all(math.isfinite(c) for c in compile_seconds) else None)})
    return rows


def skeleton_error_table(rows: Sequence[Mapping]) -> str:
    """The rows of :func:`summarise_skeleton_errors` as a markdown table."""
    lines = ["| method | 3-D error (mm) | worst sequence (mm) | aligned (mm) | sequences | frames "
             "| ms/frame | compile (s) |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        compiled = "-" if row["compile_seconds"] is None else f"{row['compile_seconds']:.1f}"
        aligned = "-" if row.get("aligned_mm") is None else f"{row['aligned_mm']:.1f}"
        lines.append(f"| {row['method']} | {row['error_mm']:.1f} | "
                     f"{row['worst_sequence_mm']:.1f} | {aligned} | {row['sequences']} | "
                     f"{row['frames']} | "
                     f"{row['ms_per_frame']:.2f} | {compiled} |")
    return "\n".join(lines)


def mixed_state_label(estimate: str, lag: int) -> str:
    """The name of a mixed-state estimate (one of :data:`MIXED_STATE_ESTIMATES`) in tables and
    legends, e.g. ``"fixed-lag (10 frames)"``."""
    if estimate not in _ROW_NAMES:
        raise ValueError(f"estimate must be one of {MIXED_STATE_ESTIMATES}, got {estimate!r}")
    return _ROW_NAMES[estimate].format(lag=lag)


def _cell(value, form: str) -> str:
    return "n/a" if value is None or not math.isfinite(value) else format(value, form)


def mixed_state_table(overall: Mapping, lag: int) -> str:
    """Kwatra et al.'s Table 1 as markdown: MSE per part (px²), posture error, largest head
    error, one row per estimate present in ``overall``.

    Args:
        overall: estimate -> ``{"mse": {part: px² or None}, "posture_error": fraction or None,
            "max_head_error": px or None}`` (``evaluate(...)["overall"]`` with non-finite values
            as None).
        lag: the fixed-lag smoother's lag, frames (its row's name).
    """
    header = ("estimate", "MSE head", "MSE hands", "MSE feet", "MSE all", "posture error %",
              "max head error px")
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(
        ["---"] + ["---:"] * (len(header) - 1)) + "|"]
    for kind in MIXED_STATE_ESTIMATES:
        if kind not in overall:
            continue
        row = overall[kind]
        cells = [mixed_state_label(kind, lag)]
        cells += [_cell(row["mse"][group], ".1f") for group in MIXED_STATE_PARTS]
        error = row["posture_error"]
        cells += [_cell(None if error is None else 100 * error, ".1f"),
                  _cell(row["max_head_error"], ".1f")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
