"""One video pipeline for every tracker: a video file in, ``overlay.mp4`` and ``track.json`` out.

:func:`track_video` runs any :class:`jaxtrack.trackers.Tracker` on a video file in bounded
memory:

1. the output folder is probed (a file created and removed there) before a frame is read;
2. the video is decoded a chunk at a time, downscaled for tracking
   (:func:`jaxtrack.vision.iter_video_chunks`), and each chunk becomes a
   :class:`jaxtrack.trackers.VideoChunk` holding only what the tracker reads
   (``Tracker.reads``): grey frames, colour frames, the person's masks (given, or the
   foreground against the video's median background), a detector's keypoints (given, scaled
   into tracking pixels) and the static scene's background; the chunks stream into
   :func:`jaxtrack.trackers.track`, so no more than a chunk of frames is ever held;
3. with ``smooth``, a tracker that has a whole-sequence smoother (``Tracker.smooth``) reports
   the smoothed estimate of every frame, and the filter's beside it; each frame gets a
   :class:`jaxtrack.trackers.status.FrameStatus` (ok, degenerate, no person, lost) by
   :func:`jaxtrack.trackers.status.frame_statuses`;
4. a second decoding pass draws the markers, scaled back to the video's own pixels, on the
   video's own frames, a chunk at a time, into a temporary file renamed onto ``overlay.mp4``
   when complete (:func:`jaxtrack.vision.overlay.write_overlay_video_from_file`);
5. ``track.json`` is written last, atomically: what ran, per frame the markers in the video's
   pixels, ESS, log-likelihood and status, the status legend and lost rule, and timings.

On an error or an interrupt (Ctrl-C) nothing half-written is left: temporary files are removed,
and an ``overlay.mp4`` written by this run is removed when ``track.json`` could not follow it.
A median background needs a pass of its own over the video (frames sampled evenly, at most
``max_samples`` held): :func:`video_background`. The command that calls this:
``jaxtrack track``.

Beyond one video decoded whole: ``stride`` tracks every ``stride``-th frame (a model's own
frame rate); a :class:`Window` cuts a fixed-size window from every tracked frame (and the
background and masks), placed where given or where its ``locate`` finds the subject in frames
sampled over the video; and several videos (views of one scene, one per calibrated camera) are
each tracked by the same tracker with the same key, cut to the length of the shortest, and
reported together by a ``report`` hook (:class:`ViewRun` per view), which also draws the
overlay from the views' frames decoded again a chunk at a time. A tracker whose observations
say why a frame was not observed (an estimate field ``reason``, its texts in the tracker's
``observation_reasons``) has those frames' status ``no person``.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import jax
import numpy as np
from jaxtyping import ArrayLike, Float, PRNGKeyArray

from jaxtrack.trackers import FrameEstimate, Tracker, TrackResult, VideoChunk, track
from jaxtrack.trackers.status import (
    LOST_RULE,
    frame_statuses,
    status_counts,
    status_legend,
)

__all__ = ["BACKGROUND_SAMPLES", "ViewRun", "Window", "cut_window", "default_marker_names",
           "track_video", "tracking_scale", "video_background"]

BACKGROUND_SAMPLES = 64
"""Frames, spread evenly over the video, whose per-pixel median is its background."""

_BASE_FIELDS = ("markers", "best_markers", "ess", "log_likelihood", "degenerate")


def default_marker_names(count: int) -> tuple[str, ...]:
    """The names of a tracker's ``count`` markers: the 12 upper-body markers of the image
    trackers, the linear-combination tracker's head and hands, the mixed-state tracker's five
    parts; ``marker_0``, ... otherwise."""
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.vision.parts import PART_NAMES

    known = {len(UPPER_BODY_12): UPPER_BODY_12, 3: ("head", "hand", "other_hand"),
             len(PART_NAMES): PART_NAMES}
    return tuple(known.get(count, [f"marker_{index}" for index in range(count)]))


def _probe_output(out_dir: Path) -> None:
    """Refuse (ValueError, one line naming ``out_dir``) a folder no file can be created in:
    what exists of it must be a folder in which a probe file can be created and removed (which
    sees what ``os.access`` does not: ``/proc``, a read-only mount)."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"output folder {out_dir} is a file; give a folder")
    existing = out_dir
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"output folder {out_dir}: cannot be created, {existing} is a file")
    try:
        handle, name = tempfile.mkstemp(dir=existing, prefix=".jaxtrack-probe-")
    except OSError as error:
        raise ValueError(f"output folder {out_dir}: cannot write into {existing} "
                         f"({error.strerror or type(error).__name__}); give a writable "
                         f"folder") from None
    os.close(handle)
    os.unlink(name)


def tracking_scale(video_size: tuple[int, int], *, scale: float | None = None,
                   max_size: int | None = None) -> float:
    """The resize factor frames of ``video_size`` ``(width, height)`` are tracked at: ``scale``,
    or the largest at most 1 that fits the longer side in ``max_size`` pixels (1 when neither
    is given)."""
    if scale is not None and max_size is not None:
        raise ValueError("give scale= or max_size=, not both")
    if scale is not None:
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be a positive resize factor, got {scale}")
        return float(scale)
    if max_size is not None:
        if int(max_size) != max_size or max_size < 32:
            raise ValueError(f"max_size must be an integer of at least 32 pixels, got "
                             f"{max_size}")
        return min(1.0, max_size / max(video_size))
    return 1.0


