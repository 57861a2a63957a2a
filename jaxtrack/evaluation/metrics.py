"""Tracking accuracy: marker errors in pixels and torso lengths, failures, per-sequence summaries.

Errors are image distances between predicted and true 2-D markers. They are also reported as a
fraction of the true torso length (neck to pelvis in the image) so that sequences filmed at
different sizes compare, and the seed papers' headline curve — the fraction of frames whose error
is within ε torso lengths — is computed from them. A track *fails* when its error stays above a
threshold (25 % of the torso) for a run of consecutive frames (10): from then on it no longer
follows the body, and the frames before that run are the frames it tracked.

Everything here is NumPy, and every result is plain Python (floats, ints, bools, lists, dicts,
None) so it can be written with :func:`jaxtrack._files.write_json_atomically` as it is. The
results measured with them: ``papers/tian2005/README.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["DEFAULT_EPSILONS", "compare_methods", "evaluate_track", "marker_errors", "summarise",
           "torso_lengths"]

DEFAULT_EPSILONS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5)
"""Error thresholds, as fractions of the torso length, of the fraction-within-ε curve."""

HEADLINE_EPSILON = 0.15


def _epsilon_key(epsilon: float) -> str:
    # '%g' gives '0.15', never '0.15000000000000002', so keys match however ε was computed
    return f"{float(epsilon):g}"


def _points(name: str, value, *, allow_nonfinite: bool = False) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 3 or array.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (time, markers, 2), got {array.shape}")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ValueError(f"{name} is empty (shape {array.shape}); it needs at least one frame "
                         f"and one marker")
    if not allow_nonfinite:
        bad = ~np.isfinite(array).all(axis=-1)
        if bad.any():
            frame, marker = (int(i) for i in np.argwhere(bad)[0])
            raise ValueError(f"{name} has {int(bad.sum())} non-finite (NaN or inf) marker "
                             f"position(s), the first at frame {frame}, marker {marker}; a "
                             f"diverged estimate must be reported, not averaged away")
    return array


def torso_lengths(markers_2d, marker_names: Sequence[str]) -> np.ndarray:
    """Image distance from neck to pelvis in each frame.

    Args:
        markers_2d: `(time, markers, 2)` pixels.
        marker_names: `(markers,)` names; must include `'neck'` and `'pelvis'` (as in
            `jaxtrack.body.UPPER_BODY_12` and `SPM_MARKERS`).

    Returns:
        `(time,)` float64 pixels.
    """
    markers_2d = _points("markers_2d", markers_2d, allow_nonfinite=True)
    names = list(marker_names)
    if len(names) != markers_2d.shape[1]:
        raise ValueError(f"markers_2d has {markers_2d.shape[1]} markers but marker_names names "
                         f"{len(names)}")
    missing = [name for name in ("neck", "pelvis") if name not in names]
    if missing:
        raise ValueError(f"torso length needs markers 'neck' and 'pelvis' but marker_names lacks "
                         f"{missing} (has {names}); use a marker set such as "
                         f"jaxtrack.body.UPPER_BODY_12")
    neck, pelvis = markers_2d[:, names.index("neck")], markers_2d[:, names.index("pelvis")]
    return np.linalg.norm(neck - pelvis, axis=-1)


def marker_errors(predicted, truth, visible=None) -> np.ndarray:
    """Mean Euclidean distance per frame between predicted and true markers.

    Args:
        predicted: `(time, markers, 2)` pixels; must be finite everywhere.
        truth: `(time, markers, 2)` pixels; must be finite wherever it is counted.
        visible: optional `(time, markers)` bool; only visible markers are averaged. Every frame
            needs at least one.

    Returns:
        `(time,)` float64 pixels.

    Raises:
        ValueError: shapes differ, `predicted` is not finite, `truth` is not finite at a counted
            marker, or a frame has no visible marker; the message names the argument.
    """
    predicted = _points("predicted", predicted)
    truth = _points("truth", truth, allow_nonfinite=True)
    if predicted.shape != truth.shape:
        raise ValueError(f"predicted has shape {predicted.shape} but truth has shape "
                         f"{truth.shape}; both must be (time, markers, 2)")
    if visible is None:
        counted = np.ones(truth.shape[:2], dtype=bool)
    else:
        counted = np.asarray(visible)
        if counted.shape != truth.shape[:2]:
            raise ValueError(f"visible has shape {counted.shape} but truth has (time, markers) = "
                             f"{truth.shape[:2]}")
        counted = counted.astype(bool)
        empty = np.flatnonzero(~counted.any(axis=1))
        if empty.size:
            raise ValueError(f"visible marks no marker in {empty.size} frame(s), the first "
                             f"{empty[:5].tolist()}; drop those frames before evaluating")
    bad_truth = counted & ~np.isfinite(truth).all(axis=-1)
    if bad_truth.any():
        frame, marker = (int(i) for i in np.argwhere(bad_truth)[0])
        raise ValueError(f"truth has {int(bad_truth.sum())} non-finite counted marker "
                         f"position(s), the first at frame {frame}, marker {marker}; mark them "
                         f"not visible")
    distances = np.linalg.norm(predicted - np.where(counted[..., None], truth, 0.0), axis=-1)
    return np.where(counted, distances, 0.0).sum(axis=1) / counted.sum(axis=1)


def _first_failure(errors_torso: np.ndarray, threshold: float, run_length: int) -> int | None:
    """First frame of the first run of `run_length` or more frames with error above threshold."""
    run = 0
    for t, bad in enumerate(errors_torso > threshold):
        run = run + 1 if bad else 0
        if run == run_length:
            return t - run_length + 1
    return None


def _optional_float(name: str, value) -> float | None:
    if value is None:
        return None
    value = float(value)
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite non-negative number of seconds or None, "
                         f"got {value}")
    return value


def evaluate_track(predicted, truth, marker_names: Sequence[str], *, visible=None,
                   epsilons: Sequence[float] = DEFAULT_EPSILONS, failure_threshold: float = 0.25,
                   failure_frames: int = 10, seconds_per_frame: float | None = None,
                   compile_seconds: float | None = None) -> dict:
    """Accuracy and failure of one tracked sequence.

    Args:
        predicted: `(time, markers, 2)` estimated markers, pixels.
        truth: `(time, markers, 2)` true markers, pixels; neck and pelvis must be finite.
        marker_names: `(markers,)` names, including `'neck'` and `'pelvis'`.
        visible: optional `(time, markers)` bool, see :func:`marker_errors`.
        epsilons: thresholds of the fraction-within-ε curve, as fractions of the torso length.
        failure_threshold: error, as a fraction of the torso, above which a frame is lost.
        failure_frames: that many consecutive lost frames make the track fail.
        seconds_per_frame: measured run time per frame (excluding compilation), or None.
        compile_seconds: measured compile time, or None.

    Returns:
        A JSON-serialisable dict: `num_frames`, `mean_error_px`, `median_error_px`,
        `mean_error_torso`, `errors_px` (list per frame), `errors_torso` (list per frame),
        `fraction_within` ({'0.05': fraction, ...}; a frame counts when error <= ε·torso),
        `fraction_within_15`, `failed`, `failure_frame` (int or None), `frames_tracked`,
        `frames_tracked_fraction`, `ms_per_frame` (or None), `compile_seconds` (or None).
    """
    errors = marker_errors(predicted, truth, visible)
    torso = torso_lengths(truth, marker_names)
    bad_torso = ~np.isfinite(torso) | (torso <= 0)
    if bad_torso.any():
        raise ValueError(f"truth has no usable torso (neck-pelvis distance zero or non-finite) in "
                         f"{int(bad_torso.sum())} frame(s), the first "
                         f"{np.flatnonzero(bad_torso)[:5].tolist()}")
    epsilons = tuple(float(e) for e in epsilons)
    if not epsilons or not all(math.isfinite(e) and e > 0 for e in epsilons):
        raise ValueError(f"epsilons must be positive finite torso fractions, got {epsilons}")
    if not (math.isfinite(failure_threshold) and failure_threshold > 0):
        raise ValueError(f"failure_threshold must be a positive torso fraction, got "
                         f"{failure_threshold}")
    if int(failure_frames) != failure_frames or failure_frames < 1:
        raise ValueError(f"failure_frames must be a positive integer, got {failure_frames}")
    seconds_per_frame = _optional_float("seconds_per_frame", seconds_per_frame)
    compile_seconds = _optional_float("compile_seconds", compile_seconds)

    num_frames = int(errors.shape[0])
    errors_torso = errors / torso
    fraction_within = {_epsilon_key(e): float(np.mean(errors <= e * torso)) for e in epsilons}
    failure_frame = _first_failure(errors_torso, float(failure_threshold), int(failure_frames))
    frames_tracked = num_frames if failure_frame is None else failure_frame
    return {
        "num_frames": num_frames,
        "mean_error_px": float(np.mean(errors)),
        "median_error_px": float(np.median(errors)),
        "mean_error_torso": float(np.mean(errors_torso)),
        "errors_px": errors.tolist(),
        "errors_torso": errors_torso.tolist(),
        "fraction_within": fraction_within,
        "fraction_within_15": float(np.mean(errors <= HEADLINE_EPSILON * torso)),
        "failed": failure_frame is not None,
        "failure_frame": failure_frame,
        "frames_tracked": int(frames_tracked),
        "frames_tracked_fraction": frames_tracked / num_frames,
        "ms_per_frame": None if seconds_per_frame is None else 1000.0 * seconds_per_frame,
        "compile_seconds": compile_seconds,
    }


def _median_or_none(values) -> float | None:
    values = [float(v) for v in values if v is not None]
    return float(np.median(values)) if values else None


def summarise(per_sequence: Sequence[Mapping]) -> dict:
    """Overall metrics of one method over several sequences (results of :func:`evaluate_track`).

    Errors and fractions pool every frame (so a long sequence weighs more); failure rate and
    tracked fraction count each sequence once.

    Returns:
        A JSON-serialisable dict: `num_sequences`, `num_frames` (total), `mean_error_px`,
        `median_error_px` (over all frames), `mean_error_torso`, `fraction_within` (pooled, same
        keys as the inputs), `fraction_within_15`, `num_failed`, `failure_rate` (fraction of
        sequences that failed), `frames_tracked_fraction` (mean over sequences),
        `ms_per_frame` and `compile_seconds` (medians over sequences that report them, or None).
    """
    results = list(per_sequence)
    if not results:
        raise ValueError("summarise needs at least one per-sequence result")
    keys = set(results[0]["fraction_within"])
    for i, result in enumerate(results):
        if set(result["fraction_within"]) != keys:
            raise ValueError(f"sequence {i} was evaluated at epsilons "
                             f"{sorted(result['fraction_within'])}, sequence 0 at {sorted(keys)}; "
                             f"evaluate every sequence with the same epsilons")
        if len(result["errors_px"]) != result["num_frames"]:
            raise ValueError(f"sequence {i}: errors_px has {len(result['errors_px'])} entries but "
                             f"num_frames is {result['num_frames']}")
    counts = np.array([result["num_frames"] for result in results], dtype=np.int64)
    total = int(counts.sum())
    errors_px = np.concatenate([np.asarray(r["errors_px"], dtype=np.float64) for r in results])
    errors_torso = np.concatenate([np.asarray(r["errors_torso"], dtype=np.float64)
                                   for r in results])

    def pooled(fractions) -> float:
        # each fraction is count / n exactly, so rounding recovers the frame count
        return float(sum(round(f * n) for f, n in zip(fractions, counts, strict=True)) / total)

    fraction_within = {key: pooled([r["fraction_within"][key] for r in results])
                       for key in sorted(keys, key=float)}
    num_failed = sum(bool(r["failed"]) for r in results)
    return {
        "num_sequences": len(results),
        "num_frames": total,
        "mean_error_px": float(errors_px.mean()),
        "median_error_px": float(np.median(errors_px)),
        "mean_error_torso": float(errors_torso.mean()),
        "fraction_within": fraction_within,
        "fraction_within_15": pooled([r["fraction_within_15"] for r in results]),
        "num_failed": num_failed,
        "failure_rate": num_failed / len(results),
        "frames_tracked_fraction": float(np.mean([r["frames_tracked"] / r["num_frames"]
                                                  for r in results])),
        "ms_per_frame": _median_or_none(r.get("ms_per_frame") for r in results),
        "compile_seconds": _median_or_none(r.get("compile_seconds") for r in results),
    }


def _cell(value, format_spec: str) -> str:
    return "n/a" if value is None else format(value, format_spec)


def compare_methods(results: Mapping[str, Mapping]) -> str:
    """A plain-text table of methods side by side, one row per method.

    Args:
        results: method name -> overall result of :func:`summarise` (a single sequence's
            :func:`evaluate_track` result also works; it is lost or not).

    Returns:
        The table: method, mean error (px), mean error (% torso), frames within 15 % of the
        torso, lost (the fraction of sequences lost, ``failure_rate``), ms/frame.
    """
    if not results:
        raise ValueError("compare_methods needs at least one method")
    header = ("method", "error px", "error %torso", "within 15%", "lost", "ms/frame")
    rows = []
    for method, result in results.items():
        failure_rate = result.get("failure_rate")
        if failure_rate is None and "failed" in result:
            failure_rate = float(bool(result["failed"]))
        torso = result.get("mean_error_torso")
        within = result.get("fraction_within_15")
        rows.append((
            str(method),
            _cell(result.get("mean_error_px"), ".2f"),
            _cell(None if torso is None else 100 * torso, ".1f"),
            _cell(None if within is None else 100 * within, ".1f") + ("%" if within is not None
                                                                      else ""),
            _cell(failure_rate, ".2f"),
            _cell(result.get("ms_per_frame"), ".2f"),
        ))
    widths = [max(len(row[i]) for row in (header, *rows)) for i in range(len(header))]

    def line(row) -> str:
        first, *rest = row
        return "  ".join([first.ljust(widths[0]),
                          *(cell.rjust(width) for cell, width in zip(rest, widths[1:],
                                                                     strict=True))])

    return "\n".join([line(header), "  ".join("-" * width for width in widths),
                      *(line(row) for row in rows)])
