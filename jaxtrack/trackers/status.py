"""The per-frame outcome of a tracked video, written into every ``track.json``: one enum,
its messages, and the rules that assign it.

A frame is, in this order of precedence:

- ``degenerate``: the filter's weights collapsed (every particle scored zero likelihood, or a
  non-finite log-likelihood), and the tracker re-seeded or only predicted;
- ``no person``: the frame shows nobody to track: the person's mask or
  silhouette is empty or fills the frame, or no view has a silhouette with its skin blobs
  (linear-combination);
- ``lost``: the estimate no longer follows the person, by :data:`LOST_RULE`: more than half of
  its points lie outside the frame, or its log-likelihood falls more than
  :data:`LOST_DROP_MADS` robust deviations below the median of the :data:`LOST_WINDOW`
  frames before it (the deviation is the median absolute deviation of those frames, at least
  :data:`LOST_MIN_SPREAD` nats, so a flat history does not turn noise into a loss); the
  first :data:`LOST_MIN_HISTORY` frames are judged by the first part alone;
- ``ok``: none of these.
"""

from __future__ import annotations

import enum

import numpy as np

__all__ = ["LOST_DROP_MADS", "LOST_MIN_HISTORY", "LOST_MIN_SPREAD", "LOST_RULE", "LOST_WINDOW",
           "FrameStatus", "frame_statuses", "status_counts", "status_legend"]

LOST_WINDOW = 30
LOST_MIN_HISTORY = 5
LOST_DROP_MADS = 8.0
LOST_MIN_SPREAD = 1.0
LOST_RULE = (f"more than half of the estimate's points outside the frame, or its "
             f"log-likelihood more than {LOST_DROP_MADS:g} x max(MAD, {LOST_MIN_SPREAD:g}) below "
             f"the median of the previous {LOST_WINDOW} frames (from frame {LOST_MIN_HISTORY})")
"""The rule of ``lost``, written into every ``track.json``."""


class FrameStatus(enum.Enum):
    """A tracked frame's outcome; ``value`` is its name in ``track.json``."""

    OK = "ok"
    DEGENERATE = "degenerate"
    NO_PERSON = "no person"
    LOST = "lost"

    @property
    def message(self) -> str:
        """What the status means, for a reader of ``track.json``."""
        return _MESSAGES[self]


_MESSAGES = {
    FrameStatus.OK: "tracked",
    FrameStatus.DEGENERATE: "every particle scored zero likelihood; the filter re-seeded or "
                            "only predicted",
    FrameStatus.NO_PERSON: "no person in the frame (an empty or frame-filling mask or "
                           "silhouette, or no view observed)",
    FrameStatus.LOST: f"the estimate no longer follows the person: {LOST_RULE}",
}


def _outside(points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``(time,)`` whether more than half of each frame's ``(time, points, 2)`` lie outside
    the ``(width, height)`` frame (a non-finite point counts as outside)."""
    width, height = size
    x, y = points[..., 0], points[..., 1]
    inside = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x <= width) & (y >= 0) & (y <= height)
    return inside.mean(axis=-1) < 0.5


def _likelihood_drops(log_likelihood: np.ndarray) -> np.ndarray:
    """``(time,)`` whether each frame's log-likelihood falls far below its recent history."""
    values = np.asarray(log_likelihood, np.float64)
    drops = np.zeros(len(values), bool)
    for t in range(LOST_MIN_HISTORY, len(values)):
        history = values[max(0, t - LOST_WINDOW):t]
        history = history[np.isfinite(history)]
        if len(history) < LOST_MIN_HISTORY or not np.isfinite(values[t]):
            continue
        median = np.median(history)
        spread = max(float(np.median(np.abs(history - median))), LOST_MIN_SPREAD)
        drops[t] = values[t] < median - LOST_DROP_MADS * spread
    return drops


def frame_statuses(points: np.ndarray, size: tuple[int, int], *,
                   degenerate: np.ndarray | None = None,
                   no_person: np.ndarray | None = None,
                   log_likelihood: np.ndarray | None = None) -> list[FrameStatus]:
    """Each frame's :class:`FrameStatus`, by the rules of this module.

    Args:
        points: ``(time, points, 2)`` the estimate (markers, parts), pixels of a frame of
            ``size``.
        size: ``(width, height)`` of the frame the points are in.
        degenerate: ``(time,)`` bool, the filter's weights collapsed (None: judged from a
            non-finite ``log_likelihood`` alone).
        no_person: ``(time,)`` bool, the frame shows nobody (None: never).
        log_likelihood: ``(time,)`` the estimate's log-likelihood (None: ``lost`` by the frame
            alone).

    Returns:
        ``time`` statuses.
    """
    points = np.asarray(points, np.float64)
    count = len(points)
    collapsed = np.zeros(count, bool) if degenerate is None else np.asarray(degenerate, bool)
    if log_likelihood is not None:
        collapsed = collapsed | ~np.isfinite(np.asarray(log_likelihood, np.float64))
    nobody = np.zeros(count, bool) if no_person is None else np.asarray(no_person, bool)
    lost = _outside(points, size)
    if log_likelihood is not None:
        lost = lost | _likelihood_drops(log_likelihood)
    statuses = []
    for t in range(count):
        if collapsed[t]:
            statuses.append(FrameStatus.DEGENERATE)
        elif nobody[t]:
            statuses.append(FrameStatus.NO_PERSON)
        elif lost[t]:
            statuses.append(FrameStatus.LOST)
        else:
            statuses.append(FrameStatus.OK)
    return statuses


def status_counts(statuses: list[FrameStatus]) -> dict[str, int]:
    """How many frames have each status (every status named, zeros included)."""
    return {status.value: sum(item is status for item in statuses) for status in FrameStatus}


def status_legend() -> dict[str, str]:
    """Each status's name and message, for ``track.json``."""
    return {status.value: status.message for status in FrameStatus}