@dataclass(frozen=True)
class Window:
    """A window of ``size`` ``(width, height)`` tracking pixels cut from every tracked frame,
    and from the background and masks alike: at ``origin`` ``(x0, y0)`` of the (scaled)
    frames, or where ``locate(frames, background, masks)`` puts it, given frames spread evenly
    over the video (``(samples, height, width, 3)`` uint8 RGB), the video's median
    background (None where masks are given) and the masks of those frames (or None). Where
    the window leaves the frame, the frame's edge is repeated (:func:`cut_window`)."""

    size: tuple[int, int]
    origin: tuple[float, float] | None = None
    locate: Callable[[np.ndarray, np.ndarray | None, np.ndarray | None], ArrayLike] | None = None

    def __post_init__(self):
        size = tuple(self.size)
        if len(size) != 2 or not all(isinstance(v, int | np.integer) and v >= 8 for v in size):
            raise ValueError(f"window size must be (width, height), integers of at least 8 "
                             f"pixels, got {self.size!r}")
        if (self.origin is None) == (self.locate is None):
            raise ValueError("give the window's origin=(x0, y0) or locate=..., one of them")


def cut_window(images: np.ndarray, origin: ArrayLike, size: tuple[int, int], *,
               mode: str = "edge") -> np.ndarray:
    """``images[..., y0:y0+h, x0:x0+w, :]`` for ``origin`` ``(x0, y0)`` and ``size``
    ``(w, h)``, the image's edge repeated where the window leaves it (the same for every frame
    and the background, so it is never foreground); ``mode="constant"`` pads with zeros
    instead (for masks: never the person)."""
    x0, y0 = (int(v) for v in origin)
    width, height = size
    full_height, full_width = images.shape[-3:-1]
    pad = [(0, 0)] * (images.ndim - 3) + [(max(0, -y0), max(0, y0 + height - full_height)),
                                          (max(0, -x0), max(0, x0 + width - full_width)), (0, 0)]
    padded = np.pad(images, pad, mode=mode)
    x0, y0 = x0 + pad[-2][0], y0 + pad[-3][0]
    return np.ascontiguousarray(padded[..., y0:y0 + height, x0:x0 + width, :])


def _sample_frames(video, *, scale: float, start: int, max_frames: int | None, stride: int,
                   max_samples: int, chunk_frames: int
                   ) -> tuple[list[np.ndarray], list[int], int]:
    """Frames spread evenly over a video in one decoding pass, at most ``2 max_samples`` kept
    (every ``step``-th frame is kept, and the step doubles whenever that would pass
    ``2 max_samples``): ``(frames, their video frame indices, frames decoded)``."""
    from jaxtrack.vision import iter_video_chunks

    kept, indices, step, seen = [], [], 1, 0
    for chunk in iter_video_chunks(video, chunk_frames, start=start, max_frames=max_frames,
                                   stride=stride, scale=scale):
        for frame, index in zip(chunk.frames, chunk.frame_indices.tolist(), strict=True):
            if seen % step == 0:
                kept.append(frame)
                indices.append(index)
                if len(kept) > 2 * max_samples:  # keep every other one: still evenly spaced
                    kept, indices, step = kept[::2], indices[::2], step * 2
            seen += 1
    return kept, indices, seen


def video_background(video: str | os.PathLike, *, scale: float = 1.0, start: int = 0,
                     max_frames: int | None = None, max_samples: int = BACKGROUND_SAMPLES,
                     chunk_frames: int = 32, grey: bool = False, stride: int = 1) -> np.ndarray:
    """The per-pixel median of frames spread evenly over a video file (the static scene):
    one decoding pass, at most ``2 max_samples`` frames kept (every ``step``-th frame is
    kept, and the step doubles whenever that would pass ``2 max_samples``) besides the
    ``chunk_frames`` being decoded.

    Args:
        video: the video file.
        scale: resize factor of the frames (as they are tracked).
        start, max_frames, stride: the frames tracked (:func:`jaxtrack.vision.read_video`).
        max_samples: frames the median is taken over (at least 3).
        chunk_frames: frames decoded at a time.
        grey: the median of the frames' grey levels instead (as
            :func:`jaxtrack.vision.median_grey_background`: the background the image
            trackers' foreground term compares grey frames with).

    Returns:
        ``(height, width, 3)`` uint8 RGB background, or with ``grey`` ``(height, width)``
        float32 grey levels in [0, 1].

    Raises:
        ValueError: fewer than 3 frames (the person would be background).
    """
    if int(max_samples) != max_samples or max_samples < 3:
        raise ValueError(f"max_samples must be an integer of at least 3, got {max_samples}")
    kept, _, seen = _sample_frames(video, scale=scale, start=start, max_frames=max_frames,
                                   stride=stride, max_samples=max_samples,
                                   chunk_frames=chunk_frames)
    return _median(video, kept, seen, max_samples, grey=grey)


def _median(video, kept: list[np.ndarray], seen: int, max_samples: int, *,
            grey: bool = False) -> np.ndarray:
    from jaxtrack.vision import median_background, median_grey_background, to_grey

    if len(kept) < 3:
        raise ValueError(f"{video}: a median background needs at least 3 frames, got "
                         f"{seen}; give the empty scene as background=...")
    if grey:
        return median_grey_background(to_grey(np.stack(kept)), max_samples=max_samples)
    return median_background(np.stack(kept), max_samples=max_samples)


def _check_keypoints(keypoints, name: str = "keypoints") -> tuple[np.ndarray, np.ndarray]:
    """``(points (frames, 12, 2), confidence (frames, 12))`` of the given keypoints."""
    if isinstance(keypoints, tuple) and len(keypoints) == 2:
        points, confidence = (np.asarray(value) for value in keypoints)
    else:
        points = np.asarray(keypoints)
        confidence = np.where(np.isfinite(points).all(axis=-1), 1.0, 0.0)
    if points.ndim != 3 or points.shape[-1] != 2 or confidence.shape != points.shape[:2]:
        raise ValueError(f"{name} must be (points (frames, markers, 2), confidence (frames, "
                         f"markers)) in the video's pixels, got shapes {points.shape} and "
                         f"{confidence.shape}")
    return points, confidence


