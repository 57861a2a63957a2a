"""Markers and stick figures drawn over frames, and the videos made of them.

:func:`draw_tracks` is the one drawer: each method's stick figure in its own colour, the ground
truth (when given) thin and white on top, so an estimate lying on it never hides it, its markers
that are not visible drawn hollow; a legend naming the colours and an optional frame counter.
It serves both videos: :func:`write_overlay_video` (several trackers' estimates, for looking
at what the numbers say; :func:`write_overlay_video_from_file` draws them on a video file's own
frames, at its own size, a chunk at a time) and :func:`write_video` (a rendered sequence,
optionally with its ground truth). Videos are written by
:func:`jaxtrack.vision.video.write_frames`: OpenCV `mp4v`, atomically (a failed write leaves
no file). cv2 is imported inside the functions. The one drawer for every video: ``docs/layers.md``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from jaxtrack.body.markers import marker_edges
from jaxtrack.body.sequence import RenderedSequence
from jaxtrack.vision.video import write_frames

__all__ = ["METHOD_COLOURS", "TRUTH_COLOUR", "draw_tracks", "write_overlay_video",
           "write_overlay_video_from_file", "write_video"]

METHOD_COLOURS = (
    (255, 64, 64), (64, 160, 255), (64, 224, 64), (255, 208, 0), (224, 64, 255), (0, 224, 224),
    (255, 140, 0), (160, 96, 255),
)
"""RGB colours given to methods in order (cycled when there are more methods)."""

TRUTH_COLOUR = (255, 255, 255)


def _point(xy) -> tuple[int, int] | None:
    if not np.isfinite(xy).all() or np.abs(xy).max() > 1e5:
        return None
    return int(round(float(xy[0]))), int(round(float(xy[1])))


def _draw_figure(cv2, image: np.ndarray, markers: np.ndarray, edges, colour, thickness: int,
                 radius: int, visible: np.ndarray | None = None) -> None:
    points = [_point(p) for p in markers]
    for a, b in edges:
        if points[a] is not None and points[b] is not None:
            cv2.line(image, points[a], points[b], colour, thickness, cv2.LINE_AA)
    for index, point in enumerate(points):
        if point is not None:
            filled = visible is None or visible[index]
            cv2.circle(image, point, radius, colour, -1 if filled else 1, cv2.LINE_AA)


def _text(cv2, image: np.ndarray, text: str, origin: tuple[int, int], colour, scale: float
          ) -> None:
    # a dark outline keeps the label readable on any background
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(image, text, origin, font, scale, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(image, text, origin, font, scale, colour, 1, cv2.LINE_AA)


def _colours(tracks: Mapping, colours: Mapping | None) -> dict:
    chosen = {method: METHOD_COLOURS[i % len(METHOD_COLOURS)] for i, method in enumerate(tracks)}
    if colours:
        chosen.update({method: tuple(int(c) for c in colour)
                       for method, colour in colours.items() if method in chosen})
    return chosen


def draw_tracks(image: np.ndarray, tracks: Mapping[str, np.ndarray], marker_names: Sequence[str],
                *, truth: np.ndarray | None = None, label: str | None = None,
                colours: Mapping[str, tuple[int, int, int]] | None = None,
                visible: np.ndarray | None = None) -> np.ndarray:
    """A copy of one frame with each method's markers and skeleton in its colour.

    Args:
        image: `(height, width, 3)` uint8 RGB.
        tracks: method -> `(markers, 2)` pixels (may be empty: truth alone); non-finite points
            are not drawn.
        marker_names: `(markers,)` names (the skeleton is `jaxtrack.body.marker_edges`).
        truth: optional `(markers, 2)` true markers, drawn thin and white over the methods.
        label: text for the bottom-left corner (the frame counter).
        colours: method -> RGB; defaults to :data:`METHOD_COLOURS` in the order of `tracks`.
        visible: optional `(markers,)` bool for `truth`: markers that are not visible (hidden
            by a nearer body part or an occluder, or outside the image) are drawn hollow.

    Returns:
        `(height, width, 3)` uint8 RGB.
    """
    import cv2

    image = np.ascontiguousarray(image, dtype=np.uint8).copy()
    height = image.shape[0]
    edges = marker_edges(tuple(marker_names))
    thickness = max(1, round(height / 240))
    scale = max(0.3, height / 720)
    line_height = max(10, round(28 * scale))
    expected = (len(marker_names), 2)

    def checked(name: str, markers) -> np.ndarray:
        markers = np.asarray(markers, dtype=np.float64)
        if markers.shape != expected:
            raise ValueError(f"{name} has shape {markers.shape}, expected {expected} for "
                             f"{len(marker_names)} marker names")
        return markers

    figures = {method: checked(f"tracks[{method!r}]", markers)
               for method, markers in tracks.items()}
    colours = _colours(tracks, colours)
    if visible is not None:
        visible = np.asarray(visible, dtype=bool)
        if truth is None:
            raise ValueError("visible marks the truth's markers, but no truth was given")
        if visible.shape != expected[:1]:
            raise ValueError(f"visible has shape {visible.shape}, expected ({len(marker_names)},)")
    # the truth goes last, thinner than the estimates: where an estimate lies on it, the
    # estimate's colour shows on both sides of the white line instead of covering it
    truth_thickness = max(1, round(height / 480))
    for method, markers in figures.items():
        _draw_figure(cv2, image, markers, edges, colours[method],
                     max(thickness, truth_thickness + 2), thickness + 2)
    if truth is not None:
        _draw_figure(cv2, image, checked("truth", truth), edges, TRUTH_COLOUR, truth_thickness,
                     thickness, visible)
    legend = [(str(method), colours[method]) for method in tracks]
    if truth is not None:
        legend.append(("truth", TRUTH_COLOUR))
    for row, (text, colour) in enumerate(legend):
        _text(cv2, image, text, (4, line_height * (row + 1)), colour, scale)
    if label:
        _text(cv2, image, label, (4, height - 6), TRUTH_COLOUR, scale)
    return image


def write_overlay_video(images: np.ndarray, tracks: Mapping[str, np.ndarray],
                        path: str | os.PathLike, *, fps: float, marker_names: Sequence[str],
                        truth: np.ndarray | None = None,
                        colours: Mapping[str, tuple[int, int, int]] | None = None,
                        labels: Sequence[str] | None = None) -> Path:
    """Write an `.mp4` (OpenCV `mp4v`) of the frames with every method's estimate drawn on top.

    Args:
        images: `(time, height, width, 3)` uint8 RGB frames.
        tracks: method -> `(time, markers, 2)` estimated markers, pixels.
        path: the video file, written atomically.
        fps: frames per second of the video.
        marker_names: `(markers,)` names.
        truth: optional `(time, markers, 2)` true markers, drawn thin and white on top.
        colours: method -> RGB; defaults to :data:`METHOD_COLOURS`.
        labels: `(time,)` texts for each frame's bottom-left corner; defaults to
            `"frame t/time"`.

    Returns:
        The path.

    Raises:
        ValueError: no tracks, or shapes that disagree (frames, markers, labels); the message
            names the argument.
        OSError: OpenCV cannot open a writer for the file.
    """

    images = np.asarray(images)
    if images.ndim != 4 or images.shape[-1] != 3 or images.dtype != np.uint8:
        raise ValueError(f"images must be (time, height, width, 3) uint8 RGB, got shape "
                         f"{images.shape} dtype {images.dtype}")
    num_frames, height, width = images.shape[:3]
    if num_frames == 0:
        raise ValueError("images has no frames")
    if not tracks:
        raise ValueError("tracks is empty; give at least one method's (time, markers, 2) track")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    expected = (num_frames, len(marker_names), 2)
    arrays = {}
    for method, track in tracks.items():
        track = np.asarray(track, dtype=np.float64)
        if track.shape != expected:
            raise ValueError(f"tracks[{method!r}] has shape {track.shape} but images has "
                             f"{num_frames} frames and marker_names names "
                             f"{len(marker_names)} markers: expected {expected}")
        arrays[method] = track
    if truth is not None:
        truth = np.asarray(truth, dtype=np.float64)
        if truth.shape != expected:
            raise ValueError(f"truth has shape {truth.shape}, expected {expected}")
    if labels is None:
        labels = [f"frame {t + 1}/{num_frames}" for t in range(num_frames)]
    elif len(labels) != num_frames:
        raise ValueError(f"labels has {len(labels)} texts for {num_frames} frames")
    frames = (draw_tracks(images[t], {m: track[t] for m, track in arrays.items()},
                          marker_names, truth=None if truth is None else truth[t],
                          label=labels[t], colours=colours)
              for t in range(num_frames))
    return write_frames(frames, path, fps, (width, height))


def write_overlay_video_from_file(video: str | os.PathLike, frame_indices: Sequence[int],
                                  tracks: Mapping[str, np.ndarray], path: str | os.PathLike, *,
                                  fps: float, marker_names: Sequence[str],
                                  labels: Sequence[str] | None = None,
                                  colours: Mapping[str, tuple[int, int, int]] | None = None,
                                  chunk_size: int = 32) -> Path:
    """Write an `.mp4` of a video file's own frames, at its own size, with every method's
    estimate drawn on top (a tracker that ran on downscaled frames gives its markers scaled
    back to the file's pixels). Frames are decoded a chunk at a time, so the file never has to
    fit in memory.

    Args:
        video: the video file tracked.
        frame_indices: `(time,)` the file's frames tracked, consecutive (every frame from the
            first).
        tracks: method -> `(time, markers, 2)` estimated markers in the file's own pixels.
        path: the video file to write, atomically.
        fps, marker_names, labels, colours: as for :func:`write_overlay_video`.
        chunk_size: frames decoded at a time.

    Returns:
        The path.

    Raises:
        ValueError: frame indices that are not consecutive, or shapes that disagree.
        jaxtrack.vision.VideoError: the file yields fewer frames than ``frame_indices``.
        OSError: OpenCV cannot open a writer for the file.
    """
    from jaxtrack.vision.video import VideoError, iter_video_chunks, read_video

    indices = np.asarray(frame_indices, np.int64)
    if indices.ndim != 1 or len(indices) == 0 or np.any(np.diff(indices) != 1):
        raise ValueError("frame_indices must be consecutive frame numbers, at least one")
    num_frames = len(indices)
    expected = (num_frames, len(marker_names), 2)
    arrays = {}
    for method, track in tracks.items():
        arrays[method] = np.asarray(track, np.float64)
        if arrays[method].shape != expected:
            raise ValueError(f"tracks[{method!r}] has shape {arrays[method].shape}, expected "
                             f"{expected}")
    if not arrays:
        raise ValueError("tracks is empty; give at least one method's (time, markers, 2) track")
    if labels is None:
        labels = [f"frame {t + 1}/{num_frames}" for t in range(num_frames)]
    elif len(labels) != num_frames:
        raise ValueError(f"labels has {len(labels)} texts for {num_frames} frames")
    first = read_video(video, start=int(indices[0]), max_frames=1)
    size = first.image_size

    def frames():
        done = 0
        for chunk in iter_video_chunks(video, chunk_size, start=int(indices[0]),
                                       max_frames=num_frames):
            for image in chunk.frames:
                yield draw_tracks(image, {m: track[done] for m, track in arrays.items()},
                                  marker_names, label=labels[done], colours=colours)
                done += 1
        if done != num_frames:
            raise VideoError(f"{video}: {done} frames from frame {indices[0]}, but "
                             f"{num_frames} were tracked")

    return write_frames(frames(), path, fps, size)


def write_video(sequence: RenderedSequence, path: str | os.PathLike, fps: float | None = None, *,
                overlay: bool = False) -> Path:
    """Write a rendered sequence's frames as an `.mp4` (OpenCV `mp4v`), atomically; with
    `overlay`, its ground-truth markers and skeleton are drawn on top by :func:`draw_tracks`
    (hollow where not visible). Returns the path.

    Raises:
        OSError: OpenCV cannot open a writer for the file.
    """
    frames = (draw_tracks(image, {}, sequence.marker_names, truth=sequence.markers_2d[t],
                          visible=sequence.visibility[t]) if overlay else image
              for t, image in enumerate(sequence.images))
    return write_frames(frames, path, float(sequence.fps if fps is None else fps),
                        sequence.image_size)
