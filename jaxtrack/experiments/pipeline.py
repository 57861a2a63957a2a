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
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
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

__all__ = ["BACKGROUND_SAMPLES", "default_marker_names", "track_video", "tracking_scale",
           "video_background"]

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


def video_background(video: str | os.PathLike, *, scale: float = 1.0, start: int = 0,
                     max_frames: int | None = None, max_samples: int = BACKGROUND_SAMPLES,
                     chunk_frames: int = 32, grey: bool = False) -> np.ndarray:
    """The per-pixel median of frames spread evenly over a video file (the static scene):
    one decoding pass, at most ``2 max_samples`` frames kept (every ``stride``-th frame is
    kept, and the stride doubles whenever that would pass ``2 max_samples``) besides the
    ``chunk_frames`` being decoded.

    Args:
        video: the video file.
        scale: resize factor of the frames (as they are tracked).
        start, max_frames: the frames tracked (:func:`jaxtrack.vision.read_video`).
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
    from jaxtrack.vision import (
        iter_video_chunks,
        median_background,
        median_grey_background,
        to_grey,
    )

    if int(max_samples) != max_samples or max_samples < 3:
        raise ValueError(f"max_samples must be an integer of at least 3, got {max_samples}")
    kept, stride, seen = [], 1, 0
    for chunk in iter_video_chunks(video, chunk_frames, start=start, max_frames=max_frames,
                                   scale=scale):
        for frame in chunk.frames:
            if seen % stride == 0:
                kept.append(frame)
                if len(kept) > 2 * max_samples:  # keep every other one: still evenly spaced
                    kept, stride = kept[::2], stride * 2
            seen += 1
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


def track_video(tracker: Tracker, video: str | os.PathLike, out_dir: str | os.PathLike, *,
                key: PRNGKeyArray, initial_pose: Float[ArrayLike, "markers 2"] | None = None,
                scale: float | None = None, max_size: int | None = None, start: int = 0,
                max_frames: int | None = None, chunk_frames: int = 64,
                masks: np.ndarray | None = None,
                keypoints: tuple[np.ndarray, np.ndarray] | np.ndarray | None = None,
                background: np.ndarray | None = None,
                marker_names: Sequence[str] | None = None, seed: int | None = None,
                detector_seconds: float | None = None, progress: bool = True,
                extra_record: dict | None = None, smooth: bool = False,
                annotate: Callable[[TrackResult, FrameEstimate | None, np.ndarray],
                                   tuple[list[dict], list[str]]] | None = None) -> dict:
    """Track a video file with any tracker; write ``out_dir/overlay.mp4`` and
    ``out_dir/track.json`` (module docstring).

    Args:
        tracker: any :class:`jaxtrack.trackers.Tracker`; what it reads (``tracker.reads``) is
            prepared for it.
        video: the video file.
        out_dir: the output folder (created if missing, probed before a frame is read).
        key: PRNG key of the tracking.
        initial_pose: ``(markers, 2)`` the pose in the first tracked frame, in the video's own
            pixels (None for trackers that start from the frame alone).
        scale, max_size: the frames are tracked at ``scale`` times their size, or with their
            longer side at most ``max_size`` pixels (:func:`tracking_scale`).
        start, max_frames: the video frames tracked (from ``start``, at most ``max_frames``).
        chunk_frames: frames decoded, prepared and tracked at a time (the first chunk one
            more): the memory bound.
        masks: ``(video frames, height, width)`` bool masks of the person, one per video frame
            from its first, at any size of the video's aspect ratio (a ``np.memmap`` keeps them
            on disk: only the chunk's frames are read); None: where the tracker reads masks,
            the foreground against the video's median background. Given masks are passed to
            the tracker even where ``reads`` does not name them (the image trackers' foreground
            term reads them), and it refuses them where it cannot use them.
        keypoints: a detector's ``(points (video frames, markers, 2), confidence (video
            frames, markers))`` in the video's own pixels, one row per video frame from its
            first (NaN where not found), or the points alone.
        background: ``(height, width, 3)`` uint8 RGB empty scene at the video's size (or
            already at the tracking size); None: the median of the video
            (:func:`video_background`) where needed (the tracker reads it and no masks are
            given, or foreground masks are made).
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

    Returns:
        What ``track.json`` holds (a dict), with ``"result"``: the :class:`TrackResult` (in
        tracking pixels) and ``"paths"``: the two files written.

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
    video = Path(video)
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
    if masks is not None and (np.ndim(masks) != 3):
        raise ValueError(f"masks must be (video frames, height, width) bool, got shape "
                         f"{np.shape(masks)}")

    first = read_video(video, start=start, max_frames=1)
    video_size = first.image_size
    width, height = video_size
    resize = tracking_scale(video_size, scale=scale, max_size=max_size)
    tracked = read_video(video, start=start, max_frames=1, scale=resize)
    tracked_size = tracked.image_size
    # the decoder rounds the size: markers go back and forth by each axis's own factor
    factors = np.array([tracked_size[0] / width, tracked_size[1] / height])
    pose = None
    if initial_pose is not None:
        pose = np.asarray(initial_pose, np.float64)
        if pose.ndim != 2 or pose.shape[-1] != 2:
            raise ValueError(f"initial_pose must be (markers, 2) video pixels, got shape "
                             f"{pose.shape}")
        pose = pose * factors

    needs_masks = "masks" in reads and masks is None
    needs_background = "background" in reads and masks is None
    timings: dict[str, float | None] = {"background_seconds": 0.0}
    scene = None
    if background is not None:
        scene = np.asarray(background)
        if scene.ndim != 3 or scene.shape[-1] != 3 or scene.dtype != np.uint8:
            raise ValueError(f"background must be (height, width, 3) uint8 RGB, got shape "
                             f"{scene.shape} dtype {scene.dtype}")
        if scene.shape[1::-1] == video_size and resize != 1.0:
            from jaxtrack.vision.video import _resize

            # as the decoder resizes the frames, so that the scene matches them pixel for pixel
            scene = _resize(scene, resize)
        if scene.shape[1::-1] != tracked_size:
            raise ValueError(f"background is {scene.shape[1]}x{scene.shape[0]}; give the empty "
                             f"scene at the video's size {width}x{height}")
    elif needs_masks or needs_background:
        tick = time.perf_counter()
        scene = video_background(video, scale=resize, start=start, max_frames=max_frames,
                                 chunk_frames=chunk_frames)
        timings["background_seconds"] = time.perf_counter() - tick
    frame_indices: list[np.ndarray] = []
    no_person: list[np.ndarray] = []
    prepare = []  # seconds each chunk took to decode and prepare

    def groups() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``(frames, file indices)``: chunk_frames + 1 frames first, then chunk_frames at a
        time, so that track()'s compiled chunks (frame 0 is its set-up) line up with the
        chunks given to it and it never joins one chunk's observations to the next's."""
        pending: list[tuple[np.ndarray, int]] = []
        target = chunk_frames + 1
        for decoded in iter_video_chunks(video, chunk_frames, start=start,
                                         max_frames=max_frames, scale=resize):
            pending.extend(zip(decoded.frames, decoded.frame_indices.tolist(), strict=True))
            if len(pending) >= target:
                group, pending = pending[:target], pending[target:]
                yield (np.stack([frame for frame, _ in group]),
                       np.array([index for _, index in group], np.int64))
                target = chunk_frames
        if pending:
            yield (np.stack([frame for frame, _ in pending]),
                   np.array([index for _, index in pending], np.int64))

    def chunks() -> Iterator[VideoChunk]:
        decoder = groups()
        while True:
            tick = time.perf_counter()
            group = next(decoder, None)
            if group is None:
                return
            rgb, indices = group
            frame_indices.append(indices)
            person = None
            if masks is not None:
                if indices[-1] >= len(masks):
                    raise ValueError(f"masks hold {len(masks)} frames, but video frame "
                                     f"{int(indices[-1])} is tracked (one mask per video "
                                     f"frame, from its first)")
                # only the chunk's masks are read (masks may be a np.memmap on disk)
                window = np.asarray(masks[int(indices[0]):int(indices[-1]) + 1], bool)
                person = masks_for_frames(window, indices - indices[0], tracked_size,
                                          name="masks")
            elif needs_masks:
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
                points = (given_keypoints[0][indices] * factors,
                          given_keypoints[1][indices])
            grey = None
            if "grey" in reads:
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

    tick = time.perf_counter()
    stream = _ahead(chunks())
    try:
        result = track(tracker, key, stream, pose, chunk_size=chunk_frames,
                       progress=progress, description=f"tracking {video.name}")
    finally:  # on an error too: stop the decoding thread and release the video
        stream.close()
    tracking_seconds = time.perf_counter() - tick
    smoothed = None
    if smooth:
        tick = time.perf_counter()
        smoothed = tracker.smooth(result.estimates)
        timings["smooth_seconds"] = time.perf_counter() - tick
    shown = result.estimates if smoothed is None else smoothed
    indices = np.concatenate(frame_indices)
    count = len(indices)
    if result.markers.shape[0] != count:
        raise RuntimeError(f"the tracker reported {result.markers.shape[0]} frames of {count}")
    names = tuple(marker_names) if marker_names is not None else default_marker_names(
        result.markers.shape[1])
    if len(names) != result.markers.shape[1]:
        raise ValueError(f"marker_names names {len(names)} markers, the tracker reports "
                         f"{result.markers.shape[1]}")
    extras = _per_frame_extras(shown)
    shown_markers = np.asarray(shown.markers) if smoothed is not None else result.markers
    nobody = np.concatenate(no_person) if no_person else np.zeros(count, bool)
    if "found" in extras:  # the tracker saw nobody (no silhouette with its skin blobs)
        nobody = nobody | ~extras["found"].astype(bool)
    statuses = frame_statuses(shown_markers, tracked_size, degenerate=result.degenerate,
                              no_person=nobody, log_likelihood=result.log_likelihood)
    markers = shown_markers / factors
    annotations, labels = ([], []) if annotate is None else annotate(result, smoothed, factors)
    if annotate is not None and not (len(annotations) == len(labels) == count):
        raise RuntimeError(f"annotate gave {len(annotations)} entries and {len(labels)} labels "
                           f"for {count} frames")
    best_markers = result.best_markers / factors
    fps = first.fps if math.isfinite(first.fps) else None

    created = []  # the folders made here, removed again (when empty) on failure
    missing = out_dir
    while not missing.exists():
        created.append(missing)
        missing = missing.parent
    overlay_path, json_path = out_dir / "overlay.mp4", out_dir / "track.json"
    written = []
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        tick = time.perf_counter()
        written.append(write_overlay_video_from_file(
            video, indices, {method: markers}, overlay_path, fps=fps or 30.0,
            marker_names=names, chunk_size=min(chunk_frames, 32),
            labels=[(f"{labels[t]}  " if labels else "") + f"{t + 1}/{count} {status.value}"
                    for t, status in enumerate(statuses)]))
        overlay_seconds = time.perf_counter() - tick
        # track()'s run time counts the chunks after the first as they are pulled from the
        # decoder; the first chunk's decoding and preparing come before it and count here
        # (its frames after frame 0's share: frame 0 is set-up, as in track())
        head = len(frame_indices[0])
        pipeline_seconds = (result.seconds_per_frame * max(count - 1, 1)
                            + prepare[0] * (head - 1) / head)
        timings.update({
            "compile_seconds": result.compile_seconds,
            "seconds_per_frame": result.seconds_per_frame,
            "observe_seconds": result.observe_seconds,
            "decode_and_prepare_seconds": sum(prepare),
            # as track()'s: frames after the first, compilation and frame 0's start excluded
            "pipeline_seconds_per_frame": pipeline_seconds / max(count - 1, 1),
            "tracking_pass_seconds": tracking_seconds,
            "overlay_seconds": overlay_seconds,
            "detector_seconds": detector_seconds})
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
                entry["filtered_markers"] = _named(result.markers[t] / factors, names)
            if annotate is not None:
                entry.update(annotations[t])
                per_frame.append(entry)
                continue
            for name, values in extras.items():
                value = values[t]
                entry[name] = (bool(value) if values.dtype == bool else int(value)
                               if np.issubdtype(values.dtype, np.integer) else _number(value))
            per_frame.append(entry)
        record = {
            "method": method, "tracker": result.options, "reads": list(reads),
            "video": str(video), "size": [width, height], "tracked_size": list(tracked_size),
            "scale": [float(factors[0]), float(factors[1])], "fps": fps,
            "frames_tracked": count, "first_frame": int(indices[0]),
            "particles": int(result.num_particles), "seed": seed,
            "estimate": "smoothed over the whole video (filtered_markers: the filter's)"
                        if smoothed is not None else "filtered",
            "masks": "given" if masks is not None else "foreground against the median "
                     "background" if needs_masks else None,
            "keypoints": "given" if given_keypoints is not None else None,
            "background": "given" if background is not None else "median of the video"
                          if scene is not None else None,
            "initial_pose": None if pose is None else _named(pose / factors, names)
                            if len(pose) == len(names) else (pose / factors).tolist(),
            "marker_names": list(names), "statuses": status_legend(), "lost_rule": LOST_RULE,
            "status_counts": status_counts(statuses), "timings": timings,
            "frames": per_frame}
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
    return {**record, "result": result, "paths": {"overlay": overlay_path, "json": json_path}}