def _named(points: np.ndarray, names: Sequence[str]) -> dict:
    return {name: [_number(x, 2), _number(y, 2)] for name, (x, y) in zip(names, points,
                                                                        strict=True)}


def _number(value, digits: int | None = None):
    """A JSON number, or None where not finite."""
    value = float(value)
    if not math.isfinite(value):
        return None
    return round(value, digits) if digits is not None else value


def _per_frame_extras(estimates) -> dict[str, np.ndarray]:
    """The tracker's own per-frame scalars beyond the common report (``(time,)`` leaves of its
    estimate: a cluster, a fitness, whether a person was found)."""
    extras = {}
    for name in getattr(type(estimates), "__dataclass_fields__", {}):
        if name in _BASE_FIELDS:
            continue
        value = getattr(estimates, name, None)
        if isinstance(value, np.ndarray | jax.Array) and np.ndim(value) == 1:
            extras[name] = np.asarray(value)
    return extras


def _ahead(items: Iterator, depth: int = 1) -> Iterator:
    """``items``, each made in a thread ``depth`` items ahead of the one taken (decoding and
    preparing the next chunk while the current one is observed and tracked: OpenCV and NumPy
    release the GIL). An error in the thread is raised where the item would have been taken;
    closing the iterator (an error or Ctrl-C in the consumer) stops the thread."""
    import queue
    import threading

    done = object()
    ready: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(item) -> bool:
        while not stop.is_set():
            try:
                ready.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def work() -> None:
        try:
            for item in items:
                if not put((item, None)):
                    return
            put((done, None))
        except BaseException as error:  # handed to the consumer, raised there
            put((done, error))
        finally:
            close = getattr(items, "close", None)  # a generator: let it release its video
            if close is not None:
                close()

    thread = threading.Thread(target=work, name="jaxtrack-decoder", daemon=True)
    thread.start()
    try:
        while True:
            item, error = ready.get()
            if error is not None:
                raise error
            if item is done:
                return
            yield item
    finally:
        stop.set()
        thread.join()


@dataclass
class ViewRun:
    """One video (a view) as :func:`track_video` tracked it.

    Attributes:
        video: the video file.
        name: the view's name.
        result: the tracker's :class:`TrackResult` (tracking pixels: inside the window where
            one is cut).
        frame_indices: ``(time,)`` the video frames tracked.
        size: ``(width, height)`` of the video's own frames.
        tracked_size: ``(width, height)`` of the frames tracked (the window's where one is
            cut).
        factors: ``(2,)`` tracking pixels per video pixel, per axis (the decoder rounds the
            scaled size).
        origin: ``(2,)`` the window's origin in the scaled frames (zeros without a window).
        stride: every ``stride``-th video frame was tracked.
        fps: the video's own frame rate (NaN where the file does not say).
        located_from: frames with a person that ``Window.locate`` placed the window from
            (where it returns ``(origin, frames)``), else the frames it was given; None
            without ``locate``.
        masks: whether the person's masks were given for this view.
        background: where the empty scene came from: ``"given"``, ``"median of the video"``,
            or None.
        reasons: per frame why it was not observed (``""``: observed), where the tracker's
            estimates carry ``reason`` codes and the tracker their texts
            (``observation_reasons``); else None.
        no_person: ``(time,)`` frames that show nobody: an empty or frame-filling mask, or
            a reason the frame was not observed.
        first_chunk: frames in the first chunk tracked (for the timings).
        prepare_seconds: per chunk, the seconds it took to decode and prepare.
    """

    video: Path
    name: str
    result: TrackResult
    frame_indices: np.ndarray
    size: tuple[int, int]
    tracked_size: tuple[int, int]
    factors: np.ndarray
    origin: np.ndarray
    stride: int
    fps: float
    located_from: int | None
    masks: bool
    background: str | None
    reasons: list[str] | None
    no_person: np.ndarray
    first_chunk: int
    prepare_seconds: list[float]


def _per_view(value, count: int, name: str) -> list:
    """``value`` for each of ``count`` videos: a list or tuple of one per video, or one value
    for all."""
    if isinstance(value, list | tuple):
        if len(value) != count:
            raise ValueError(f"{name} must be one per video ({count}), got {len(value)}")
        return list(value)
    return [value] * count


def _reasons(tracker: Tracker, estimates) -> list[str] | None:
    """Per frame the text of the estimate's ``reason`` code (``""``: observed), or None."""
    texts = getattr(tracker, "observation_reasons", None)
    codes = getattr(estimates, "reason", None)
    if texts is None or codes is None:
        return None
    return [texts[int(code)] if 0 <= int(code) < len(texts) else f"reason {int(code)}"
            for code in np.asarray(codes)]


def _views_frames(views: list[dict], count: int, chunk_frames: int) -> Iterator[list]:
    """Per tracked frame, the views' frames as they were tracked (scaled, cut to the window),
    decoded again a chunk at a time in step."""
    from jaxtrack.vision import VideoError, iter_video_chunks

    def frames(view) -> Iterator[np.ndarray]:
        for chunk in iter_video_chunks(view["path"], chunk_frames, start=view["start"],
                                       max_frames=count, stride=view["stride"],
                                       scale=view["resize"]):
            images = chunk.frames
            if view["window"] is not None:
                images = cut_window(images, view["origin"], view["window"])
            yield from images

    streams = [frames(view) for view in views]
    done = 0
    for images in zip(*streams, strict=False):
        yield list(images)
        done += 1
    if done != count:
        raise VideoError(f"{views[0]['path']}: {done} frames on a second reading, but {count} "
                         f"were tracked")


