"""The per-frame status of ``track.json`` (``jaxtrack.cli._status``): one enum, its messages,
and the rules that assign ok, degenerate, no person and lost."""

import numpy as np

from jaxtrack.cli._status import (
    LOST_DROP_MADS,
    LOST_RULE,
    LOST_WINDOW,
    FrameStatus,
    frame_statuses,
    status_counts,
    status_legend,
)

SIZE = (320, 240)


def _inside(count: int) -> np.ndarray:
    """``(count, 12, 2)`` a pose well inside the frame."""
    rng = np.random.default_rng(0)
    return np.tile(rng.uniform([100, 60], [220, 180], (12, 2)), (count, 1, 1))


def test_every_status_has_one_name_and_a_message():
    legend = status_legend()
    assert list(legend) == ["ok", "degenerate", "no person", "lost"]
    assert all(message for message in legend.values())
    assert LOST_RULE in FrameStatus.LOST.message


def test_an_estimate_leaving_the_frame_is_lost():
    points = _inside(4)
    points[1, :7, 0] += 400  # 7 of 12 markers right of the frame
    points[2, :6, 0] += 400  # exactly half: still followed
    points[3, 0] = np.nan  # a missing point counts as outside, one is not enough
    assert frame_statuses(points, SIZE) == [FrameStatus.OK, FrameStatus.LOST, FrameStatus.OK,
                                            FrameStatus.OK]


def test_a_log_likelihood_far_below_its_running_median_is_lost():
    rng = np.random.default_rng(1)
    count = 60
    values = -100 + rng.normal(0, 2.0, count)
    spread = np.median(np.abs(values[20:50] - np.median(values[20:50])))
    values[50] = np.median(values[20:50]) - (LOST_DROP_MADS + 2) * max(spread, 1.0)
    values[55] = np.median(values[25:55]) - (LOST_DROP_MADS - 2) * max(spread, 1.0)
    values[2] = -1000  # before the history is long enough: not judged by the likelihood
    statuses = frame_statuses(_inside(count), SIZE, log_likelihood=values)
    lost = [t for t, status in enumerate(statuses) if status is FrameStatus.LOST]
    assert lost == [50]
    assert LOST_WINDOW == 30


def test_degenerate_comes_before_no_person_before_lost():
    points = _inside(4)
    points[:, :, 0] += 1000  # every frame outside
    statuses = frame_statuses(points, SIZE, degenerate=np.array([True, False, False, False]),
                              no_person=np.array([True, True, False, False]),
                              log_likelihood=np.array([0.0, 0.0, 0.0, -np.inf]))
    assert statuses == [FrameStatus.DEGENERATE, FrameStatus.NO_PERSON, FrameStatus.LOST,
                        FrameStatus.DEGENERATE]
    assert status_counts(statuses) == {"ok": 0, "degenerate": 2, "no person": 1, "lost": 1}
