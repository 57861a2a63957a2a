"""The per-frame status every ``jaxtrack track`` method writes into ``track.json``: the one
enum and its rules of :mod:`jaxtrack.trackers.status` (ok, degenerate, no person, lost), under
the name the commands have imported it by."""

from jaxtrack.trackers.status import (
    LOST_DROP_MADS,
    LOST_MIN_HISTORY,
    LOST_MIN_SPREAD,
    LOST_RULE,
    LOST_WINDOW,
    FrameStatus,
    frame_statuses,
    status_counts,
    status_legend,
)

__all__ = ["LOST_DROP_MADS", "LOST_MIN_HISTORY", "LOST_MIN_SPREAD", "LOST_RULE", "LOST_WINDOW",
           "FrameStatus", "frame_statuses", "status_counts", "status_legend"]