def _track_view(tracker: Tracker, key, view: dict, name: str, pose, per_chunk: int,
                progress: bool, window: Window | None, chunks, runs: list) -> float:
    """Track one view (``track_video``'s chunks of it), append its :class:`ViewRun` to
    ``runs``; returns the seconds the tracking pass took."""
    frame_indices: list[np.ndarray] = []
    no_person: list[np.ndarray] = []
    prepare: list[float] = []  # seconds each chunk took to decode and prepare
    tick = time.perf_counter()
    stream = _ahead(chunks(view, frame_indices, no_person, prepare))
    try:
        result = track(tracker, key, stream, pose, chunk_size=per_chunk,
                       progress=progress, description=f"tracking {view['path'].name}")
    finally:  # on an error too: stop the decoding thread and release the video
        stream.close()
    seconds = time.perf_counter() - tick
    indices = np.concatenate(frame_indices)
    if result.markers.shape[0] != len(indices):
        raise RuntimeError(f"the tracker reported {result.markers.shape[0]} frames of "
                           f"{len(indices)}")
    nobody = np.concatenate(no_person) if no_person else np.zeros(len(indices), bool)
    reasons = _reasons(tracker, result.estimates)
    if reasons is not None:  # the observation says why nobody was seen
        nobody = nobody | np.array([bool(text) for text in reasons])
    tracked_size = (tuple(window.size) if window is not None
                    else tuple(view["scaled_size"]))
    runs.append(ViewRun(
        video=view["path"], name=name, result=result, frame_indices=indices,
        size=tuple(view["size"]), tracked_size=tracked_size, factors=view["factors"],
        origin=view["origin"], stride=view["stride"], fps=float(view["first"].source_fps),
        located_from=view["located_from"], masks=view["masks"] is not None,
        background=view["scene_from"], reasons=reasons, no_person=nobody,
        first_chunk=len(frame_indices[0]), prepare_seconds=prepare))
    return seconds


def track_video(tracker: Tracker, video: str | os.PathLike | Sequence[str | os.PathLike],
                out_dir: str | os.PathLike, *,
                key: PRNGKeyArray, initial_pose: Float[ArrayLike, "markers 2"] | None = None,
                scale: float | Sequence[float] | None = None, max_size: int | None = None,
                start: int = 0, max_frames: int | None = None, stride: int | Sequence[int] = 1,
                window: Window | None = None, chunk_frames: int = 64,
                masks: np.ndarray | Sequence[np.ndarray | None] | None = None,
                keypoints: tuple[np.ndarray, np.ndarray] | np.ndarray | None = None,
                background: np.ndarray | Sequence[np.ndarray | None] | None = None,
                marker_names: Sequence[str] | None = None, seed: int | None = None,
                detector_seconds: float | None = None, progress: bool = True,
                extra_record: dict | None = None, smooth: bool = False,
                annotate: Callable[[TrackResult, FrameEstimate | None, np.ndarray],
                                   tuple[list[dict], list[str]]] | None = None,
                view_names: Sequence[str] | None = None,
                report: Callable[[list[ViewRun], dict],
                                 tuple[dict, Callable[[Iterator[list], Path, float], Path]]]
                | None = None) -> dict:
    """Track a video file (or several views, each its own file) with any tracker; write
    ``out_dir/overlay.mp4`` and ``out_dir/track.json`` (module docstring).

    Args:
        tracker: any :class:`jaxtrack.trackers.Tracker`; what it reads (``tracker.reads``) is
            prepared for it. One that runs a detector inside its update, on the region it
            predicts (``jaxtrack.experiments._guided_detection``), has ``host_report(markers,
            factors)``: its per-frame and total record join ``track.json``
            (``guided_detection``), the detector's time inside the tracking pass is reported
            apart from the tracker's (``guided_detector_wall_seconds``,
            ``tracker_seconds_per_frame``), and its ``close()`` is called when the run ends.
        video: the video file, or one per view (then ``report`` is needed).
        out_dir: the output folder (created if missing, probed before a frame is read).
        key: PRNG key of the tracking (the same for every view: views differ by what they see,
            not by their noise).
        initial_pose: ``(markers, 2)`` the pose in the first tracked frame, in the video's own
            pixels (None for trackers that start from the frame alone).
        scale, max_size: the frames are tracked at ``scale`` times their size (one per view, or
            one for all), or with their longer side at most ``max_size`` pixels
            (:func:`tracking_scale`).
        start, max_frames, stride: the video frames tracked: from ``start``, every
            ``stride``-th (one per view, or one for all), at most ``max_frames`` of them.
        window: a :class:`Window` cut from every tracked frame (None: the whole frame).
        chunk_frames: frames decoded, prepared and tracked at a time (the first chunk one
            more): the memory bound.
        masks: ``(video frames, height, width)`` bool masks of the person, one per video frame
            from its first, at any size of the video's aspect ratio (a ``np.memmap`` keeps them
            on disk: only the chunk's frames are read); with several views a list, one (or
            None) per view; None: where the tracker reads masks, the foreground against the
            video's median background. Given masks are passed to the tracker even where
            ``reads`` does not name them (the image trackers' foreground term reads them), and
            it refuses them where it cannot use them.
        keypoints: a detector's ``(points (video frames, markers, 2), confidence (video
            frames, markers))`` in the video's own pixels, one row per video frame from its
            first (NaN where not found), or the points alone (one video only).
        background: ``(height, width, 3)`` uint8 RGB empty scene at the video's size (or
            already at the tracking size; one per view with several); None: the median of the
            video (:func:`video_background`) where needed (the tracker reads it and no masks
            are given, or foreground masks are made).
        marker_names: names of the tracker's markers (:func:`default_marker_names`).
        seed: the seed ``key`` was made from, for the record.
        detector_seconds: time a detector took to make ``keypoints``, for the record.
        progress: show a progress bar while tracking.
        extra_record: more JSON-able entries for ``track.json`` (the command's options, how the
            initial pose was found); they may not replace the pipeline's own.
        smooth: report the tracker's whole-sequence smoother (``Tracker.smooth``: the estimate
            of every frame given the whole video) as ``markers``, drawn and scored for status,
            with the filter's as ``filtered_markers``; refused for a tracker without one.
        annotate: ``annotate(result, smoothed, factors)`` gives the tracker's own per-frame
            JSON entries (replacing the estimate's scalars the pipeline writes otherwise) and
            a label per frame drawn on the overlay; ``factors`` are the tracking pixels per
            video pixel, per axis.
        view_names: the views' names (default ``view0``, ``view1``, ...).
        report: ``report(runs, timings)`` makes ``track.json``'s record itself from the
            :class:`ViewRun` of each view and the pipeline's timings, and returns it with the
            overlay's writer, ``draw(frames, path, fps)``: ``frames`` yields per tracked frame
            the views' frames as tracked (scaled, cut to the window), decoded a chunk at a
            time; it writes ``path`` and returns it. Needed for several views.

    Returns:
        What ``track.json`` holds (a dict), with ``"result"``: the :class:`TrackResult` (in
        tracking pixels; the first view's), ``"runs"``: every view's :class:`ViewRun` and
        ``"paths"``: the two files written.

    Raises:
        ValueError: an unwritable ``out_dir`` (before a frame is read), inputs that disagree
            with the video or the tracker (one line naming them);
            :class:`jaxtrack.vision.VideoError`: the video cannot be read.
    """
    from jaxtrack.vision import iter_video_chunks, masks_for_frames, read_video, to_grey
    from jaxtrack.vision.foreground import foreground_mask
    from jaxtrack.vision.overlay import write_overlay_video_from_file

    if not isinstance(tracker, Tracker):
        raise TypeError(f"tracker must be a jaxtrack.trackers.Tracker, got "
                        f"{type(tracker).__name__}")
    if not isinstance(chunk_frames, int) or chunk_frames < 1:
        raise ValueError(f"chunk_frames must be a positive integer, got {chunk_frames!r}")
    if extra_record is not None:
        if not isinstance(extra_record, dict):
            raise TypeError("extra_record must be a dict of JSON-able entries")
    if smooth and type(tracker).smooth is Tracker.smooth:
        raise ValueError(f"the {type(tracker).__name__} has no whole-sequence smoother; leave "
                         f"smooth out")
    out_dir = Path(out_dir)
    _probe_output(out_dir)  # before a frame is read
    videos = ([Path(video)] if isinstance(video, str | os.PathLike)
              else [Path(path) for path in video])
    if not videos:
        raise ValueError("give at least one video")
    several = len(videos) > 1
    guided = callable(getattr(tracker, "host_report", None))
    if guided and (several or window is not None or report is not None):
        raise ValueError("a tracker that detects on the region it predicts (host_report) "
                         "tracks one whole video: leave the window, report and other views out")
    if several and report is None:
        raise ValueError(f"{len(videos)} videos (views) are reported by a report=... hook; "
                         f"give one video, or report=")
    if report is not None and (smooth or annotate is not None):
        raise ValueError("report= makes the whole record: leave smooth and annotate out")
    if window is not None and not isinstance(window, Window):
        raise TypeError(f"window must be a jaxtrack.experiments.pipeline.Window, got "
                        f"{type(window).__name__}")
    strides = _per_view(stride, len(videos), "stride")
    if not all(isinstance(value, int | np.integer) and value >= 1 for value in strides):
        raise ValueError(f"stride must be a positive integer, got {stride!r}")
    scales = _per_view(scale, len(videos), "scale")
    masks_of = _per_view(masks, len(videos), "masks") if several else [masks]
    backgrounds = _per_view(background, len(videos), "background") if several else [background]
    names = list(view_names) if view_names is not None else [
        f"view{index}" for index in range(len(videos))]
    if len(names) != len(videos):
        raise ValueError(f"view_names names {len(names)} views for {len(videos)} videos")
    reads = tuple(tracker.reads)
    given_keypoints = None if keypoints is None else _check_keypoints(keypoints)
    method = str(tracker.options().get("method", type(tracker).__name__))
    if "keypoints" in reads and given_keypoints is None:
        raise ValueError(f"the {method} tracker reads a detector's keypoints: give "
                         f"keypoints=...")
    if "keypoints" not in reads and given_keypoints is not None:
        raise ValueError(f"the {method} tracker does not read keypoints (an image tracker "
                         f"reads them with its likelihood's keypoint term): leave keypoints "
                         f"out")
    if given_keypoints is not None and several:
        raise ValueError("keypoints are given for one video; give one video")
    for given in masks_of:
        if given is not None and (np.ndim(given) != 3):
            raise ValueError(f"masks must be (video frames, height, width) bool, got shape "
                             f"{np.shape(given)}")

    views = []  # per video: what is known before tracking
    timings: dict[str, float | None] = {"background_seconds": 0.0}
    for index, path in enumerate(videos):
        first = read_video(path, start=start, max_frames=1)
        video_size = first.image_size
        width, height = video_size
        resize = tracking_scale(video_size, scale=scales[index], max_size=max_size)
        scaled_size = read_video(path, start=start, max_frames=1, scale=resize).image_size
        # the decoder rounds the size: markers go back and forth by each axis's own factor
        factors = np.array([scaled_size[0] / width, scaled_size[1] / height])
        view_masks = masks_of[index]
        needs_masks = "masks" in reads and view_masks is None
        needs_background = "background" in reads and view_masks is None
        scene, scene_from = None, None
        if backgrounds[index] is not None:
            scene, scene_from = np.asarray(backgrounds[index]), "given"
            if scene.ndim != 3 or scene.shape[-1] != 3 or scene.dtype != np.uint8:
                raise ValueError(f"background must be (height, width, 3) uint8 RGB, got shape "
                                 f"{scene.shape} dtype {scene.dtype}")
            if scene.shape[1::-1] == video_size and resize != 1.0:
                from jaxtrack.vision.video import _resize

                # as the decoder resizes the frames, so that the scene matches them pixel for
                # pixel
                scene = _resize(scene, resize)
            if scene.shape[1::-1] != scaled_size:
                raise ValueError(f"background is {scene.shape[1]}x{scene.shape[0]}; give the "
                                 f"empty scene at the video's size {width}x{height}")
        views.append({"path": path, "first": first, "size": video_size, "resize": resize,
                      "scaled_size": scaled_size, "factors": factors, "masks": view_masks,
                      "needs_masks": needs_masks, "scene": scene, "scene_from": scene_from,
                      "sample": (needs_masks or needs_background) and scene is None
                      or (window is not None and window.locate is not None) or several,
                      "stride": int(strides[index]), "start": start, "origin": np.zeros(2),
                      "window": None if window is None else tuple(window.size),
                      "located_from": None})
    count = max_frames
    tick = time.perf_counter()
    for _ in range(2):  # a second pass where the views' lengths differ: sampled as tracked
        lengths = []
        for view in views:
            if not view["sample"]:
                continue
            view["kept"], view["kept_indices"], seen = _sample_frames(
                view["path"], scale=view["resize"], start=start, max_frames=count,
                stride=view["stride"], max_samples=BACKGROUND_SAMPLES,
                chunk_frames=chunk_frames)
            view["seen"] = seen
            lengths.append(seen)
        if not several or len(set(lengths)) == 1:
            break
        count = min(lengths)
    if several:
        count = min(view["seen"] for view in views)
    for view in views:
        if not view["sample"]:
            continue
        if (view["needs_masks"] or "background" in reads and view["masks"] is None) \
                and view["scene"] is None:
            view["scene"] = _median(view["path"], view["kept"], view["seen"],
                                    BACKGROUND_SAMPLES)
            view["scene_from"] = "median of the video"
        if window is not None:
            if window.locate is not None:
                sampled = None
                if view["masks"] is not None:
                    sampled = masks_for_frames(view["masks"], np.asarray(view["kept_indices"]),
                                               view["scaled_size"], name="masks")
                located = window.locate(np.stack(view["kept"]), view["scene"], sampled)
                if isinstance(located, tuple) and len(located) == 2 \
                        and np.ndim(located[0]) == 1:
                    located, view["located_from"] = located[0], int(located[1])
                else:
                    view["located_from"] = len(view["kept"])
                view["origin"] = np.asarray(located, np.float64).reshape(2)
        del view["kept"], view["kept_indices"]
    for view in views:
        if window is not None:
            if window.origin is not None:
                view["origin"] = np.asarray(window.origin, np.float64).reshape(2)
            if view["scene"] is not None:
                view["scene"] = cut_window(view["scene"], view["origin"], window.size)
    timings["background_seconds"] = time.perf_counter() - tick
    per_chunk = chunk_frames
    if report is not None and all(view["sample"] for view in views):
        # the length is known: equal chunks, so that little of the last one is padding (as
        # track() does for a video of known length)
        known = min(view["seen"] for view in views)
        if known > 1:
            per_chunk = math.ceil((known - 1) / math.ceil((known - 1) / chunk_frames))
    pose = None
    if initial_pose is not None:
        pose = np.asarray(initial_pose, np.float64)
        if pose.ndim != 2 or pose.shape[-1] != 2:
            raise ValueError(f"initial_pose must be (markers, 2) video pixels, got shape "
                             f"{pose.shape}")
        pose = pose * views[0]["factors"] - views[0]["origin"]

    def grey_only(view) -> bool:
        """Whether the tracker needs the view's grey frames alone (no colour, no foreground
        made from the colour frames): then they are decoded straight to grey."""
        return "grey" in reads and "colour" not in reads and not view["needs_masks"]

    def groups(view) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``(frames, file indices)``: per_chunk + 1 frames first, then per_chunk at a
        time, so that track()'s compiled chunks (frame 0 is its set-up) line up with the
        chunks given to it and it never joins one chunk's observations to the next's. The
        frames are RGB, or grey levels (``to_grey``'s, bit for bit) where :func:`grey_only`:
        decoding straight to grey makes no RGB copy, and costs several times less."""
        for decoded in iter_video_chunks(view["path"], per_chunk, start=start,
                                         max_frames=count, stride=view["stride"],
                                         scale=view["resize"], grey=grey_only(view),
                                         first_chunk_size=per_chunk + 1):
            yield decoded.frames, decoded.frame_indices

    def chunks(view, frame_indices, no_person, prepare) -> Iterator[VideoChunk]:
        decoder = groups(view)
        given_masks, scene = view["masks"], view["scene"]
        decoded_grey = grey_only(view)
        while True:
            tick = time.perf_counter()
            group = next(decoder, None)
            if group is None:
                return
            rgb, indices = group
            grey = None
            if decoded_grey:
                grey, rgb = rgb, None
                if window is not None:
                    grey = cut_window(grey[..., None], view["origin"], window.size)[..., 0]
            frame_indices.append(indices)
            person = None
            if given_masks is not None:
                if indices[-1] >= len(given_masks):
                    raise ValueError(f"masks hold {len(given_masks)} frames, but video frame "
                                     f"{int(indices[-1])} is tracked (one mask per video "
                                     f"frame, from its first)")
                # only the chunk's masks are read (masks may be a np.memmap on disk)
                cut = np.asarray(given_masks[int(indices[0]):int(indices[-1]) + 1], bool)
                person = masks_for_frames(cut, indices - indices[0], view["scaled_size"],
                                          name="masks")
                if window is not None:  # outside the frame: never the person
                    person = cut_window(person[..., None], view["origin"], window.size,
                                        mode="constant")[..., 0]
            if window is not None and rgb is not None:
                rgb = cut_window(rgb, view["origin"], window.size)
            if given_masks is None and view["needs_masks"]:
                person = np.stack([foreground_mask(image, scene) for image in rgb])
            if person is not None:
                area = person.mean(axis=(1, 2))
                no_person.append((area == 0) | (area == 1))
            points = None
            if given_keypoints is not None:
                if indices[-1] >= len(given_keypoints[0]):
                    raise ValueError(f"keypoints hold {len(given_keypoints[0])} frames, but "
                                     f"video frame {int(indices[-1])} is tracked (one row per "
                                     f"video frame, from its first)")
                points = given_keypoints[0][indices] * view["factors"]
                if window is not None:
                    points = points - view["origin"]
                points = (points, given_keypoints[1][indices])
            if "grey" in reads and grey is None:
                # frame by frame: the same values as to_grey(rgb), without its chunk-sized
                # temporaries (two float copies of the chunk, page faults that cost several
                # times the arithmetic)
                grey = np.empty(rgb.shape[:3], np.float32)
                for index, image in enumerate(rgb):
                    grey[index] = to_grey(image)
            chunk = VideoChunk(
                grey=grey,
                colour=rgb if "colour" in reads else None, masks=person, keypoints=points,
                background=scene if ("background" in reads and scene is not None) else None)
            prepare.append(time.perf_counter() - tick)
            yield chunk

    runs, tracking_seconds = [], 0.0
    try:
        for view, name in zip(views, names, strict=True):
            tracking_seconds += _track_view(
                tracker, key, view, name, pose, per_chunk, progress, window, chunks, runs)
        host = tracker.host_report(runs[0].result.markers, views[0]["factors"]) \
            if guided else None
    finally:  # the tracker's host side (a detector's process) ends with the run
        if guided and callable(getattr(tracker, "close", None)):
            tracker.close()
    if several and len({len(run.frame_indices) for run in runs}) != 1:
        raise RuntimeError("the views were tracked over different numbers of frames")
    run = runs[0]
    result, indices, count = run.result, run.frame_indices, len(run.frame_indices)
    first = views[0]["first"]
    frame_rate = first.source_fps / run.stride
    fps = frame_rate if math.isfinite(frame_rate) else None
    timings.update({
        "compile_seconds": sum(r.result.compile_seconds for r in runs),
        "seconds_per_frame": result.seconds_per_frame,
        "observe_seconds": sum(r.result.observe_seconds for r in runs),
        "decode_and_prepare_seconds": sum(sum(r.prepare_seconds) for r in runs),
        "tracking_pass_seconds": tracking_seconds, "detector_seconds": detector_seconds})
    if host is not None:  # the detector's time inside the tracking pass, apart from the tracker's
        inside = host["wall_seconds"]
        timings.update({
            "guided_detector_seconds": host["record"]["detector_seconds"],
            "guided_detector_wall_seconds": inside,
            "tracker_seconds_per_frame": max(
                0.0, result.seconds_per_frame - inside / max(count - 1, 1))})

    created = []  # the folders made here, removed again (when empty) on failure
    missing = out_dir
    while not missing.exists():
        created.append(missing)
        missing = missing.parent
    overlay_path, json_path = out_dir / "overlay.mp4", out_dir / "track.json"
    written = []
    try:
        if report is not None:
            record, draw = report(runs, dict(timings))
            out_dir.mkdir(parents=True, exist_ok=True)
            written.append(draw(_views_frames(views, count, min(chunk_frames, 32)),
                                overlay_path, fps or 30.0))
        else:
            record = _single_record(
                tracker, run, views[0], smooth, annotate, marker_names, method, reads, seed,
                given_keypoints is not None, pose, window, timings, fps,
                extra_keys=bool(window is not None or run.stride != 1), host=host)
            out_dir.mkdir(parents=True, exist_ok=True)
            tick = time.perf_counter()
            markers, names_, labels = record.pop("_overlay")
            labels = [f"{labels[t] + '  ' if labels else ''}{t + 1}/{count} "
                      f"{record['frames'][t]['status']}" for t in range(count)]
            if host is not None:  # which detection the track followed (guided detection)
                labels = [label + (f", followed {frame['followed']}" if frame else "")
                          for label, frame in zip(labels, host["frames"], strict=True)]
            if run.stride == 1 and window is None:
                written.append(write_overlay_video_from_file(
                    run.video, indices, {method: markers}, overlay_path, fps=fps or 30.0,
                    marker_names=names_, chunk_size=min(chunk_frames, 32), labels=labels))
            else:
                written.append(_write_strided_overlay(
                    run.video, start, run.stride, count, {method: markers}, overlay_path,
                    fps=fps or 30.0, marker_names=names_, labels=labels,
                    chunk_size=min(chunk_frames, 32)))
            record["timings"]["overlay_seconds"] = time.perf_counter() - tick
        if extra_record:
            clashes = sorted(set(extra_record) & set(record))
            if clashes:
                raise ValueError(f"extra_record may not replace the pipeline's own entries "
                                 f"{', '.join(clashes)}")
            record.update(extra_record)
        from jaxtrack._files import write_json_atomically

        written.append(write_json_atomically(json_path, record))  # last: the run is complete
    except BaseException:
        for path in written:
            Path(path).unlink(missing_ok=True)
        for folder in created:  # deepest first
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    return {**record, "result": result, "runs": runs,
            "paths": {"overlay": overlay_path, "json": json_path}}


def _write_strided_overlay(video: Path, start: int, stride: int, count: int, tracks: dict,
                           path: Path, *, fps: float, marker_names: Sequence[str],
                           labels: Sequence[str], chunk_size: int) -> Path:
    """The overlay of every ``stride``-th frame from ``start`` (``count`` of them): the
    video's own frames, at its own size, decoded a chunk at a time, the markers drawn on."""
    from jaxtrack.vision import VideoError, iter_video_chunks, read_video, write_frames
    from jaxtrack.vision.overlay import draw_tracks

    size = read_video(video, start=start, max_frames=1).image_size

    def frames() -> Iterator[np.ndarray]:
        done = 0
        for chunk in iter_video_chunks(video, chunk_size, start=start, max_frames=count,
                                       stride=stride):
            for image in chunk.frames:
                yield draw_tracks(image, {m: track[done] for m, track in tracks.items()},
                                  marker_names, label=labels[done])
                done += 1
        if done != count:
            raise VideoError(f"{video}: {done} frames from frame {start}, but {count} were "
                             f"tracked")

    return write_frames(frames(), path, fps, size)


def _single_record(tracker, run: ViewRun, view: dict, smooth, annotate, marker_names, method,
                   reads, seed, keypoints_given: bool, pose, window, timings, fps, *,
                   extra_keys: bool, host: dict | None = None) -> dict:
    """``track.json``'s record of one video tracked (the module docstring), with the
    overlay's ``(markers in video pixels, marker names, labels)`` under ``"_overlay"``."""
    result, indices, factors, origin = run.result, run.frame_indices, run.factors, run.origin
    count = len(indices)
    first = view["first"]
    width, height = run.size
    smoothed = None
    if smooth:
        tick = time.perf_counter()
        smoothed = tracker.smooth(result.estimates)
        timings["smooth_seconds"] = time.perf_counter() - tick
    shown = result.estimates if smoothed is None else smoothed
    names = tuple(marker_names) if marker_names is not None else default_marker_names(
        result.markers.shape[1])
    if len(names) != result.markers.shape[1]:
        raise ValueError(f"marker_names names {len(names)} markers, the tracker reports "
                         f"{result.markers.shape[1]}")
    extras = _per_frame_extras(shown)
    shown_markers = np.asarray(shown.markers) if smoothed is not None else result.markers
    nobody = run.no_person
    if "found" in extras:  # the tracker saw nobody (no silhouette with its skin blobs)
        nobody = nobody | ~extras["found"].astype(bool)
    statuses = frame_statuses(shown_markers, run.tracked_size, degenerate=result.degenerate,
                              no_person=nobody, log_likelihood=result.log_likelihood)
    to_video = ((lambda points: points / factors) if window is None
                else (lambda points: (points + origin) / factors))
    markers = to_video(shown_markers)
    annotations, labels = ([], []) if annotate is None else annotate(result, smoothed, factors)
    if annotate is not None and not (len(annotations) == len(labels) == count):
        raise RuntimeError(f"annotate gave {len(annotations)} entries and {len(labels)} labels "
                           f"for {count} frames")
    best_markers = to_video(result.best_markers)
    # track()'s run time counts the chunks after the first as they are pulled from the
    # decoder; the first chunk's decoding and preparing come before it and count here
    # (its frames after frame 0's share: frame 0 is set-up, as in track())
    head, prepare = run.first_chunk, run.prepare_seconds
    pipeline_seconds = (result.seconds_per_frame * max(count - 1, 1)
                        + prepare[0] * (head - 1) / head)
    timings = {**timings, "compile_seconds": result.compile_seconds,
               "observe_seconds": result.observe_seconds,
               "decode_and_prepare_seconds": sum(prepare),
               # as track()'s: frames after the first, compilation and frame 0's start excluded
               "pipeline_seconds_per_frame": pipeline_seconds / max(count - 1, 1)}
    per_frame = []
    for t, index in enumerate(indices):
        entry = {"frame": int(index),
                 "time_s": _number(index / first.source_fps)
                 if math.isfinite(first.source_fps) else None,
                 "status": statuses[t].value, "markers": _named(markers[t], names),
                 "best_markers": _named(best_markers[t], names),
                 "ess": _number(result.ess[t]),
                 "log_likelihood": _number(result.log_likelihood[t]),
                 "degenerate": bool(result.degenerate[t])}
        if smoothed is not None:
            entry["filtered_markers"] = _named(to_video(result.markers[t]), names)
        if host is not None:
            entry["guided_detection"] = host["frames"][t]
        if annotate is not None:
            entry.update(annotations[t])
            per_frame.append(entry)
            continue
        for name, values in extras.items():
            value = values[t]
            entry[name] = (bool(value) if values.dtype == bool else int(value)
                           if np.issubdtype(values.dtype, np.integer) else _number(value))
        if run.reasons is not None:
            entry["observation"] = run.reasons[t] or "observed"
        per_frame.append(entry)
    record = {
        "method": method, "tracker": result.options, "reads": list(reads),
        "video": str(run.video), "size": [width, height], "tracked_size": list(run.tracked_size),
        "scale": [float(factors[0]), float(factors[1])], "fps": fps,
        "frames_tracked": count, "first_frame": int(indices[0]),
        "particles": int(result.num_particles), "seed": seed,
        "estimate": "smoothed over the whole video (filtered_markers: the filter's)"
                    if smoothed is not None else "filtered",
        "masks": "given" if run.masks else "foreground against the median "
                 "background" if view["needs_masks"] else None,
        "keypoints": "given" if keypoints_given else None,
        "background": run.background,
        "initial_pose": None if pose is None else _named(to_video(pose), names)
                        if len(pose) == len(names) else to_video(pose).tolist(),
        "marker_names": list(names), "statuses": status_legend(), "lost_rule": LOST_RULE,
        "status_counts": status_counts(statuses), "timings": timings,
        "frames": per_frame}
    if host is not None:
        record["guided_detection"] = host["record"]
    if extra_keys:
        record["stride"] = run.stride
        record["window"] = None if window is None else {
            "size": list(window.size), "origin": [float(v) for v in origin],
            "located_from": run.located_from}
    record["_overlay"] = (markers, names, labels)
    return record
